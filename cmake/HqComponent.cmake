# hq_add_test(<name> SOURCES ... LIBS ... [PREFIX <p>]): one gtest binary per component, discovered
# by ctest; PREFIX is put before each discovered test name so `ctest -R <p>` selects the component.
# Tests run from the repository root so that relative paths such as calib/ and ../shared/data
# resolve the same way as in the README.
function(hq_add_test name)
  cmake_parse_arguments(ARG "" "PREFIX" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} GTest::gtest GTest::gmock GTest::gtest_main
                                        hq::warnings)
  gtest_discover_tests(${name} WORKING_DIRECTORY ${PROJECT_SOURCE_DIR} DISCOVERY_TIMEOUT 60
                       TEST_PREFIX "${ARG_PREFIX}")
endfunction()
