# SPDX-License-Identifier: MIT
# Project-wide warning flags, applied per target with gs_set_warnings(target).
function(gs_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wno-unused-parameter -Wno-psabi)
endfunction()
