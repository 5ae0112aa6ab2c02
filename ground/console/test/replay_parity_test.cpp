// GIVEN a flight's vehicle states fed to a live console (the link's path, LiveStateFeed), WHEN
// they are recorded as hq-ground records them (the CSV files by TelemetryRecorder, the MCAP as
// the link's CDR, here serialised by Cyclone itself) and replayed through ReplayPlayer into a
// second console, THEN every replayed frame shows what the live one showed: flight state,
// motors, height, clearance, operator input, thrust, the obstacle cloud placed in the top
// view, the track and heading, the markers and the state latency, the modes the vehicle offers,
// its marker target and explore phase, the ground's own link figures (state age, round trip)
// and, after the vehicle's goodbye event, the "vehicle ended" banner.
#include "hq/base/format_into.hpp"
#include "hq/console/console_model.hpp"
#include "hq/console/recording.hpp"
#include "hq/console/replay_player.hpp"
#include "hq/console/state_feed.hpp"
#include "hq/ground/ground_station.hpp"
#include "hq/link/link.hpp"
#include "hq/mcap/mcap.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/files.hpp"

#include <dds/ddsi/ddsi_cdrstream.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fmt/format.h>
#include <string>
#include <vector>

namespace hq::console {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

constexpr std::int64_t kT0_ns = 1'700'000'000'000'000'000LL;
constexpr std::int64_t kPeriod_ns = 33'000'000;
constexpr std::int64_t kLatency_ns = 2'500'000;  // exact in the CSV's latency_us (%.1f)
constexpr int kStates = 60;
constexpr const char* kGoodbye = "vehicle ended: stopped by SIGTERM; landed";

// What the ground measured of the link as state i arrived (exact at the CSV's 3 decimals).
LinkFigures figures_at(int i) {
  return {12.5F + 0.25F * static_cast<float>(i), 40.0F + 0.5F * static_cast<float>(i % 7)};
}

// A state and the storage its sequences point into.
struct FlightState {
  link::VehicleState s{};
  std::vector<hq_msgs_Vector3f> cloud;
  std::vector<hq_msgs_MarkerInCamera> markers;
};

// A flight through every phase: landed with the motors idle, taking off (height estimated),
// airborne over the floor (height from depth) near a wall (a cloud every 10th state, the
// clearance shrinking, the command limited), a marker in view and the marker filter's pose for
// a stretch, then landing. Values are exact at the CSV's 4 decimals.
std::vector<FlightState> make_flight() {
  std::vector<FlightState> flight(kStates);
  for (int i = 0; i < kStates; ++i) {
    FlightState& f = flight[static_cast<std::size_t>(i)];
    link::VehicleState& s = f.s;
    const auto k = static_cast<float>(i);
    s.vehicle_id = 1;
    s.sequence_number = 100U + static_cast<std::uint64_t>(i);
    s.t_ns = 5'000'000'000LL + i * kPeriod_ns;
    s.session_id = 0xABCDEFULL;
    s.commanding_station_id = 7;
    s.mode = i < 10 ? hq_msgs_MODE_HOVER : hq_msgs_MODE_TELEOP;
    s.estimator_health = hq_msgs_HEALTH_OK;
    s.link_health = i == 30 ? hq_msgs_HEALTH_DEGRADED : hq_msgs_HEALTH_OK;
    s.v_H_mps = {i < 10 ? 0.0F : 0.25F, 0.0625F, i < 10 ? -0.5F : 0.0F};
    s.omega_B_radps = {0.0F, 0.0F, i >= 20 && i < 30 ? 0.5F : 0.0F};
    s.roll_rad = 0.0125F;
    s.pitch_rad = -0.025F;
    s.v_obs_H_mps = {i >= 20 ? -0.125F : 0.0F, 0.0F, 0.0F};
    if (i < 5) {
      s.flight_state = hq_msgs_FLIGHT_LANDED;
      s.motors_armed = false;
      s.height_source = hq_msgs_HEIGHT_ESTIMATE;
      s.height_m = 0.05F;
      s.operator_input = hq_msgs_INPUT_IGNORED_LANDED;
    } else if (i < 15) {
      s.flight_state = hq_msgs_FLIGHT_TAKING_OFF;
      s.motors_armed = true;
      s.height_source = hq_msgs_HEIGHT_ESTIMATE;
      s.height_m = 0.05F + 0.0625F * static_cast<float>(i - 5);
      s.operator_input = hq_msgs_INPUT_IGNORED_MODE;
    } else if (i < 50) {
      s.flight_state = hq_msgs_FLIGHT_AIRBORNE;
      s.motors_armed = true;
      s.height_source = i == 40 ? hq_msgs_HEIGHT_NONE : hq_msgs_HEIGHT_DEPTH;
      s.height_m = i == 40 ? 0.0F : 1.25F;
      s.operator_input = i >= 25 ? hq_msgs_INPUT_LIMITED_UNSEEN : hq_msgs_INPUT_FLOWN;
    } else {
      s.flight_state = hq_msgs_FLIGHT_LANDING;
      s.motors_armed = true;
      s.height_source = hq_msgs_HEIGHT_ESTIMATE;
      s.height_m = 1.25F - 0.0625F * static_cast<float>(i - 50);
      s.operator_input = hq_msgs_INPUT_IGNORED_MODE;
    }
    s.v_cmd_flown_H_mps = {0.25F, 0.0F, 0.0F};
    s.clearance_m = i >= 15 ? 2.0F - 0.03125F * static_cast<float>(i - 15) : -1.0F;
    s.hover_thrust_gain = i >= 15 ? 0.9375F : 0.0F;
    s.hover_thrust_converged = i >= 35;
    s.position_valid = i >= 42 && i < 48;
    s.p_W_m = {s.position_valid ? 1.5F + 0.0625F * (k - 42.0F) : 0.0F,
               s.position_valid ? -0.75F : 0.0F, -1.25F};
    s.yaw_W_rad = s.position_valid ? 0.5F : 0.0F;
    s.truth_valid = true;
    s.v_truth_H_mps = {0.25F, 0.0F, 0.0F};
    // Flying to marker 3 from state 40, exploring (phase 3) for a stretch of it.
    s.marker_target_valid = i >= 40 && i < 52;
    s.marker_target_id = s.marker_target_valid ? 3 : 0;
    s.explore_phase = i >= 44 && i < 50 ? 3 : 0;
    // The first half from a vehicle without its marker stage, the second with it.
    if (i < 30) {
      s.modes_offered = link::kModesWithoutMarkerStage;
      s.marker_mode_off_reason = s.explore_mode_off_reason = link::kModeOffMarkerStageDisabled;
    } else {
      s.modes_offered = link::kModesOfferedMask;
    }
    // The odom pose: integrated from take-off on, its sigmas growing (exact at 4 decimals).
    s.odom_valid = i >= 5;
    s.p_odom_m = {s.odom_valid ? 0.0625F * (k - 5.0F) : 0.0F, s.odom_valid ? -0.125F : 0.0F,
                  s.odom_valid ? -1.0F : 0.0F};
    s.yaw_odom_rad = s.odom_valid ? 0.25F + 0.0625F * k : 0.0F;
    s.odom_position_sigma_m = s.odom_valid ? 0.0625F * (k - 5.0F) : 0.0F;
    s.odom_yaw_sigma_rad = s.odom_valid ? 0.0625F : 0.0F;
    s.odom_yaw_relative_to_start = true;
    s.v_H_sigma_mps = {0.0625F, 0.0625F, 0.125F};
    if (i >= 15 && i % 10 == 5) {
      for (int p = 0; p < 12; ++p) {
        const auto q = static_cast<float>(p);
        f.cloud.push_back(
            {2.0F - 0.03125F * (k - 15.0F) + 0.0625F * q, -0.5F + 0.125F * q, 0.25F - 0.0625F * q});
      }
    }
    if (i >= 38 && i < 46) {
      f.markers.push_back({3, {0.125F, -0.0625F, 1.5F}, {0.96875F, 0.0F, 0.25F, 0.0F}});
    }
    s.obstacle_points_B_m._length = static_cast<std::uint32_t>(f.cloud.size());
    s.obstacle_points_B_m._maximum = s.obstacle_points_B_m._length;
    s.obstacle_points_B_m._buffer = f.cloud.empty() ? nullptr : f.cloud.data();
    s.obstacle_points_B_m._release = false;
    s.markers._length = static_cast<std::uint32_t>(f.markers.size());
    s.markers._maximum = s.markers._length;
    s.markers._buffer = f.markers.empty() ? nullptr : f.markers.data();
    s.markers._release = false;
  }
  return flight;
}

std::int64_t receipt_ns(int i) { return kT0_ns + i * kPeriod_ns; }

// The vehicle's goodbye, received three quarters of a period after the last state.
link::Event goodbye() {
  link::Event e{};
  e.vehicle_id = 1;
  e.sequence_number = 9;
  e.t_ns = 5'000'000'000LL + kStates * kPeriod_ns;
  e.severity = hq_msgs_SEVERITY_INFO;
  e.code = link::kEventCodeVehicleEnded;
  hq::format_into(e.text, "{}", kGoodbye);
  e.session_id = 0xABCDEFULL;
  return e;
}
std::int64_t goodbye_receipt_ns() {
  return kT0_ns + (kStates - 1) * kPeriod_ns + 3 * kPeriod_ns / 4;
}

// The CDR Cyclone sends for `s` (XCDR1, little endian), with its encapsulation header: what the
// recorder takes with dds_takecdr and writes unchanged.
template <typename T>
std::vector<std::uint8_t> cdr_of(const T& s) {
  dds_ostreamLE_t os;
  dds_ostreamLE_init(&os, 0, CDR_ENC_VERSION_1);
  dds_stream_writeLE(&os, reinterpret_cast<const char*>(&s),
                     link::TopicTraits<T>::descriptor().m_ops);
  std::vector<std::uint8_t> out = {0x00, 0x01, 0x00, 0x00};
  out.insert(out.end(), os.x.m_buffer, os.x.m_buffer + os.x.m_index);
  dds_ostreamLE_fini(&os);
  return out;
}

void write_mcap(const fs::path& path, const std::vector<FlightState>& flight) {
  mcap::McapWriter writer;
  writer.open(path.string());
  const std::string idl = "module hq_msgs { };";  // the schema's text is not read back
  const std::uint16_t schema =
      writer.add_schema("hq_msgs::VehicleState", "omgidl",
                        {reinterpret_cast<const std::uint8_t*>(idl.data()), idl.size()});
  const std::uint16_t channel = writer.add_channel(schema, "/hq/vehicle_state", "cdr");
  const std::uint16_t event_schema = writer.add_schema(
      "hq_msgs::Event", "omgidl", {reinterpret_cast<const std::uint8_t*>(idl.data()), idl.size()});
  const std::uint16_t events = writer.add_channel(event_schema, "/hq/event", "cdr");
  // The ground's own figures (the recorder's /ground/link, written per command tick: here one
  // tick just before each state).
  const std::uint16_t ground_link = writer.add_channel(0, "/ground/link", "json");
  for (int i = 0; i < kStates; ++i) {
    const LinkFigures f = figures_at(i);
    const std::string json =
        "{\"timestamp\":{\"sec\":0,\"nsec\":0},\"latency_ms\":2.5,"
        "\"round_trip_ms\":" +
        std::to_string(f.round_trip_ms) + ",\"state_age_ms\":" + std::to_string(f.state_age_ms) +
        "}";
    writer.write(ground_link, static_cast<std::uint32_t>(i), receipt_ns(i) - 1000,
                 receipt_ns(i) - 1000,
                 {reinterpret_cast<const std::uint8_t*>(json.data()), json.size()});
    writer.write(channel, static_cast<std::uint32_t>(i), receipt_ns(i), receipt_ns(i) - kLatency_ns,
                 cdr_of(flight[static_cast<std::size_t>(i)].s));
  }
  writer.write(events, 0, goodbye_receipt_ns(), goodbye_receipt_ns(), cdr_of(goodbye()));
  writer.close();
}

void write_csv(const fs::path& dir, const std::vector<FlightState>& flight) {
  ground::TelemetryRecorder recorder(dir.string());
  for (int i = 0; i < kStates; ++i) {
    const LinkFigures f = figures_at(i);
    recorder.state(receipt_ns(i), kLatency_ns, flight[static_cast<std::size_t>(i)].s,
                   std::llround(1e6 * static_cast<double>(f.state_age_ms)),
                   std::llround(1e6 * static_cast<double>(f.round_trip_ms)));
  }
  recorder.event(goodbye_receipt_ns(), goodbye());
  ASSERT_TRUE(recorder.close()) << recorder.error();
}

// What the console shows of the vehicle after a state: the snapshot's derived fields.
void expect_same_view(const Snapshot& live, const Snapshot& replayed, const std::string& where) {
  SCOPED_TRACE(where);
  constexpr float kTol = 2e-3F;  // the CSV's 4 decimals, integrated into the track
  EXPECT_TRUE(replayed.have_state);
  EXPECT_EQ(replayed.mode, live.mode);
  EXPECT_EQ(replayed.estimator_health, live.estimator_health);
  EXPECT_EQ(replayed.link_health, live.link_health);
  EXPECT_STREQ(replayed.flight_state, live.flight_state);
  EXPECT_EQ(replayed.motors_armed, live.motors_armed);
  EXPECT_EQ(replayed.height_valid, live.height_valid);
  EXPECT_NEAR(replayed.height_m, live.height_m, kTol);
  EXPECT_STREQ(replayed.height_source, live.height_source);
  EXPECT_STREQ(replayed.operator_input, live.operator_input);
  EXPECT_NEAR(replayed.clearance_m, live.clearance_m, kTol);
  EXPECT_NEAR(replayed.hover_thrust_gain, live.hover_thrust_gain, kTol);
  EXPECT_EQ(replayed.hover_thrust_converged, live.hover_thrust_converged);
  EXPECT_NEAR(replayed.roll_rad, live.roll_rad, kTol);
  EXPECT_NEAR(replayed.pitch_rad, live.pitch_rad, kTol);
  EXPECT_NEAR(replayed.yaw_W_rad, live.yaw_W_rad, kTol);
  EXPECT_NEAR(replayed.position_W.x_W_m, live.position_W.x_W_m, kTol);
  EXPECT_NEAR(replayed.position_W.y_W_m, live.position_W.y_W_m, kTol);
  EXPECT_EQ(replayed.position_from_vehicle, live.position_from_vehicle);
  EXPECT_EQ(replayed.position_states, live.position_states);
  EXPECT_EQ(replayed.have_truth, live.have_truth);
  EXPECT_EQ(replayed.modes_offered, live.modes_offered);
  EXPECT_STREQ(replayed.marker_mode_off, live.marker_mode_off);
  EXPECT_STREQ(replayed.explore_mode_off, live.explore_mode_off);
  EXPECT_EQ(replayed.marker_target_id, live.marker_target_id);
  EXPECT_STREQ(replayed.explore_phase, live.explore_phase);
  EXPECT_NEAR(replayed.latest.state_age_ms, live.latest.state_age_ms, 1e-3F);
  EXPECT_NEAR(replayed.latest.round_trip_ms, live.latest.round_trip_ms, 1e-3F);
  EXPECT_EQ(replayed.track_count, live.track_count);
  ASSERT_EQ(replayed.cloud_count, live.cloud_count);
  for (std::size_t i = 0; i < live.cloud_count; ++i) {
    EXPECT_NEAR(replayed.cloud_W[i].x_W_m, live.cloud_W[i].x_W_m, kTol) << "cloud point " << i;
    EXPECT_NEAR(replayed.cloud_W[i].y_W_m, live.cloud_W[i].y_W_m, kTol) << "cloud point " << i;
  }
  ASSERT_EQ(replayed.marker_count, live.marker_count);
  EXPECT_EQ(replayed.marker_detections, live.marker_detections);
  for (std::size_t i = 0; i < live.marker_count; ++i) {
    EXPECT_EQ(replayed.markers[i].id, live.markers[i].id);
    EXPECT_NEAR(replayed.markers[i].p_camera_marker_m[2], live.markers[i].p_camera_marker_m[2],
                kTol);
    EXPECT_NEAR(replayed.markers[i].q_camera_marker[2], live.markers[i].q_camera_marker[2], kTol);
  }
  EXPECT_NEAR(replayed.latest.latency_ms, live.latest.latency_ms, 1e-3F);
  EXPECT_NEAR(replayed.latest.v_est_H_mps[0], live.latest.v_est_H_mps[0], kTol);
  EXPECT_NEAR(replayed.latest.v_obs_H_mps[0], live.latest.v_obs_H_mps[0], kTol);
  EXPECT_NEAR(replayed.latest.v_truth_H_mps[0], live.latest.v_truth_H_mps[0], kTol);
}

// The live console after each state, frame by frame.
std::vector<Snapshot> live_frames(const std::vector<FlightState>& flight) {
  ConsoleModel live;
  LiveStateFeed feed;
  std::vector<Snapshot> frames;
  for (int i = 0; i < kStates; ++i) {
    feed.on_state(live, receipt_ns(i), 1e-6 * static_cast<double>(kLatency_ns),
                  flight[static_cast<std::size_t>(i)].s, figures_at(i));
    frames.push_back(live.make_snapshot());
    live.snapshot(frames.back());
  }
  return frames;
}

void expect_replay_matches_live(const Recording& r, const std::vector<Snapshot>& live) {
  ASSERT_EQ(r.states.size(), static_cast<std::size_t>(kStates));
  ReplayPlayer player(r);
  ConsoleModel replayed;
  Snapshot view = replayed.make_snapshot();
  std::uint64_t frames_missing = 0;
  for (int i = 0; i < kStates; ++i) {
    // Half a period after state i: it is shown, state i + 1 is not yet.
    player.seek(1e-9 * (static_cast<double>(i) + 0.5) * static_cast<double>(kPeriod_ns));
    player.feed(replayed, frames_missing);
    replayed.snapshot(view);
    expect_same_view(live[static_cast<std::size_t>(i)], view,
                     r.directory + ", state " + std::to_string(i));
    // The link panel's figures: the ground's, as recorded with the state
    EXPECT_NEAR(view.link.round_trip_ms, figures_at(i).round_trip_ms, 1e-3) << "state " << i;
    EXPECT_NEAR(view.link.state_one_way_ms, figures_at(i).state_age_ms, 1e-3) << "state " << i;
    EXPECT_FALSE(view.link.vehicle_ended) << "state " << i;
    ASSERT_FALSE(::testing::Test::HasFailure()) << "first difference at state " << i;
  }
  // After the goodbye: the live console's blue banner, its words the vehicle's.
  player.seek(player.timeline().duration_s);
  player.feed(replayed, frames_missing);
  replayed.snapshot(view);
  EXPECT_TRUE(view.link.vehicle_ended);
  char banner[256];
  ASSERT_TRUE(vehicle_ended_banner(view.link, banner, sizeof banner));
  EXPECT_THAT(banner, HasSubstr(kGoodbye));
}

// The live view must show the flight's fields (not the defaults both sides would share).
TEST(ReplayParity, TheLiveViewShowsEveryPhaseOfTheFlight) {
  const std::vector<FlightState> flight = make_flight();
  const std::vector<Snapshot> live = live_frames(flight);
  EXPECT_STREQ(live[2].flight_state, "landed");
  EXPECT_FALSE(live[2].motors_armed);
  EXPECT_STREQ(live[2].operator_input, "commands ignored: take off first");
  EXPECT_LT(live[2].clearance_m, 0.0F);
  EXPECT_STREQ(live[7].flight_state, "taking off");
  EXPECT_TRUE(live[7].motors_armed);
  EXPECT_STREQ(live[7].height_source, "estimate");
  EXPECT_STREQ(live[20].flight_state, "airborne");
  EXPECT_STREQ(live[20].height_source, "depth");
  EXPECT_FLOAT_EQ(live[20].height_m, 1.25F);
  EXPECT_FLOAT_EQ(live[20].clearance_m, 2.0F - 0.03125F * 5.0F);
  EXPECT_EQ(live[20].cloud_count, 12U);  // the cloud of state 15 stands
  EXPECT_FALSE(live[40].height_valid);
  EXPECT_EQ(live[30].link_health, "degraded");
  EXPECT_EQ(live[40].marker_count, 1U);
  EXPECT_TRUE(live[44].position_from_vehicle);
  EXPECT_STREQ(live[55].flight_state, "landing");
  EXPECT_TRUE(live[40].hover_thrust_converged);
  EXPECT_FLOAT_EQ(live[40].hover_thrust_gain, 0.9375F);
  EXPECT_THAT(live[10].explore_mode_off, HasSubstr("markers.enabled: false in its config"));
  EXPECT_THAT(live[10].marker_mode_off, HasSubstr("--config config/markers.yaml"));
  EXPECT_STREQ(live[40].marker_mode_off, "");
  EXPECT_EQ(live[40].modes_offered, link::kModesOfferedMask);
  EXPECT_EQ(live[45].marker_target_id, 3);
  EXPECT_STREQ(live[45].explore_phase, "explore");
  EXPECT_EQ(live[30].marker_target_id, -1);
  EXPECT_FLOAT_EQ(live[20].latest.state_age_ms, 17.5F);
}

// The live path runs on the flying thread: after construction it allocates nothing, even for
// the largest cloud and marker list the link allows.
TEST(ReplayParity, TheLivePathAllocatesNothingPerState) {
  std::vector<FlightState> flight = make_flight();
  FlightState& big = flight[25];
  big.cloud.assign(hq_msgs_kMaxObstaclePoints, {1.0F, 0.5F, 0.0F});
  big.markers.assign(hq_msgs_kMaxMarkersInState,
                     big.markers.empty() ? hq_msgs_MarkerInCamera{} : big.markers.front());
  big.s.obstacle_points_B_m = {hq_msgs_kMaxObstaclePoints, hq_msgs_kMaxObstaclePoints,
                               big.cloud.data(), false};
  big.s.markers = {hq_msgs_kMaxMarkersInState, hq_msgs_kMaxMarkersInState, big.markers.data(),
                   false};
  ConsoleModel live;
  LiveStateFeed feed;
  const long before = hq::testing::allocation_count();
  for (int round = 0; round < 3; ++round) {
    for (int i = 0; i < kStates; ++i) {
      feed.on_state(live, receipt_ns(round * kStates + i), 2.5,
                    flight[static_cast<std::size_t>(i)].s, {1.0F, 2.0F});
    }
  }
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
  EXPECT_EQ(feed.latest().obstacle_points_B_m.size(), 0U);  // the last state carried none
}

TEST(ReplayParity, McapReplayShowsWhatTheLiveConsoleShowedFrameByFrame) {
  const fs::path dir = testing::fresh_dir("hq_replay_parity", "mcap");
  fs::create_directories(dir);
  const std::vector<FlightState> flight = make_flight();
  write_mcap(dir / "flight.mcap", flight);
  const Recording r = load_recording((dir / "flight.mcap").string());
  EXPECT_EQ(r.problem_count, 0U) << (r.problems.empty() ? "" : r.problems[0]);
  expect_replay_matches_live(r, live_frames(flight));
  fs::remove_all(dir);
}

TEST(ReplayParity, CsvReplayShowsWhatTheLiveConsoleShowedFrameByFrame) {
  const fs::path dir = testing::fresh_dir("hq_replay_parity", "csv");
  const std::vector<FlightState> flight = make_flight();
  write_csv(dir, flight);
  const Recording r = load_recording(dir.string());
  EXPECT_EQ(r.absent_columns.size(), 0U) << (r.absent_columns.empty() ? "" : r.absent_columns[0]);
  // rgb.txt has no frame: the only problem allowed is none.
  EXPECT_EQ(r.problem_count, 0U) << (r.problems.empty() ? "" : r.problems[0]);
  expect_replay_matches_live(r, live_frames(flight));
  fs::remove_all(dir);
}

// The odom pose and the velocity's sigma (VehicleState's last fields) come back from the MCAP
// and the CSV as the live feed took them.
TEST(ReplayParity, TheOdomPoseReplaysAsTheLiveFeedRecordedIt) {
  const fs::path dir = testing::fresh_dir("hq_replay_parity", "odom");
  fs::create_directories(dir / "csv");
  const std::vector<FlightState> flight = make_flight();
  write_mcap(dir / "flight.mcap", flight);
  write_csv(dir / "csv", flight);
  for (const std::string& path : {(dir / "flight.mcap").string(), (dir / "csv").string()}) {
    SCOPED_TRACE(path);
    const Recording r = load_recording(path);
    ASSERT_EQ(r.states.size(), static_cast<std::size_t>(kStates));
    for (int i = 0; i < kStates; ++i) {
      RecordedState live;
      to_recorded(receipt_ns(i), 1e-6 * static_cast<double>(kLatency_ns),
                  flight[static_cast<std::size_t>(i)].s, live);
      const RecordedState& replayed = r.states[static_cast<std::size_t>(i)];
      EXPECT_EQ(replayed.odom_valid, live.odom_valid) << "state " << i;
      for (std::size_t a = 0; a < 3; ++a) {
        EXPECT_FLOAT_EQ(replayed.p_odom_m[a], live.p_odom_m[a]) << "state " << i;
        EXPECT_FLOAT_EQ(replayed.v_H_sigma_mps[a], live.v_H_sigma_mps[a]) << "state " << i;
      }
      EXPECT_FLOAT_EQ(replayed.yaw_odom_rad, live.yaw_odom_rad) << "state " << i;
      EXPECT_FLOAT_EQ(replayed.odom_position_sigma_m, live.odom_position_sigma_m) << i;
      EXPECT_FLOAT_EQ(replayed.odom_yaw_sigma_rad, live.odom_yaw_sigma_rad) << "state " << i;
      EXPECT_EQ(replayed.odom_yaw_relative_to_start, live.odom_yaw_relative_to_start) << i;
    }
    EXPECT_TRUE(r.states[30].odom_valid);  // not the defaults both sides would share
    EXPECT_FLOAT_EQ(r.states[30].p_odom_m[0], 0.0625F * 25.0F);
  }
  fs::remove_all(dir);
}

TEST(ReplayParity, AnOlderCsvRecordingNamesWhatItLacks) {
  const fs::path dir = testing::fresh_dir("hq_replay_parity", "older");
  write_csv(dir, make_flight());
  fs::remove(dir / "obstacles.csv");
  fs::remove(dir / "markers.csv");
  const Recording r = load_recording(dir.string());
  ASSERT_EQ(r.states.size(), static_cast<std::size_t>(kStates));
  std::string absent;
  for (const std::string& c : r.absent_columns) absent += c + "\n";
  EXPECT_THAT(absent, HasSubstr("obstacles.csv (the whole file: an older recording; replay "
                                "shows no obstacle cloud)"));
  EXPECT_THAT(absent, HasSubstr("markers.csv"));
  EXPECT_TRUE(r.states[20].obstacle_points_B_m.empty());
  EXPECT_STREQ(r.states[20].flight_state, "airborne");  // the rest is read as before
  fs::remove_all(dir);
}

TEST(ReplayParity, AnObstacleRowWithoutItsStateIsNamed) {
  const fs::path dir = testing::fresh_dir("hq_replay_parity", "orphan");
  write_csv(dir, make_flight());
  {
    std::FILE* f = std::fopen((dir / "obstacles.csv").c_str(), "a");
    ASSERT_NE(f, nullptr);
    fmt::print(f, "{},999,1.0,2.0,3.0\n", static_cast<long long>(receipt_ns(3)));
    std::fclose(f);
  }
  const Recording r = load_recording(dir.string());
  ASSERT_EQ(r.problems.size(), 1U);
  EXPECT_THAT(r.problems[0], HasSubstr("obstacles.csv:"));
  EXPECT_THAT(r.problems[0], HasSubstr("no state in telemetry.csv"));
  EXPECT_EQ(r.states[25].obstacle_points_B_m.size(), 12U);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hq::console
