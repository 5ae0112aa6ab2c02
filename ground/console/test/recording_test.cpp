#include "hq/console/recording.hpp"

#include "hq/base/format_into.hpp"
#include "hq/ground/ground_station.hpp"
#include "hq/testing/files.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

namespace hq::console {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using hq::testing::slurp;

fs::path fresh_dir(const std::string& name) { return hq::testing::fresh_dir("hq_console", name); }

// GIVEN a recording written by the ground's recorder, WHEN read back, THEN every row returns.
void write_recording(const fs::path& dir, int states) {
  ground::TelemetryRecorder recorder(dir.string());
  for (int i = 0; i < states; ++i) {
    link::VehicleState s{};
    s.sequence_number = static_cast<std::uint64_t>(i + 1);
    s.t_ns = i * 33'000'000LL;
    s.v_H_mps = {0.1F * static_cast<float>(i), 0, 0};
    s.mode = i < 5 ? hq_msgs_MODE_HOVER : hq_msgs_MODE_TELEOP;
    recorder.state(1'000'000'000LL + i * 33'000'000LL, 2'000'000, s);
    haptics::VelocityCommand c;
    c.v_H_mps = {0.5, 0, 0};
    recorder.command(1'000'000'000LL + i * 33'000'000LL, c, true);
  }
  link::Event e{};
  hq::format_into(e.text, "hello, \"world\"");
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

TEST(Recording, RoundTripsPositionTruthAndMarkerCount) {
  const fs::path dir = fresh_dir("extras");
  {
    ground::TelemetryRecorder recorder(dir.string());
    hq_msgs_MarkerInCamera seen[3]{};
    for (int i = 0; i < 3; ++i) {
      link::VehicleState s{};
      s.sequence_number = static_cast<std::uint64_t>(i + 1);
      s.mode = hq_msgs_MODE_MARKER;
      s.position_valid = i != 1;
      s.position_invalid_reason = i == 1 ? 2 : 0;  // no marker for too long
      s.position_age_s = i == 1 ? 3.25F : 0.125F;
      s.position_sigma_m = 0.0625F;
      s.p_W_m = {1.5F + static_cast<float>(i), -0.25F, -1.125F};
      s.yaw_W_rad = 0.75F * static_cast<float>(i);
      s.truth_valid = i == 2;
      s.v_truth_H_mps = {0.5F, -0.125F * static_cast<float>(i), 0.0625F};
      s.markers._buffer = seen;
      s.markers._length = static_cast<std::uint32_t>(i + 1);
      s.markers._maximum = 3;
      recorder.state(1'000'000'000LL + i * 10'000'000LL, 1'000'000, s);
    }
  }
  const Recording r = load_recording(dir.string());
  ASSERT_EQ(r.states.size(), 3U);
  EXPECT_TRUE(r.absent_columns.empty()) << r.absent_columns.front();
  EXPECT_TRUE(r.states[0].position_valid);
  EXPECT_FALSE(r.states[1].position_valid);
  EXPECT_EQ(r.states[0].position_invalid_reason, 0);
  EXPECT_EQ(r.states[1].position_invalid_reason, 2);
  EXPECT_FLOAT_EQ(r.states[1].position_age_s, 3.25F);
  EXPECT_FLOAT_EQ(r.states[1].position_sigma_m, 0.0625F);
  EXPECT_FLOAT_EQ(r.states[2].p_W_m[0], 3.5F);
  EXPECT_FLOAT_EQ(r.states[2].p_W_m[1], -0.25F);
  EXPECT_FLOAT_EQ(r.states[2].p_W_m[2], -1.125F);
  EXPECT_FLOAT_EQ(r.states[2].yaw_W_rad, 1.5F);
  EXPECT_FALSE(r.states[1].truth_valid);
  EXPECT_TRUE(r.states[2].truth_valid);
  EXPECT_FLOAT_EQ(r.states[2].v_truth_H_mps[0], 0.5F);
  EXPECT_FLOAT_EQ(r.states[2].v_truth_H_mps[1], -0.25F);
  EXPECT_FLOAT_EQ(r.states[2].v_truth_H_mps[2], 0.0625F);
  EXPECT_EQ(r.states[0].markers_n, 1);
  EXPECT_EQ(r.states[2].markers_n, 3);
  EXPECT_EQ(r.problem_count, 0U) << (r.problems.empty() ? "" : r.problems[0]);
  fs::remove_all(dir);
}

// GIVEN states with the vehicle's flight fields (and one from a vehicle that leaves them at
// zero), WHEN recorded and read back, THEN they return, and the unfilled ones read as unknown
// rather than as a clearance of 0 m on the floor.
TEST(Recording, FlightFieldsRoundTripAndUnfilledOnesAreUnknown) {
  const fs::path dir = fresh_dir("flight_fields");
  {
    ground::TelemetryRecorder recorder(dir.string());
    link::VehicleState s{};
    s.sequence_number = 1;
    s.mode = hq_msgs_MODE_TELEOP;
    recorder.state(1'000'000'000LL, 1'000'000, s);  // session 0: fields not filled
    s.sequence_number = 2;
    s.session_id = 0xfeedbeefcafeULL;
    s.commanding_station_id = 7;
    s.flight_state = hq_msgs_FLIGHT_AIRBORNE;
    s.motors_armed = true;
    s.height_source = hq_msgs_HEIGHT_DEPTH;
    s.height_m = 1.25F;
    s.operator_input = hq_msgs_INPUT_LIMITED_UNSEEN;
    s.v_cmd_flown_H_mps = {0.3F, 0, 0};
    s.clearance_m = 0.347F;
    recorder.state(1'033'000'000LL, 1'000'000, s);
    s.sequence_number = 3;
    s.height_source = hq_msgs_HEIGHT_NONE;
    s.clearance_m = -1;
    recorder.state(1'066'000'000LL, 1'000'000, s);
  }
  const Recording r = load_recording(dir.string());
  ASSERT_EQ(r.states.size(), 3U) << (r.problems.empty() ? "" : r.problems[0]);
  EXPECT_FALSE(r.states[0].flight_fields);
  EXPECT_TRUE(std::isnan(r.states[0].clearance_m));
  EXPECT_STREQ(r.states[0].flight_state, "unknown");
  const RecordedState& a = r.states[1];
  EXPECT_TRUE(a.flight_fields);
  EXPECT_EQ(a.session_id, 0xfeedbeefcafeULL);
  EXPECT_EQ(a.commanding_station_id, 7U);
  EXPECT_STREQ(a.flight_state, "airborne");
  EXPECT_EQ(a.motors_armed, 1);
  EXPECT_STREQ(a.height_source, "depth");
  EXPECT_NEAR(a.height_m, 1.25, 1e-4);
  EXPECT_STREQ(a.operator_input, "limited_unseen");
  EXPECT_NEAR(a.v_cmd_flown_H_mps[0], 0.3F, 1e-4);
  EXPECT_NEAR(a.clearance_m, 0.347, 1e-4);
  EXPECT_TRUE(std::isnan(r.states[2].height_m));     // source none
  EXPECT_TRUE(std::isnan(r.states[2].clearance_m));  // < 0: none seen
  EXPECT_TRUE(r.absent_columns.empty());
  fs::remove_all(dir);
}

// GIVEN a telemetry.csv of the first layout (no closest obstacle, pose, truth or markers),
// WHEN read, THEN every row returns with those fields absent, and the absent columns are named.
TEST(Recording, OldLayoutLoadsAndNamesTheAbsentColumns) {
  const fs::path dir = fresh_dir("old_layout");
  fs::create_directories(dir);
  std::ofstream(dir / "telemetry.csv")
      << "# hq-ground telemetry v1\n"
         "receipt_ns,latency_us,sequence,t_ns,v_H_x_mps,v_H_y_mps,v_H_z_mps,omega_B_x_radps,"
         "omega_B_y_radps,omega_B_z_radps,roll_rad,pitch_rad,v_obs_H_x_mps,v_obs_H_y_mps,v_obs_H_z_"
         "mps,"
         "mode,estimator_health,link_health,vehicle_id\n"
         "1000,5.0,1,0,0.2500,0,0,0,0,0,0,0,0,0,0,hover,ok,ok,1\n"
         "2000,5.0,2,10,0.5000,0,0,0,0,0,0,0,0,0,0,teleop,ok,ok,1\n";
  const Recording r = load_recording(dir.string());
  ASSERT_EQ(r.states.size(), 2U);
  EXPECT_FLOAT_EQ(r.states[1].v_H_mps[0], 0.5F);
  EXPECT_FALSE(r.states[1].position_valid);
  EXPECT_FALSE(r.states[1].truth_valid);
  EXPECT_EQ(r.states[1].markers_n, -1);
  EXPECT_TRUE(std::isnan(r.states[1].closest_obstacle_m));
  EXPECT_THAT(
      r.absent_columns,
      ::testing::IsSupersetOf({"telemetry.csv: closest_obstacle_m", "telemetry.csv: position_valid",
                               "telemetry.csv: truth_valid", "telemetry.csv: v_truth_H_x_mps",
                               "telemetry.csv: markers_n"}));
  // 11 of the second layout's columns, 11 of the flight fields' (session .. clearance), the
  // two hover thrust columns, the three of the position's validity, the eight of telemetry v3
  // (modes offered, marker target, explore phase, link figures), the eleven of the odom pose and
  // the two files of telemetry v2 (obstacles.csv, markers.csv).
  EXPECT_EQ(r.absent_columns.size(), 48U);
  EXPECT_THAT(r.absent_columns,
              ::testing::Contains(HasSubstr("obstacles.csv (the whole file: an older recording; "
                                            "replay shows no obstacle cloud)")));
  EXPECT_FALSE(r.states[1].flight_fields);
  EXPECT_STREQ(r.states[1].flight_state, "unknown");
  EXPECT_TRUE(std::isnan(r.states[1].height_m));
  EXPECT_TRUE(std::isnan(r.states[1].clearance_m));
  for (const std::string& p : r.problems) EXPECT_THAT(p, ::testing::Not(HasSubstr("telemetry")));
  fs::remove_all(dir);
}

// GIVEN a telemetry.csv written before the frame-letter rename (omega_x_radps for omega_B_x_radps,
// v_obs_x_mps for v_obs_H_x_mps), WHEN read, THEN the gyro rates and the repulsion load from the
// old columns, with nothing reported missing.
TEST(Recording, ColumnsNamedBeforeTheFrameLetterRenameLoad) {
  const fs::path dir = fresh_dir("before_rename");
  fs::create_directories(dir);
  std::ofstream(dir / "telemetry.csv")
      << "# hq-ground telemetry v1\n"
         "receipt_ns,latency_us,sequence,t_ns,v_H_x_mps,v_H_y_mps,v_H_z_mps,"
         "omega_x_radps,omega_y_radps,omega_z_radps,"  // vocabulary: old spelling
         "roll_rad,pitch_rad,"
         "v_obs_x_mps,v_obs_y_mps,v_obs_z_mps,"  // vocabulary: old spelling
         "mode,estimator_health,link_health,vehicle_id\n"
         "1000,5.0,1,0,0.25,0,0,0.1,-0.2,0.3,0,0,0.4,-0.5,0.6,hover,ok,ok,1\n";
  const Recording r = load_recording(dir.string());
  ASSERT_EQ(r.states.size(), 1U);
  EXPECT_FLOAT_EQ(r.states[0].omega_B_radps[0], 0.1F);
  EXPECT_FLOAT_EQ(r.states[0].omega_B_radps[1], -0.2F);
  EXPECT_FLOAT_EQ(r.states[0].omega_B_radps[2], 0.3F);
  EXPECT_FLOAT_EQ(r.states[0].v_obs_H_mps[0], 0.4F);
  EXPECT_FLOAT_EQ(r.states[0].v_obs_H_mps[1], -0.5F);
  EXPECT_FLOAT_EQ(r.states[0].v_obs_H_mps[2], 0.6F);
  for (const std::string& p : r.problems) EXPECT_THAT(p, ::testing::Not(HasSubstr("telemetry")));
  EXPECT_THAT(r.absent_columns, ::testing::Not(::testing::Contains(HasSubstr("omega"))));
  EXPECT_THAT(r.absent_columns, ::testing::Not(::testing::Contains(HasSubstr("v_obs"))));
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
  EXPECT_THAT(r.problems[0], HasSubstr("telemetry.csv:33: v_H_x_mps = 'abc'"));
  EXPECT_THAT(r.problems[1], HasSubstr("telemetry.csv:39: expected 65 fields"));
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

// GIVEN one telemetry stamp garbled by a flipped digit (years ahead), WHEN loaded, THEN it is
// rejected naming file:line and the gap, instead of a replay that waits for years.
TEST(Recording, GarbledStampIsRejectedNamingFileAndLine) {
  const fs::path dir = fresh_dir("garbled_stamp");
  write_recording(dir, 10);
  std::string text = slurp(dir / "telemetry.csv");
  const std::size_t row = text.find("\n1099000000,");
  ASSERT_NE(row, std::string::npos);
  text.replace(row + 1, 10, "9099000000000000000");
  std::ofstream(dir / "telemetry.csv") << text;
  const std::string message =
      hq::testing::input_error_message([&] { load_recording(dir.string()); });
  EXPECT_THAT(message, HasSubstr("telemetry.csv:33: receipt_ns = 9099000000000000000 is "));
  EXPECT_THAT(message, HasSubstr("after line 32's 1066000000, expected rows in time order at most "
                                 "3600 s apart"));
  fs::remove_all(dir);
}

TEST(Recording, StampGoingBackIsRejectedNamingFileAndLine) {
  const fs::path dir = fresh_dir("backwards_stamp");
  write_recording(dir, 10);
  std::string text = slurp(dir / "commands.csv");
  const std::size_t row = text.find("\n1099000000,");
  ASSERT_NE(row, std::string::npos);
  text.replace(row + 1, 10, "1000000001");
  std::ofstream(dir / "commands.csv") << text;
  EXPECT_THAT(hq::testing::input_error_message([&] { load_recording(dir.string()); }),
              HasSubstr("commands.csv:8: t_ns = 1000000001 is 0.066 s before line 7's "
                        "1066000000"));
  fs::remove_all(dir);
}

// A file of a single garbled row is in order by itself; it starts far from the others.
TEST(Recording, FileStartingFarFromTheOthersIsRejected) {
  const fs::path dir = fresh_dir("far_file");
  write_recording(dir, 10);
  std::string text = slurp(dir / "events.csv");
  const std::size_t row = text.find("\n1100000000,");
  ASSERT_NE(row, std::string::npos);
  text.replace(row + 1, 10, "5100000000000000000");
  std::ofstream(dir / "events.csv") << text;
  EXPECT_THAT(hq::testing::input_error_message([&] { load_recording(dir.string()); }),
              HasSubstr("events.csv:4: first stamp 5100000000000000000 is 5.1e+09 s after "
                        "telemetry.csv:30's 1000000000, expected the files of one recording to "
                        "start within 3600 s"));
  fs::remove_all(dir);
}

TEST(Recording, AbsurdFrameTimestampIsRejected) {
  const fs::path dir = fresh_dir("frame_stamp");
  write_recording(dir, 3);
  std::ofstream(dir / "rgb" / "1.000000.jpg") << "jpeg";
  std::ofstream(dir / "rgb.txt", std::ios::app) << "1e300 rgb/1.000000.jpg\n";
  EXPECT_THAT(hq::testing::input_error_message([&] { load_recording(dir.string()); }),
              HasSubstr("rgb.txt:3: timestamp = 1e300, expected seconds since 1970"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hq::console
