// parse_or_exit: --help and --version exit 0, every usage error exits 2 with the program's name,
// --quiet and --verbose set the log level.
#include "hq/base/program.hpp"

#include "hq/base/log.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace hq {
namespace {

using ::testing::HasSubstr;
using ::testing::StartsWith;

struct Parsed {
  std::optional<int> exit;
  std::string out;
  std::string err;
};

// A program with one required option and one ranged option, parsed from `args`.
Parsed parse(std::vector<std::string> args) {
  args.insert(args.begin(), "/usr/bin/hq-test");
  std::vector<char*> argv;
  argv.reserve(args.size());
  for (std::string& arg : args) argv.push_back(arg.data());
  CLI::App app{"hq-test: a program"};
  std::string input;
  double rate_hz = 10.0;
  app.add_option("--input", input, "input file")->required();
  app.add_option("--rate-hz", rate_hz, "rate")->check(CLI::Range(1.0, 100.0));
  ::testing::internal::CaptureStdout();
  ::testing::internal::CaptureStderr();
  Parsed parsed;
  parsed.exit = parse_or_exit(app, static_cast<int>(argv.size()), argv.data());
  parsed.out = ::testing::internal::GetCapturedStdout();
  parsed.err = ::testing::internal::GetCapturedStderr();
  return parsed;
}

TEST(ParseOrExit, GoodArgumentsGoOn) {
  const Parsed parsed = parse({"--input", "a.yaml", "--rate-hz", "20"});
  EXPECT_FALSE(parsed.exit.has_value());
  EXPECT_EQ(parsed.err, "");
}

TEST(ParseOrExit, HelpAndVersionExitZeroOnStdout) {
  const Parsed help = parse({"--help"});
  EXPECT_EQ(help.exit, 0);
  EXPECT_THAT(help.out, HasSubstr("--input"));
  EXPECT_THAT(help.out, HasSubstr("--version"));
  EXPECT_THAT(help.out, HasSubstr("--quiet"));
  const Parsed version = parse({"--version"});
  EXPECT_EQ(version.exit, 0);
  EXPECT_THAT(version.out, StartsWith("hq-test " + version_line("hq-test").substr(8)));
  EXPECT_THAT(version_line("hq-x"), StartsWith("hq-x 0."));
}

// CLI11 alone exits 109 (unknown option), 106 (missing required), 105 (validation).
TEST(ParseOrExit, EveryUsageErrorExitsTwoNamingTheProgram) {
  const std::vector<std::vector<std::string>> usage_errors = {
      {"--input", "a.yaml", "--no-such-option"},  {},
      {"--input", "a.yaml", "--rate-hz", "1000"}, {"--input", "a.yaml", "--rate-hz", "fast"},
      {"--input", "a.yaml", "stray-positional"},  {"--input", "a.yaml", "--quiet", "--verbose"}};
  for (const std::vector<std::string>& args : usage_errors) {
    const Parsed parsed = parse(args);
    EXPECT_EQ(parsed.exit, 2) << ::testing::PrintToString(args);
    EXPECT_THAT(parsed.err, StartsWith("hq-test: ")) << ::testing::PrintToString(args);
    EXPECT_THAT(parsed.err, HasSubstr("--help")) << ::testing::PrintToString(args);
  }
}

TEST(ParseOrExit, QuietAndVerboseSetTheLogLevel) {
  parse({"--input", "a", "--quiet"});
  EXPECT_FALSE(log::enabled(log::Level::kInfo));
  EXPECT_TRUE(log::enabled(log::Level::kWarning));
  parse({"--input", "a", "-v"});
  EXPECT_TRUE(log::enabled(log::Level::kDebug));
  parse({"--input", "a"});
  EXPECT_TRUE(log::enabled(log::Level::kInfo));
  EXPECT_FALSE(log::enabled(log::Level::kDebug));
}

TEST(ProgramName, DropsTheFolder) {
  EXPECT_EQ(program_name("/usr/bin/hq-onboard"), "hq-onboard");
  EXPECT_EQ(program_name("hq-ground"), "hq-ground");
}

}  // namespace
}  // namespace hq
