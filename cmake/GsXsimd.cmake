# SPDX-License-Identifier: MIT
# The xsimd target for hbgs's builds (the main one and tests/layers/alone): Debian 12's package
# needs two fixes.
find_package(xsimd QUIET)
if(NOT TARGET xsimd)
  # Cross builds: Debian's xsimd config lives under the host's arch dir; headers are arch-independent.
  find_path(XSIMD_INCLUDE_DIR xsimd/xsimd.hpp REQUIRED)
  add_library(xsimd INTERFACE IMPORTED)
  set_target_properties(xsimd PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${XSIMD_INCLUDE_DIR}")
endif()
# Debian xsimd 8.1.0-7 links a nonexistent "xtl" library; xsimd is header-only.
set_property(TARGET xsimd PROPERTY INTERFACE_LINK_LIBRARIES "")
