# SPDX-License-Identifier: Apache-2.0
# The Debian package: `cpack --config <build>/CPackConfig.cmake` (tools/package wraps it) turns
# this build's install tree into wallar_<version>_<arch>.deb for bookworm: the binary, the
# systemd unit, the board files, /etc/wallar/board.yaml (a conffile), udev rules, the manual
# page, libwallar-client (the apps' library, its headers and pkg-config file), libwallar_vit.so
# (the tracker Monado loads, under /usr/lib/<arch>/wallar, and its header), and maintainer
# scripts that create the service user and enable the service
# (tools/debian/). The cross build makes the arm64 package, a host build the amd64 one.

set(_deb_src ${PROJECT_SOURCE_DIR}/tools/debian)
set(_deb_gen ${PROJECT_BINARY_DIR}/debian)
file(MAKE_DIRECTORY ${_deb_gen})

# Debian ships compressed manual pages and changelogs (gzip -9n: no name or time stamp in the
# header, so the package is byte-for-byte the same from one build to the next).
foreach(_pair "wallar.1;wallar.1.gz" "changelog;changelog.gz")
  list(GET _pair 0 _in)
  list(GET _pair 1 _out)
  execute_process(COMMAND gzip -9nc ${_deb_src}/${_in} OUTPUT_FILE ${_deb_gen}/${_out}
                  RESULT_VARIABLE _rc)
  if(NOT _rc EQUAL 0)
    message(FATAL_ERROR "gzip of tools/debian/${_in} failed (${_rc})")
  endif()
endforeach()
set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${_deb_src}/wallar.1
                                                               ${_deb_src}/changelog)

install(FILES ${_deb_gen}/wallar.1.gz DESTINATION share/man/man1)
install(FILES ${_deb_src}/copyright ${_deb_gen}/changelog.gz DESTINATION share/doc/wallar)
install(FILES ${_deb_src}/60-wallar.rules DESTINATION lib/udev/rules.d)

# Debian architecture names of the target.
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
  set(_deb_arch arm64)
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$")
  set(_deb_arch amd64)
else()
  set(_deb_arch ${CMAKE_SYSTEM_PROCESSOR})
endif()

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME wallar)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
# Whoever builds packages for others sets their own name and address here.
set(WALLAR_PACKAGE_MAINTAINER "wallar developers <wallar@users.noreply.github.com>"
    CACHE STRING "Maintainer field of the .deb")
set(CPACK_PACKAGE_CONTACT "${WALLAR_PACKAGE_MAINTAINER}")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "stereo video see-through AR headset firmware")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${_deb_arch})
set(CPACK_DEBIAN_PACKAGE_SECTION misc)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
# The extended description (the summary above is its first line); an empty line is a paragraph.
string(CONCAT CPACK_DEBIAN_PACKAGE_DESCRIPTION
       "wallar runs a stereo video see-through augmented-reality headset on a Linux\n"
       "single-board computer: it captures synchronised stereo video (V4L2) and an\n"
       "IMU (I2C or serial), tracks the head, builds a sparse 3-D map, finds the\n"
       "room's walls, floor and ceiling in it and draws the wall model over the\n"
       "camera images on the headset's display through EGL.\n"
       "\n"
       "The package installs the wallar service (started at boot as the system user\n"
       "wallar), the board files and the udev rules that give the user its devices.")
# Library dependencies from the binary's ELF (dpkg-shlibdeps, which finds arm64 libraries of the
# multiarch installation too); the maintainer scripts' tools by hand.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# libwallar-client.so.0 (the client API's library, firmware/client/): its shlibs file and the ldconfig
# trigger come from CPack.
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS ON)
set(CPACK_DEBIAN_PACKAGE_GENERATE_SHLIBS_POLICY ">=")
set(CPACK_DEBIAN_PACKAGE_DEPENDS "adduser, init-system-helpers (>= 1.52), systemd")
set(CPACK_DEBIAN_PACKAGE_CONTROL_EXTRA
    ${_deb_src}/postinst ${_deb_src}/prerm ${_deb_src}/postrm ${_deb_src}/conffiles
    ${_deb_src}/triggers)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
include(CPack)
