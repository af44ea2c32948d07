# SPDX-License-Identifier: Apache-2.0
# Cross-build for 64-bit ARM Linux (Raspberry Pi 5 class boards) with Debian's cross GCC.
#
# Default: Debian multiarch in / -- the arm64 -dev packages that tools/setup --cross installs
# live in /usr/lib/aarch64-linux-gnu and /usr/include/aarch64-linux-gnu beside the host ones,
# and the cross GCC already searches there. Point WALLAR_SYSROOT at a board's root file system
# (or a debootstrap tree) to build against that instead.
#
#   cmake --preset aarch64                   # multiarch, what CI does
#   cmake -DWALLAR_SYSROOT=/srv/rpi5-root ...   # a sysroot
#
# Variables (cache or -D or environment):
#   WALLAR_CROSS_PREFIX  compiler prefix, default "aarch64-linux-gnu-" (found on PATH)
#   WALLAR_SYSROOT       target root file system, default empty = Debian multiarch in /
#   WALLAR_QEMU          emulator for running target binaries (ctest), default qemu-aarch64
#
# The SIMD baseline (-march=armv8-a, never -march=native) is chosen in cmake/WallarCompile.cmake.

set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)

# try_compile projects re-read this file; hand them our settings.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES WALLAR_CROSS_PREFIX WALLAR_SYSROOT WALLAR_QEMU)

if(NOT DEFINED WALLAR_CROSS_PREFIX)
  if(DEFINED ENV{WALLAR_CROSS_PREFIX})
    set(WALLAR_CROSS_PREFIX "$ENV{WALLAR_CROSS_PREFIX}")
  else()
    set(WALLAR_CROSS_PREFIX "aarch64-linux-gnu-")
  endif()
endif()
if(NOT DEFINED WALLAR_SYSROOT)
  set(WALLAR_SYSROOT "$ENV{WALLAR_SYSROOT}")
endif()
if(NOT DEFINED WALLAR_QEMU)
  if(DEFINED ENV{WALLAR_QEMU})
    set(WALLAR_QEMU "$ENV{WALLAR_QEMU}")
  else()
    set(WALLAR_QEMU "qemu-aarch64")
  endif()
endif()
set(WALLAR_CROSS_PREFIX "${WALLAR_CROSS_PREFIX}" CACHE STRING "Cross compiler prefix")
set(WALLAR_SYSROOT "${WALLAR_SYSROOT}" CACHE PATH "Target sysroot (empty: Debian multiarch in /)")
set(WALLAR_QEMU "${WALLAR_QEMU}" CACHE STRING "User-mode emulator for target binaries")

set(CMAKE_C_COMPILER "${WALLAR_CROSS_PREFIX}gcc")
set(CMAKE_CXX_COMPILER "${WALLAR_CROSS_PREFIX}g++")

# The host's multiarch triplet (x86_64-linux-gnu on a PC): its CMake package configs must never
# be taken for the target's (e.g. OpenCV's, whose arm64 twin cannot be installed beside it;
# cmake/WallarDeps.cmake then falls back to the arm64 multiarch libraries).
set(_wallar_host_multiarch "${CMAKE_HOST_SYSTEM_PROCESSOR}-linux-gnu")

if(WALLAR_SYSROOT)
  # A real target root file system: look only inside it (programs still come from the host).
  set(CMAKE_SYSROOT "${WALLAR_SYSROOT}")
  set(CMAKE_FIND_ROOT_PATH "${WALLAR_SYSROOT}")
  set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
  set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
  set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
  set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
  set(_wallar_target_root "${WALLAR_SYSROOT}")
  set(ENV{PKG_CONFIG_SYSROOT_DIR} "${WALLAR_SYSROOT}")
else()
  # Debian multiarch in /: with CMAKE_LIBRARY_ARCHITECTURE set, find_package and find_library
  # look in /usr/lib/aarch64-linux-gnu[/cmake] and the architecture-independent /usr/share
  # (Eigen3, CLI11, nlohmann_json), never in the host's /usr/lib/<host triplet>. Ignore the
  # host triplet's folders explicitly as well, in case a package registers them some other way.
  set(_wallar_target_root "")
  set(ENV{PKG_CONFIG_SYSROOT_DIR} "")
  if(NOT _wallar_host_multiarch STREQUAL "${CMAKE_LIBRARY_ARCHITECTURE}")
    file(GLOB _wallar_host_cmake_dirs LIST_DIRECTORIES true
         "/usr/lib/${_wallar_host_multiarch}/cmake/*")
    list(APPEND CMAKE_IGNORE_PATH
         "/usr/lib/${_wallar_host_multiarch}" "/lib/${_wallar_host_multiarch}"
         "/usr/lib/${_wallar_host_multiarch}/cmake" ${_wallar_host_cmake_dirs})
    list(REMOVE_DUPLICATES CMAKE_IGNORE_PATH)
  endif()
endif()

# pkg-config (host binary) must see only the target's .pc files, never the host's.
set(ENV{PKG_CONFIG_LIBDIR}
    "${_wallar_target_root}/usr/lib/${CMAKE_LIBRARY_ARCHITECTURE}/pkgconfig:${_wallar_target_root}/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_PATH} "")

# ctest (and gtest_discover_tests) run target binaries through qemu user-mode emulation. The
# dynamic loader and libraries are found under -L: the sysroot, or / for multiarch (where
# /lib/ld-linux-aarch64.so.1 comes from libc6:arm64).
if(_wallar_target_root)
  set(CMAKE_CROSSCOMPILING_EMULATOR "${WALLAR_QEMU};-L;${_wallar_target_root}")
else()
  set(CMAKE_CROSSCOMPILING_EMULATOR "${WALLAR_QEMU};-L;/")
endif()
