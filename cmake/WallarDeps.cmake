# SPDX-License-Identifier: Apache-2.0
# Third-party dependencies, all from Debian 12 packages (tools/setup installs them). The same
# file serves the host build and the aarch64 cross-build against Debian's arm64 multiarch
# packages; where an arm64 -dev package cannot be installed beside its amd64 twin (OpenCV's
# CMake config lives in libopencv-dev, which drags in conflicting modules), imported targets
# are made from the multiarch libraries directly.

find_package(Threads REQUIRED)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(PkgConfig REQUIRED)
pkg_check_modules(YAML REQUIRED IMPORTED_TARGET yaml-0.1)
pkg_check_modules(PNG REQUIRED IMPORTED_TARGET libpng)
pkg_check_modules(JPEG REQUIRED IMPORTED_TARGET libjpeg)
# MCAP recordings (drivers/recording/mcap.cpp): chunk compression and CRC-32.
pkg_check_modules(ZSTD REQUIRED IMPORTED_TARGET libzstd)
pkg_check_modules(LZ4 REQUIRED IMPORTED_TARGET liblz4)
pkg_check_modules(ZLIB REQUIRED IMPORTED_TARGET zlib)  # MJPEG frames, JPEG calibration images
pkg_check_modules(USB REQUIRED IMPORTED_TARGET libusb-1.0)  # drivers/usb: discovery, hot-plug
pkg_check_modules(SYSTEMD REQUIRED IMPORTED_TARGET libsystemd)  # sd_notify: Type=notify, watchdog
pkg_check_modules(GPIOD REQUIRED IMPORTED_TARGET libgpiod)  # v1 API (gpiod.h), Debian 12: 1.6.3
# The headset view (drivers/display): Mesa's EGL and GLES, GBM and libdrm for KMS.
pkg_check_modules(EGL REQUIRED IMPORTED_TARGET egl)
pkg_check_modules(GLES REQUIRED IMPORTED_TARGET glesv2)
pkg_check_modules(GBM REQUIRED IMPORTED_TARGET gbm)
pkg_check_modules(DRM REQUIRED IMPORTED_TARGET libdrm)
# The live server (drivers/net): Foxglove's WebSocket protocol on libwebsockets (Debian 12: 4.1.6).
# Its arm64 -dev package cannot be installed beside the amd64 one (their lws_config.h differ, in
# the install path only), so a cross-build links the arm64 runtime library (libwebsockets17,
# Multi-Arch: same) with the host's headers.
pkg_check_modules(WEBSOCKETS QUIET IMPORTED_TARGET libwebsockets)
if(NOT WEBSOCKETS_FOUND)
  if(NOT CMAKE_CROSSCOMPILING)
    message(FATAL_ERROR "libwebsockets not found (tools/setup installs libwebsockets-dev)")
  endif()
  find_path(WALLAR_WEBSOCKETS_INCLUDE libwebsockets.h REQUIRED)
  find_library(WALLAR_WEBSOCKETS_LIB NAMES websockets libwebsockets.so.17 REQUIRED)
  add_library(PkgConfig::WEBSOCKETS SHARED IMPORTED)
  set_target_properties(PkgConfig::WEBSOCKETS PROPERTIES
    IMPORTED_LOCATION "${WALLAR_WEBSOCKETS_LIB}"
    INTERFACE_INCLUDE_DIRECTORIES "${WALLAR_WEBSOCKETS_INCLUDE}")
  message(STATUS "libwebsockets: ${WALLAR_WEBSOCKETS_LIB} with the host's headers")
endif()
find_package(CLI11 CONFIG REQUIRED)
find_package(nlohmann_json 3.10 REQUIRED)
find_package(hwy REQUIRED)  # Highway: portable SIMD with run-time dispatch

# calib3d and features2d: on arm64 only their runtime packages (libopencv-*406) can be installed
# beside the amd64 ones; the headers come from the host's OpenCV packages.
set(WALLAR_OPENCV_MODULES core imgproc flann features2d calib3d video)
find_package(OpenCV QUIET COMPONENTS ${WALLAR_OPENCV_MODULES})
if(OpenCV_FOUND)
  set(WALLAR_OPENCV_LIBS ${OpenCV_LIBS})
else()
  # Cross-build: link the arm64 multiarch libraries; headers are architecture independent
  # except cvconfig.h, which lives in the multiarch include directory.
  find_path(WALLAR_OPENCV_INCLUDE opencv2/core.hpp PATH_SUFFIXES opencv4 REQUIRED)
  find_path(WALLAR_OPENCV_ARCH_INCLUDE opencv2/cvconfig.h
            PATHS /usr/include/${CMAKE_LIBRARY_ARCHITECTURE}/opencv4 NO_DEFAULT_PATH REQUIRED)
  set(WALLAR_OPENCV_LIBS)
  foreach(module IN LISTS WALLAR_OPENCV_MODULES)
    find_library(WALLAR_OPENCV_${module} NAMES opencv_${module} libopencv_${module}.so.406
                 REQUIRED)
    add_library(opencv_${module} SHARED IMPORTED)
    set_target_properties(opencv_${module} PROPERTIES
      IMPORTED_LOCATION "${WALLAR_OPENCV_${module}}"
      INTERFACE_INCLUDE_DIRECTORIES "${WALLAR_OPENCV_ARCH_INCLUDE};${WALLAR_OPENCV_INCLUDE}")
    list(APPEND WALLAR_OPENCV_LIBS opencv_${module})
  endforeach()
  message(STATUS "OpenCV: multiarch libraries for ${CMAKE_LIBRARY_ARCHITECTURE}")
endif()

if(WALLAR_BUILD_TESTS)
  find_package(GTest REQUIRED)
  include(GoogleTest)
endif()
if(WALLAR_BUILD_BENCH)
  find_package(benchmark REQUIRED)
endif()
