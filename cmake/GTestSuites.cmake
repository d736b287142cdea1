# Script mode (cmake -P), run after a GoogleTest program is built: lists its tests and writes a
# CTest file that registers one test per suite, named PREFIX:Suite and run with
# --gtest_filter=Suite.*. A suite shares one process, and with it its SetUpTestSuite fixture
# and the program's start (under the sanitizers about half a second), where one test per
# process paid both for every test.
#
# Variables: TEST_EXECUTABLE, CTEST_FILE, PREFIX, LABEL, ENVIRONMENT (a CMake list).
execute_process(COMMAND "${TEST_EXECUTABLE}" --gtest_list_tests
  OUTPUT_VARIABLE listing ERROR_VARIABLE errors RESULT_VARIABLE result TIMEOUT 120)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "${TEST_EXECUTABLE} --gtest_list_tests failed (${result}):\n${listing}\n${errors}")
endif()
string(REPLACE ";" "," listing "${listing}")
string(REPLACE "\n" ";" lines "${listing}")
set(content "# Written by cmake/GTestSuites.cmake from ${TEST_EXECUTABLE} --gtest_list_tests\n")
foreach(line IN LISTS lines)
  # A suite's line starts in the first column and ends its name with a dot ("Suite." or
  # "Instance/Suite.  # TypeParam = ..."); the tests' lines are indented.
  if(NOT line MATCHES "^([A-Za-z_][A-Za-z0-9_/]*)\\.")
    continue()
  endif()
  set(suite "${CMAKE_MATCH_1}")
  if(suite MATCHES "(^|/)DISABLED_")
    continue()
  endif()
  set(name "${PREFIX}:${suite}")
  string(APPEND content
    "add_test([==[${name}]==] [==[${TEST_EXECUTABLE}]==] [==[--gtest_filter=${suite}.*]==])\n"
    "set_tests_properties([==[${name}]==] PROPERTIES LABELS [==[${LABEL}]==] ENVIRONMENT [==[${ENVIRONMENT}]==])\n")
endforeach()
file(WRITE "${CTEST_FILE}" "${content}")
