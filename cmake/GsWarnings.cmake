# SPDX-License-Identifier: MIT
# Project-wide warning flags, applied per target with gs_set_warnings(target).
function(gs_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wno-unused-parameter -Wno-psabi)
  # In a unity build (the sanitizer and cross presets) each .cpp is #included into a batch file, so
  # g++ takes a class holding a type from the .cpp's anonymous namespace (a pimpl's fields) for a
  # header's and warns; in the per-source release build the warning stays on.
  if(CMAKE_UNITY_BUILD AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    target_compile_options(${target} PRIVATE -Wno-subobject-linkage)
  endif()
endfunction()
