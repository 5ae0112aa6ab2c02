// hq-report on recordings written by the ground's own recorder: the truth RMSE line of a
// simulated flight, and an older layout whose absent columns the page names.
#include "hq/ground/ground_station.hpp"
#include "hq/testing/files.hpp"
#include "hq/testing/process.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

namespace hq::ground {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using hq::testing::slurp;

fs::path fresh_dir(const std::string& name) { return hq::testing::fresh_dir("hq_report", name); }

// Runs hq-report with an argument vector (no shell), output to `output` (default
// <recording>/report.out).
int run_report(const fs::path& recording, std::vector<std::string> extra = {},
               fs::path output = {}) {
  if (output.empty()) output = recording / "report.out";
  std::vector<std::string> args = {HQ_REPORT_EXE, recording.string()};
  args.insert(args.end(), extra.begin(), extra.end());
  hq::testing::Process p(args, output.string());
  return p.wait_exit(120.0);
}

void record_flight(const fs::path& dir) {
  TelemetryRecorder recorder(dir.string());
  for (int i = 0; i < 10; ++i) {
    link::VehicleState s{};
    s.sequence_number = static_cast<std::uint64_t>(i + 1);
    s.t_ns = i * 50'000'000LL;
    s.mode = hq_msgs_MODE_TELEOP;
    recorder.state(1'000'000'000LL + s.t_ns, 1'000'000, s);
  }
}

// GIVEN a simulated flight whose estimate is off the truth by (0.2, -0.1, 0) m/s on half the
// states and exact on the rest, WHEN reported, THEN the page's truth line holds the RMSE
// sqrt(0.5 * e^2) per axis over the states with truth.
TEST(HqReport, RecordingWithTruthHasTheTruthRmseLine) {
  if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) GTEST_SKIP() << "no gnuplot";
  const fs::path dir = fresh_dir("truth");
  {
    TelemetryRecorder recorder(dir.string());
    for (int i = 0; i < 40; ++i) {
      link::VehicleState s{};
      s.sequence_number = static_cast<std::uint64_t>(i + 1);
      s.t_ns = i * 50'000'000LL;
      s.mode = hq_msgs_MODE_TELEOP;
      s.truth_valid = true;
      s.v_truth_H_mps = {0.5F, 0.25F, 0.0F};
      const bool off = i % 2 == 0;
      s.v_H_mps = {0.5F + (off ? 0.2F : 0.0F), 0.25F - (off ? 0.1F : 0.0F), 0.0F};
      s.position_valid = i >= 20;
      s.p_W_m = {0.05F * static_cast<float>(i), 0.0F, -1.0F};
      recorder.state(1'000'000'000LL + s.t_ns, 1'000'000, s);
    }
  }
  ASSERT_EQ(run_report(dir), 0) << slurp(dir / "report.out");
  const std::string page = slurp(dir / "report" / "report.md");
  // sqrt(0.5 * 0.2^2) = 0.141, sqrt(0.5 * 0.1^2) = 0.071.
  EXPECT_THAT(page, HasSubstr("| velocity estimate RMSE vs truth (simulator, v_est - v_truth in "
                              "H) | x 0.141, y 0.071, z 0.000 m/s over 40 states |"));
  const std::string script = slurp(dir / "report" / "report.gp");
  EXPECT_THAT(script, HasSubstr("t 'truth'"));
  EXPECT_THAT(script, HasSubstr("vehicle position p_W"));
  EXPECT_GT(fs::file_size(dir / "report" / "velocity_H.png"), 5000U);
  fs::remove_all(dir);
}

// GIVEN a recording of the first layout, WHEN reported, THEN it still reports, says there is no
// truth, draws no truth trace and names the absent columns.
TEST(HqReport, OldLayoutReportsAndNamesAbsentColumns) {
  if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) GTEST_SKIP() << "no gnuplot";
  const fs::path dir = fresh_dir("old");
  fs::create_directories(dir);
  std::ofstream(dir / "telemetry.csv")
      << "receipt_ns,latency_us,sequence,t_ns,v_H_x_mps,v_H_y_mps,v_H_z_mps,omega_B_x_radps,"
         "omega_B_y_radps,omega_B_z_radps,roll_rad,pitch_rad,v_obs_H_x_mps,v_obs_H_y_mps,v_obs_H_z_"
         "mps,"
         "mode,estimator_health,link_health,vehicle_id\n"
         "1000000000,5.0,1,0,0.25,0,0,0,0,0,0,0,0,0,0,hover,ok,ok,1\n"
         "1100000000,5.0,2,10,0.5,0,0,0,0,0,0,0,0,0,0,teleop,ok,ok,1\n";
  ASSERT_EQ(run_report(dir), 0) << slurp(dir / "report.out");
  const std::string page = slurp(dir / "report" / "report.md");
  EXPECT_THAT(page, HasSubstr("| velocity estimate RMSE vs truth | no truth in this recording |"));
  EXPECT_THAT(page, HasSubstr("- telemetry.csv: v_truth_H_x_mps"));
  EXPECT_THAT(page, HasSubstr("- telemetry.csv: position_valid"));
  EXPECT_THAT(slurp(dir / "report" / "report.gp"), ::testing::Not(HasSubstr("t 'truth'")));
  fs::remove_all(dir);
}

// GIVEN a recording folder and an --out folder whose names hold a quote and ";touch FILE;",
// WHEN reported, THEN the report is written there and no command ran: hq-report spawns gnuplot
// with an argument vector and its script names no path.
TEST(HqReport, QuotesAndSemicolonsInPathsRunNothing) {
  if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) GTEST_SKIP() << "no gnuplot";
  const fs::path base = fresh_dir("inject");
  // A relative name: the shell (or gnuplot) would create it in its working directory.
  const std::string canary = "hq_report_canary_" + std::to_string(getpid());
  const fs::path recording = base / ("rec'x;touch " + canary + ";'");
  const fs::path out = base / ("x';touch " + canary + ";'");
  const auto touched = [&] {
    return fs::exists(fs::current_path() / canary) || fs::exists(base / canary) ||
           fs::exists(out / canary) || fs::exists(recording / "report" / canary);
  };
  fs::create_directories(base);
  record_flight(recording);
  ASSERT_EQ(run_report(recording, {"--out", out.string()}, base / "report.out"), 0)
      << slurp(base / "report.out");
  EXPECT_TRUE(fs::exists(out / "report.md"));
  EXPECT_GT(fs::file_size(out / "velocity_H.png"), 5000U);
  EXPECT_FALSE(touched()) << "a shell or gnuplot ran the injected command";
  EXPECT_THAT(slurp(out / "report.gp"), ::testing::Not(HasSubstr("touch")));
  // The same with the default output folder, inside the quoted recording folder.
  ASSERT_EQ(run_report(recording, {}, base / "report.out"), 0) << slurp(base / "report.out");
  EXPECT_TRUE(fs::exists(recording / "report" / "report.md"));
  EXPECT_FALSE(touched());
  fs::remove_all(base);
}

// A missing recording folder is named with what is expected there, and the message no longer
// names a --replay flag hq-report does not have.
TEST(HqReport, MissingFolderExitsTwoNamingIt) {
  const fs::path dir = fresh_dir("missing");
  const fs::path output =
      fs::temp_directory_path() / ("hq_report_missing_" + std::to_string(getpid()) + ".out");
  EXPECT_EQ(run_report(dir, {}, output), 2);
  const std::string message = slurp(output);
  EXPECT_THAT(message, HasSubstr("hq-report: " + dir.string() +
                                 ": not found, expected a recording folder written by hq-ground "
                                 "--record"));
  EXPECT_THAT(message, ::testing::Not(HasSubstr("--replay")));
  fs::remove(output);
}

}  // namespace
}  // namespace hq::ground
