# hq_add_test(<name> SOURCES ... LIBS ... [PREFIX <p>]): one gtest binary per component, discovered
# by ctest; PREFIX is put before each discovered test name so `ctest -R <p>` selects the component.
# Tests run from the repository root so that relative paths such as calib/ and ../shared/data
# resolve the same way as in docs/development.md, "Real data".
function(hq_add_test name)
  cmake_parse_arguments(ARG "" "PREFIX" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} GTest::gtest GTest::gmock GTest::gtest_main
                                        hq::warnings)
  # Labels for a fast loop: `ctest -L unit` runs every component's own tests (seconds to a few
  # minutes); the cross-component flights, campaigns and processes under tests/ are
  # `integration`, and the script tests (npm checkers, install, valgrind) carry none.
  string(FIND "${CMAKE_CURRENT_SOURCE_DIR}/" "${PROJECT_SOURCE_DIR}/tests/" under_tests)
  if(under_tests EQUAL 0)
    set(label integration)
  else()
    set(label unit)
  endif()
  gtest_discover_tests(${name} WORKING_DIRECTORY ${PROJECT_SOURCE_DIR} DISCOVERY_TIMEOUT 60
                       TEST_PREFIX "${ARG_PREFIX}" PROPERTIES LABELS ${label})
endfunction()
