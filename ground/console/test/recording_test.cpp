#include "hq/console/recording.hpp"

#include "hq/ground/ground_station.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace hq::console {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() /
                       ("hq_console_" + std::to_string(getpid()) + "_" + name);
  fs::remove_all(dir);
  return dir;
}

// GIVEN a recording written by the ground's recorder, WHEN read back, THEN every row returns.
void write_recording(const fs::path& dir, int states) {
  ground::TelemetryRecorder recorder(dir.string());
  for (int i = 0; i < states; ++i) {
    link::VehicleState s{};
    s.sequence_number = static_cast<unsigned long long>(i + 1);
    s.t_ns = i * 33'000'000LL;
    s.v_H_mps = {0.1F * static_cast<float>(i), 0, 0};
    s.mode = i < 5 ? hq_msgs_MODE_HOVER : hq_msgs_MODE_TELEOP;
    recorder.state(1'000'000'000LL + i * 33'000'000LL, 2'000'000, s);
    haptics::VelocityCommand c;
    c.v_H_mps = {0.5, 0, 0};
    recorder.command(1'000'000'000LL + i * 33'000'000LL, c, true);
  }
  link::Event e{};
  std::snprintf(e.text, sizeof e.text, "hello, \"world\"");
  recorder.event(1'100'000'000LL, e);
}

TEST(Recording, RoundTripsStatesCommandsAndEvents) {
  const fs::path dir = fresh_dir("round_trip");
  write_recording(dir, 10);
  const Recording r = load_recording(dir.string());
  ASSERT_EQ(r.states.size(), 10U);
  EXPECT_EQ(r.commands.size(), 10U);
  ASSERT_EQ(r.events.size(), 1U);
  EXPECT_EQ(r.events[0].text, "hello, 'world'");
  EXPECT_STREQ(r.states[0].mode, "hover");
  EXPECT_STREQ(r.states[9].mode, "teleop");
  EXPECT_NEAR(r.states[9].v_H_mps[0], 0.9F, 1e-4);
  EXPECT_EQ(r.problem_count, 0U) << (r.problems.empty() ? "" : r.problems[0]);
  fs::remove_all(dir);
}

TEST(Recording, TruncatedAndCorruptLinesAreNamedAndTheRestIsRead) {
  const fs::path dir = fresh_dir("truncated");
  write_recording(dir, 10);
  // Cut the telemetry mid-line and spoil one number.
  std::ifstream in(dir / "telemetry.csv");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  in.close();
  text.resize(text.size() - 40);
  const std::size_t row4 = text.find("\n1099000000,");
  ASSERT_NE(row4, std::string::npos);
  text.replace(text.find(",0.3000,", row4), 8, ",abc,");
  std::ofstream(dir / "telemetry.csv") << text;
  const Recording r = load_recording(dir.string());
  EXPECT_EQ(r.states.size(), 8U);
  ASSERT_EQ(r.problem_count, 2U);
  EXPECT_THAT(r.problems[0], HasSubstr("telemetry.csv:11: v_H_x_mps = 'abc'"));
  EXPECT_THAT(r.problems[1], HasSubstr("telemetry.csv:17: expected 20 fields"));
  fs::remove_all(dir);
}

TEST(Recording, ForeignDirectoryIsRejectedAndForeignCsvNamed) {
  const fs::path dir = fresh_dir("foreign");
  fs::create_directories(dir);
  EXPECT_THAT(hq::testing::input_error_message([&] { load_recording(dir.string()); }),
              HasSubstr("not an hq-ground recording"));
  std::ofstream(dir / "telemetry.csv") << "time,x,y\n1,2,3\n";
  const Recording r = load_recording(dir.string());
  EXPECT_TRUE(r.states.empty());
  ASSERT_FALSE(r.problems.empty());
  EXPECT_THAT(r.problems[0], HasSubstr("telemetry.csv:1: header has no column receipt_ns"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hq::console
