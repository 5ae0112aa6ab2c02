#include "hq/ground/ground_station.hpp"

#include "hq/testing/files.hpp"
#include "hq/testing/input_error.hpp"
#include "hq/testing/process.hpp"
#include "hq/testing/wire_enum.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <signal.h>
#include <sstream>
#include <string>
#include <sys/resource.h>
#include <unistd.h>

namespace hq::ground {
namespace {

using ::testing::HasSubstr;

TEST(ModeToggle, Button0TogglesTeleopAndHoverOnRisingEdgesOnly) {
  ModeToggle toggle;
  EXPECT_FALSE(toggle.on_buttons(0, hq_msgs_MODE_HOVER));
  EXPECT_EQ(toggle.on_buttons(1, hq_msgs_MODE_HOVER), hq_msgs_MODE_TELEOP);
  EXPECT_FALSE(toggle.on_buttons(1, hq_msgs_MODE_HOVER));  // held: asks once
  EXPECT_FALSE(toggle.on_buttons(0, hq_msgs_MODE_TELEOP));
  EXPECT_EQ(toggle.on_buttons(1, hq_msgs_MODE_TELEOP), hq_msgs_MODE_HOVER);
  EXPECT_FALSE(toggle.on_buttons(0, hq_msgs_MODE_HOVER));
  EXPECT_EQ(toggle.on_buttons(1, hq_msgs_MODE_LAND), hq_msgs_MODE_TELEOP);  // out of land too
}

TEST(ModeToggle, Button1LandsAndWinsOverAToggle) {
  ModeToggle toggle;
  EXPECT_EQ(toggle.on_buttons(2, hq_msgs_MODE_TELEOP), hq_msgs_MODE_LAND);
  EXPECT_FALSE(toggle.on_buttons(2, hq_msgs_MODE_LAND));
  EXPECT_EQ(toggle.on_buttons(3, hq_msgs_MODE_LAND), hq_msgs_MODE_TELEOP);  // 0 rises, 1 held
  EXPECT_FALSE(toggle.on_buttons(0, hq_msgs_MODE_TELEOP));
  EXPECT_EQ(toggle.on_buttons(3, hq_msgs_MODE_TELEOP), hq_msgs_MODE_LAND);
}

TEST(GroundStation, ModeNamesCoverOutOfRangeValues) {
  EXPECT_STREQ(to_string(hq_msgs_MODE_LAND), "land");
  EXPECT_STREQ(to_string(hq::testing::wire_enum<hq_msgs_Mode>(42)), "invalid");
  EXPECT_STREQ(to_string(hq::testing::wire_enum<hq_msgs_Health>(-3)), "invalid");
}

TEST(LatencyStats, QuantilesFollowTheSamples) {
  LatencyStats stats;
  EXPECT_EQ(stats.quantile_ms(0.5), 0.0);
  for (int i = 1; i <= 100; ++i) stats.add(i * 100'000LL);  // 0.1 .. 10 ms
  EXPECT_NEAR(stats.quantile_ms(0.5), 5.0, 0.02);
  EXPECT_NEAR(stats.quantile_ms(0.99), 9.9, 0.02);
  stats.add(-5);  // clock step: clamped into the first bin, not out of the array
  stats.add(1'000'000'000'000LL);
  EXPECT_EQ(stats.count(), 102);
}

TEST(LatencyStats, CoarseBinsReachSeconds) {
  // Round trips and state ages over a slow link: 1 ms bins up to 10 s.
  LatencyStats stats(1'000'000, 10'000);
  for (int i = 1; i <= 100; ++i) stats.add(i * 12'000'000LL);  // 12 .. 1200 ms
  EXPECT_NEAR(stats.quantile_ms(0.5), 601.0, 1.0);
  EXPECT_NEAR(stats.quantile_ms(0.99), 1189.0, 1.0);
}

TEST(TelemetryRecorder, UnwritableDirectoryIsNamed) {
  EXPECT_THAT(hq::testing::input_error_message([] { TelemetryRecorder r("/proc/no/such/dir"); }),
              HasSubstr("--record /proc/no/such/dir"));
}

TEST(MarkerTaskOf, NamesTheCommandLineTasksAndRejectsOthers) {
  EXPECT_EQ(marker_task_of("hold"), hq_msgs_MARKER_TASK_HOLD);
  EXPECT_EQ(marker_task_of("goto"), hq_msgs_MARKER_TASK_GO_TO);
  EXPECT_EQ(marker_task_of("land"), hq_msgs_MARKER_TASK_LAND);
  EXPECT_FALSE(marker_task_of("none").has_value());
  EXPECT_FALSE(marker_task_of("Land").has_value());
}

namespace fs = std::filesystem;

using hq::testing::slurp;

fs::path fresh_dir(const std::string& name) { return hq::testing::fresh_dir("hq_ground", name); }

// GIVEN a folder that holds a recording, WHEN --record names it again, THEN it is refused and
// the recording is untouched (it used to be truncated).
TEST(TelemetryRecorder, ExistingRecordingIsRefusedNotTruncated) {
  const fs::path dir = fresh_dir("existing");
  {
    TelemetryRecorder first(dir.string());
    link::VehicleState s{};
    first.state(1'000'000'000LL, 0, s);
    ASSERT_TRUE(first.close()) << first.error();
  }
  const auto size = fs::file_size(dir / "telemetry.csv");
  EXPECT_THAT(hq::testing::input_error_message([&] { TelemetryRecorder again(dir.string()); }),
              HasSubstr("--record " + dir.string() +
                        ": already holds a recording (telemetry.csv); refusing to overwrite it"));
  EXPECT_EQ(fs::file_size(dir / "telemetry.csv"), size);
  fs::remove_all(dir);
}

// GIVEN a file size limit standing in for a full disk (RLIMIT_FSIZE: writes past it fail with
// EFBIG as they would with ENOSPC), WHEN a flight is recorded past it, THEN flush and close say
// which file failed and why, instead of losing the rows silently.
TEST(TelemetryRecorder, FullDiskIsReportedByFlushAndClose) {
  const fs::path dir = fresh_dir("full");
  rlimit saved{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
  const auto previous_handler = signal(SIGXFSZ, SIG_IGN);
  rlimit small = saved;
  small.rlim_cur = 16 * 1024;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
  bool flushed = true;
  bool closed = true;
  std::string error;
  {
    TelemetryRecorder recorder(dir.string());
    for (int i = 0; i < 2000 && flushed; ++i) {
      link::VehicleState s{};
      s.sequence_number = static_cast<std::uint64_t>(i + 1);
      recorder.state(1'000'000'000LL + i * 1'000'000LL, 0, s);
      if (i % 100 == 99) flushed = recorder.flush();
    }
    closed = recorder.close();
    error = recorder.error();
  }
  setrlimit(RLIMIT_FSIZE, &saved);
  signal(SIGXFSZ, previous_handler);
  EXPECT_FALSE(flushed);
  EXPECT_FALSE(closed);
  EXPECT_THAT(error, HasSubstr(dir.string() + "/telemetry.csv: write failed: File too large; "
                                              "the recording stops here"));
  fs::remove_all(dir);
}

TEST(TelemetryRecorder, CompleteRecordingClosesCleanly) {
  const fs::path dir = fresh_dir("clean");
  TelemetryRecorder recorder(dir.string());
  link::VehicleState s{};
  recorder.state(1'000'000'000LL, 0, s);
  EXPECT_TRUE(recorder.flush());
  EXPECT_TRUE(recorder.close());
  EXPECT_TRUE(recorder.close());
  EXPECT_EQ(recorder.error(), "");
  fs::remove_all(dir);
}

// hq-ground --record into an existing recording exits 2 naming it, before any link is set up.
TEST(HqGround, RecordIntoAnExistingRecordingExitsTwo) {
  const fs::path dir = fresh_dir("process");
  { TelemetryRecorder first(dir.string()); }
  const fs::path out =
      fs::temp_directory_path() / ("hq_ground_" + std::to_string(getpid()) + ".out");
  hq::testing::Process p({HQ_GROUND_EXE, "--device", "sim", "--headless", "--duration-s", "1",
                          "--insecure", "--record", dir.string()},
                         out.string());
  EXPECT_EQ(p.wait_exit(60.0), 2);
  EXPECT_THAT(slurp(out), HasSubstr("hq-ground: --record " + dir.string() +
                                    ": already holds a recording (telemetry.csv)"));
  fs::remove(out);
  fs::remove_all(dir);
}

// GIVEN a recording with one garbled stamp, WHEN hq-ground replays it, THEN it exits 2 naming
// file:line at once instead of waiting for years.
TEST(HqGround, ReplayOfAGarbledStampExitsTwoNamingFileAndLine) {
  const fs::path dir = fresh_dir("garbled_replay");
  {
    TelemetryRecorder recorder(dir.string());
    for (int i = 0; i < 5; ++i) {
      link::VehicleState s{};
      recorder.state(1'000'000'000LL + i * 50'000'000LL, 0, s);
    }
    recorder.state(9'000'000'000'000'000'000LL, 0, link::VehicleState{});
  }
  const fs::path out =
      fs::temp_directory_path() / ("hq_ground_replay_" + std::to_string(getpid()) + ".out");
  hq::testing::Process p({HQ_GROUND_EXE, "--replay", dir.string(), "--headless"}, out.string());
  EXPECT_EQ(p.wait_exit(30.0), 2);
  EXPECT_THAT(slurp(out), HasSubstr("hq-ground: " + (dir / "telemetry.csv").string() +
                                    ":35: receipt_ns = 9000000000000000000 is "));
  fs::remove(out);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hq::ground
