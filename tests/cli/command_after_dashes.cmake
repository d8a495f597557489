# SPDX-License-Identifier: MIT
# For the `cmake [-D...] -P <script> -- <program> <args...>` scripts of the CLI tests: sets `cmd` to
# the program and its arguments after "--", behind ${EMULATOR} (a cross build's emulator, given as a
# variable because cmake itself would take an emulator option such as qemu's -L).
set(cmd ${EMULATOR})
set(after_dashes OFF)
math(EXPR last "${CMAKE_ARGC} - 1")
foreach(i RANGE 1 ${last})
  if(after_dashes)
    list(APPEND cmd "${CMAKE_ARGV${i}}")
  elseif("${CMAKE_ARGV${i}}" STREQUAL "--")
    set(after_dashes ON)
  endif()
endforeach()
if(NOT cmd)
  message(FATAL_ERROR "${CMAKE_SCRIPT_MODE_FILE}: no command after --")
endif()
