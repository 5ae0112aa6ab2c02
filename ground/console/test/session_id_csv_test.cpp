// The vehicle session in telemetry.csv: written in hex as the console says it, read back, and
// older recordings' decimal still read.
#include "hq/console/recording.hpp"
#include "hq/ground/ground_station.hpp"
#include "hq/testing/files.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace hq::console {
namespace {

namespace fs = std::filesystem;

void record_one_state(const fs::path& dir) {
  ground::TelemetryRecorder recorder(dir.string());
  link::VehicleState s{};
  s.sequence_number = 1;
  s.mode = hq_msgs_MODE_TELEOP;
  s.session_id = 0xfeedbeefcafeULL;
  s.flight_state = hq_msgs_FLIGHT_AIRBORNE;
  recorder.state(1'000'000'000LL, 1'000'000, s);
}

TEST(SessionIdCsv, WrittenInHexAsTheConsoleSaysItAndReadBack) {
  const fs::path dir = hq::testing::fresh_dir("hq_console", "session_hex");
  record_one_state(dir);
  const std::string text = hq::testing::slurp(dir / "telemetry.csv");
  // The console's "new session 0x0000feedbeefcafe", character for character.
  EXPECT_NE(text.find(",0x0000feedbeefcafe,"), std::string::npos) << text;
  const Recording r = load_recording(dir.string());
  ASSERT_EQ(r.states.size(), 1U) << (r.problems.empty() ? "" : r.problems[0]);
  EXPECT_EQ(r.states[0].session_id, 0xfeedbeefcafeULL);
  fs::remove_all(dir);
}

TEST(SessionIdCsv, OlderRecordingsDecimalSessionIsStillRead) {
  const fs::path dir = hq::testing::fresh_dir("hq_console", "session_decimal");
  record_one_state(dir);
  std::string text = hq::testing::slurp(dir / "telemetry.csv");
  const std::size_t at = text.find("0x0000feedbeefcafe");
  ASSERT_NE(at, std::string::npos);
  text.replace(at, 18, "280297064090366");  // 0xfeedbeefcafe as the recorder wrote it before
  std::ofstream(dir / "telemetry.csv") << text;
  const Recording r = load_recording(dir.string());
  ASSERT_EQ(r.states.size(), 1U) << (r.problems.empty() ? "" : r.problems[0]);
  EXPECT_EQ(r.states[0].session_id, 0xfeedbeefcafeULL);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hq::console
