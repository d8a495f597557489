# SPDX-License-Identifier: MIT
# Fails when a doctest TEST_CASE name contains ';'. doctest_discover_tests turns each case into a
# ctest entry whose name is a CMake list element, so a ';' splits the name in two: each half runs
# "--test-case=<half>", which matches no case, and passes with no assertion run (9 cases did so
# until issue 24's session). Usage: cmake -DSOURCE_DIR=<repo> [-DPLANT_FILE=f -DPLANT_TEXT=t] -P this
# (a planted file is checked as if it were in tests/, to prove the check fails).
file(GLOB_RECURSE sources "${SOURCE_DIR}/tests/*.cpp")
set(bad "")
foreach(f IN LISTS sources)
  file(READ "${f}" text)
  string(REPLACE ";" "@SEMICOLON@" text "${text}")
  string(REGEX MATCHALL "TEST_CASE(_TEMPLATE)?\\(\"[^\"\n]*@SEMICOLON@[^\"\n]*\"" hits "${text}")
  foreach(h IN LISTS hits)
    string(REPLACE "@SEMICOLON@" "<;>" h "${h}")
    file(RELATIVE_PATH rel "${SOURCE_DIR}" "${f}")
    string(APPEND bad "  ${rel}: ${h}\n")
  endforeach()
endforeach()
if(DEFINED PLANT_FILE)
  string(REPLACE ";" "@SEMICOLON@" text "${PLANT_TEXT}")
  if(text MATCHES "TEST_CASE(_TEMPLATE)?\\(\"[^\"\n]*@SEMICOLON@[^\"\n]*\"")
    string(APPEND bad "  ${PLANT_FILE}: ${PLANT_TEXT}\n")
  endif()
endif()
if(bad)
  message(FATAL_ERROR "test case names with ';' (ctest splits them and the halves run nothing; write ',' instead):\n${bad}")
endif()
list(LENGTH sources n)
message(STATUS "no test case name of ${n} test sources contains a semicolon")
