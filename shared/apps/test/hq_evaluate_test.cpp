// hq-evaluate as a process: inputs that give no accuracy figure exit 2 with the reason.
#include "hq/testing/process.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

struct ToolRun {
  int exit_code;
  std::string output;
};

ToolRun evaluate(const std::string& gt_text, const std::string& est_text) {
  const fs::path dir = fs::temp_directory_path() / ("hq_evaluate_" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "gt.txt") << gt_text;
  std::ofstream(dir / "est.txt") << est_text;
  const std::string out = (dir / "out.txt").string();
  int code = -1;
  {
    hq::testing::Process p(
        {HQ_EVALUATE_EXE, "--gt", (dir / "gt.txt").string(), "--est", (dir / "est.txt").string()},
        out);
    code = p.wait_exit(30.0);
  }
  std::ifstream in(out);
  std::stringstream ss;
  ss << in.rdbuf();
  fs::remove_all(dir);
  return {code, ss.str()};
}

constexpr const char* kGroundTruth =
    "1.0 0 0 0 0 0 0 1\n"
    "1.5 1 0 0 0 0 0 1\n"
    "2.0 2 0 0 0 0 0 1\n";

// GIVEN an estimate with a position of 1e200 m, WHEN evaluated, THEN the overflowed error is
// an error naming the figure and the largest position, not "inf" with exit 0.
TEST(HqEvaluate, OverflowingErrorExitsTwoNamingWhy) {
  const ToolRun r = evaluate(kGroundTruth,
                             "1.0 0 0 0 0 0 0 1\n"
                             "1.5 1e200 0 0 0 0 0 1\n"
                             "2.0 2 0 0 0 0 0 1\n");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("hq-evaluate: RPE trans is inf over 2 pairs, expected finite"));
  EXPECT_THAT(r.output, HasSubstr("the largest coordinate is 2 m in"));
  EXPECT_THAT(r.output, HasSubstr("and 1e+200 m in"));
  EXPECT_THAT(r.output, Not(HasSubstr("RPE window")));
}

TEST(HqEvaluate, NoOverlapOrEmptyEstimateExitsTwoNamingWhy) {
  const ToolRun disjoint = evaluate(kGroundTruth, "100.0 0 0 0 0 0 0 1\n");
  EXPECT_EQ(disjoint.exit_code, 2) << disjoint.output;
  EXPECT_THAT(disjoint.output,
              HasSubstr("hq-evaluate: RPE needs at least 2 associated poses, got 0"));
  const ToolRun empty = evaluate(kGroundTruth, "");
  EXPECT_EQ(empty.exit_code, 2) << empty.output;
  EXPECT_THAT(empty.output, HasSubstr("estimate 0 poses"));
}

TEST(HqEvaluate, MatchingTrajectoriesReportZeroError) {
  const ToolRun r = evaluate(kGroundTruth, kGroundTruth);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("ATE        m        0.000000"));
  EXPECT_THAT(r.output, HasSubstr("ground truth noise: not estimated (needs 4 or more"));
}

TEST(HqEvaluate, ReportsTheFloorTheGroundTruthsOwnNoiseSets) {
  // GIVEN a ground truth moving at 1 m/s whose pose 3 is 1 mm off its line: the four third
  // differences that contain it are 1, 3, 3 and 1 mm, of the 6 that 9 poses give
  std::string truth;
  for (int k = 0; k < 9; ++k) {
    const double x = 0.1 * k + (k == 3 ? 0.001 : 0.0);
    truth += std::to_string(1.0 + 0.1 * k) + " " + std::to_string(x) + " 0 0 0 0 0 1\n";
  }
  // WHEN evaluated against itself
  const ToolRun r = evaluate(truth, truth);
  // THEN sqrt((1 + 9 + 9 + 1) mm^2 / (20 x 6)) = 0.408 mm per pose, and over the 0.8 s window
  // sqrt(2) of that per 0.8 s
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("ground truth noise per pose 0.000408 m, 0.0000 deg"));
  EXPECT_THAT(r.output, HasSubstr("floor of the RPE 0.000722 m/s"));
}

}  // namespace
