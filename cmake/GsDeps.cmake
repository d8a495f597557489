# SPDX-License-Identifier: MIT
# Finds hbgs's third-party dependencies (Debian 12 packages) and papers over their packaging bugs.
find_package(Eigen3 3.3 REQUIRED NO_MODULE)

include(GsXsimd)

find_path(STB_INCLUDE_DIR stb_image.h PATH_SUFFIXES stb REQUIRED)

# zlib (Debian zlib1g-dev) for .spz versions 2 and 3 (gzip) and libzstd (libzstd-dev) for version
# 4 (ZSTD streams); without them (a cross build with no target libraries) gs_io still builds and its
# .spz functions report, per version, which library this build lacks.
option(GS_WITH_ZLIB "Read and write .spz splat files versions 2 and 3 (zlib)" ON)
if(GS_WITH_ZLIB)
  find_package(ZLIB QUIET)
  if(NOT ZLIB_FOUND)
    message(STATUS "hbgs: zlib not found, .spz versions 2 and 3 are disabled")
    set(GS_WITH_ZLIB OFF)
  endif()
endif()
# No FindZstd module ships with CMake, and Debian's zstdConfig.cmake names a host path in a cross
# build's search, so the header and library are looked up directly (the library in the target's
# directories only, as the toolchain files say), as FindZLIB does; the imported target is gs::zstd.
option(GS_WITH_ZSTD "Read and write .spz splat files version 4 (libzstd)" ON)
if(GS_WITH_ZSTD)
  find_path(ZSTD_INCLUDE_DIR zstd.h)
  find_library(ZSTD_LIBRARY NAMES zstd)
  if(ZSTD_INCLUDE_DIR AND ZSTD_LIBRARY)
    if(NOT TARGET gs::zstd)
      add_library(gs::zstd UNKNOWN IMPORTED)
      set_target_properties(gs::zstd PROPERTIES IMPORTED_LOCATION "${ZSTD_LIBRARY}"
                                                INTERFACE_INCLUDE_DIRECTORIES "${ZSTD_INCLUDE_DIR}")
    endif()
  else()
    message(STATUS "hbgs: libzstd not found, .spz version 4 is disabled")
    set(GS_WITH_ZSTD OFF)
  endif()
endif()

if(GS_BUILD_TESTS)
  find_package(doctest REQUIRED)
  include(doctest)
endif()

if(GS_WITH_EMBREE)
  find_package(embree 3 QUIET)
  if(NOT embree_FOUND)
    message(STATUS "hbgs: Embree not found, `hbgs synth` and the ray-picking tests are disabled")
    set(GS_WITH_EMBREE OFF)
  endif()
endif()

if(GS_BUILD_BENCH)
  find_package(benchmark QUIET)
endif()

find_package(CLI11 QUIET CONFIG)
if(NOT TARGET CLI11::CLI11)
  find_path(CLI11_INCLUDE_DIR CLI/CLI.hpp REQUIRED)
  add_library(CLI11::CLI11 INTERFACE IMPORTED)
  set_target_properties(CLI11::CLI11 PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${CLI11_INCLUDE_DIR}")
endif()
find_package(nlohmann_json 3 QUIET)
if(NOT TARGET nlohmann_json::nlohmann_json)
  find_path(NLOHMANN_INCLUDE_DIR nlohmann/json.hpp REQUIRED)
  add_library(nlohmann_json::nlohmann_json INTERFACE IMPORTED)
  set_target_properties(nlohmann_json::nlohmann_json PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${NLOHMANN_INCLUDE_DIR}")
endif()
