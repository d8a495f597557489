# SPDX-License-Identifier: MIT
# CPack: one .deb per target architecture, hbgs_<version>_<arch>.deb, holding everything
# `cmake --install` puts under the prefix (libraries, headers, CMake package, hbgs.pc, the hbgs
# program), installed under /usr. Made in a build folder with
#   cpack --config <builddir>/CPackConfig.cmake -G DEB      (or: cd <builddir> && cpack -G DEB)
# The architecture comes from the target processor, not the build machine. Native packages get
# their Depends from dpkg-shlibdeps; cross packages from cmake/GsDebCrossDepends.cmake, which reads
# the program's ELF dependencies at cpack time (dpkg-shlibdeps cannot resolve foreign libraries).
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$")
  set(GS_DEB_ARCH amd64)
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64|ARM64)$")
  set(GS_DEB_ARCH arm64)
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^arm")
  set(GS_DEB_ARCH armhf)
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(i.86|x86)$")
  set(GS_DEB_ARCH i386)
else()
  string(TOLOWER "${CMAKE_SYSTEM_PROCESSOR}" GS_DEB_ARCH)
endif()

set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME hbgs)
set(CPACK_PACKAGE_VENDOR "hbgs")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "CPU 3D Gaussian splatting: libraries, headers and the hbgs program")
set(CPACK_PACKAGE_CONTACT "hbgs maintainers <hbgs@localhost>")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES OFF)  # the host's strip cannot handle ARM objects; keep packages alike
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${GS_DEB_ARCH})
set(CPACK_DEBIAN_FILE_NAME "hbgs_${PROJECT_VERSION}_${GS_DEB_ARCH}.deb")
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_DESCRIPTION
    "Hybrid bundle-adjusting 3D Gaussian splatting on the CPU.\n Static C++17 libraries (hbgs::hbgs in CMake, pkg-config hbgs), their headers under\n /usr/include/gs, and the hbgs command-line program (train, render, register, ingest).")

# Building against the package needs the header-only dependencies and, when compiled in, the
# capture backends' development files; the program itself needs only the shared libraries (Depends).
set(_gs_recommends libeigen3-dev libxsimd-dev nlohmann-json3-dev pkg-config)
if(GS_WITH_ZLIB)
  list(APPEND _gs_recommends zlib1g-dev)
endif()
if(GS_WITH_ZSTD)
  list(APPEND _gs_recommends libzstd-dev)
endif()
if(GS_WITH_LIBCAMERA)
  list(APPEND _gs_recommends libcamera-dev)
endif()
if(GS_WITH_LIBAV)
  list(APPEND _gs_recommends libavformat-dev libavcodec-dev libavutil-dev libswscale-dev)
endif()
list(JOIN _gs_recommends ", " CPACK_DEBIAN_PACKAGE_RECOMMENDS)

if(CMAKE_CROSSCOMPILING)
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS OFF)
  # Read by GsDebCrossDepends.cmake (the CPack project config file) when cpack runs.
  set(GS_DEB_CROSS_PROGRAM "$<TARGET_FILE:hbgs>")
  if(NOT TARGET hbgs)
    set(GS_DEB_CROSS_PROGRAM "")
  endif()
  set(GS_DEB_READELF "${CMAKE_READELF}")
  if(NOT GS_DEB_READELF)
    find_program(GS_DEB_READELF NAMES ${CROSS_TRIPLE}-readelf readelf)
  endif()
  file(GENERATE OUTPUT ${PROJECT_BINARY_DIR}/GsDebCrossDepends.cmake CONTENT
"set(GS_DEB_CROSS_PROGRAM \"${GS_DEB_CROSS_PROGRAM}\")
set(GS_DEB_READELF \"${GS_DEB_READELF}\")
include(\"${CMAKE_CURRENT_LIST_DIR}/GsDebCrossDepends.cmake\")
")
  set(CPACK_PROJECT_CONFIG_FILE ${PROJECT_BINARY_DIR}/GsDebCrossDepends.cmake)
else()
  set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
endif()

include(CPack)
