# hq_add_test(<name> SOURCES ... LIBS ...): one gtest binary per component, discovered by ctest.
# Tests run from the repository root so that relative paths such as calib/ and ../shared/data
# resolve the same way as in the README.
function(hq_add_test name)
  cmake_parse_arguments(ARG "" "" "SOURCES;LIBS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_LIBS} GTest::gtest GTest::gmock GTest::gtest_main
                                        hq::warnings)
  gtest_discover_tests(${name} WORKING_DIRECTORY ${PROJECT_SOURCE_DIR} DISCOVERY_TIMEOUT 60)
endfunction()
