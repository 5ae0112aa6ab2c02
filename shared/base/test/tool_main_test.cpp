// run_tool: whatever a tool's body throws becomes "<tool>: <message>" and exit status 2.
#include "hq/base/tool_main.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace hq {
namespace {

using ::testing::HasSubstr;

template <typename Throw>
int run_throwing(Throw thrower) {
  char name[] = "hq-test";
  char* argv[] = {name, nullptr};
  return run_tool("hq-test", 1, argv, [&](int, char**) -> int {
    thrower();
    return 0;
  });
}

TEST(RunTool, InputErrorExitsTwoWithTheToolName) {
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(run_throwing([] { throw InputError("a.yaml: x = 1, expected > 2"); }), 2);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "hq-test: a.yaml: x = 1, expected > 2\n");
}

// A library's own exception (yaml-cpp's bad conversion derives from std::runtime_error) used to
// escape main and abort with status 134.
TEST(RunTool, LibraryExceptionsExitTwoNotAbort) {
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(run_throwing([] { throw std::runtime_error("yaml-cpp: bad conversion"); }), 2);
  EXPECT_THAT(::testing::internal::GetCapturedStderr(),
              HasSubstr("hq-test: yaml-cpp: bad conversion"));
  ::testing::internal::CaptureStderr();
  EXPECT_EQ(run_throwing([] { throw 42; }), 2);
  EXPECT_THAT(::testing::internal::GetCapturedStderr(), HasSubstr("hq-test: unknown exception"));
}

TEST(RunTool, ReturnsTheBodysExitStatus) {
  char name[] = "hq-test";
  char* argv[] = {name, nullptr};
  EXPECT_EQ(run_tool("hq-test", 1, argv, [](int, char**) { return 3; }), 3);
}

}  // namespace
}  // namespace hq
