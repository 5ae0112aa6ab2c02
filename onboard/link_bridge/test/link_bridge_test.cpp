// The bridge over a real DDS domain: a private domain per test process, loopback only.
#include "hq/link_bridge/link_bridge.hpp"

#include "hq/testing/input_error.hpp"
#include "hq/testing/loopback_dds.hpp"
#include "hq/testing/wire_enum.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace hq::link_bridge {
namespace {

using ::testing::HasSubstr;

link::LinkConfig private_link() {
  hq::testing::use_loopback_dds();
  link::LinkConfig config;
  config.domain_id = hq::testing::private_domain_id(0);
  config.security.enabled = false;  // the test's ground shares this process: plain DDS
  return config;
}

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// A ground station's writers and the vehicle's outputs, on the same domain.
struct Ground {
  explicit Ground(const link::LinkConfig& config)
      : participant(config.domain_id),
        command_topic(participant),
        mode_topic(participant),
        heartbeat_topic(participant),
        event_topic(participant),
        state_topic(participant),
        commands(participant, command_topic, link::command_qos(config, link::End::kWriter)),
        mode_requests(participant, mode_topic, link::mode_request_qos()),
        heartbeats(participant, heartbeat_topic, link::heartbeat_qos(config)),
        events(participant, event_topic, link::event_qos()),
        states(participant, state_topic, link::vehicle_state_qos()) {}
  link::Participant participant;
  link::Topic<link::VelocityCommand> command_topic;
  link::Topic<link::ModeRequest> mode_topic;
  link::Topic<link::Heartbeat> heartbeat_topic;
  link::Topic<link::Event> event_topic;
  link::Topic<link::VehicleState> state_topic;
  link::Writer<link::VelocityCommand> commands;
  link::Writer<link::ModeRequest> mode_requests;
  link::Writer<link::Heartbeat> heartbeats;
  link::Reader<link::Event> events;
  link::Reader<link::VehicleState> states;
};

// Polls the bridge as the control loop does (every 2 ms) until `done` or 5 s.
template <typename Done>
bool poll_until(LinkBridge& bridge, std::vector<pipeline::ModeRequest>& requests, Done done) {
  const std::int64_t end_ns = now_ns() + 5'000'000'000;
  while (now_ns() < end_ns) {
    bridge.poll(now_ns(), requests);
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return false;
}

// Publishes `out` (after a fresh command from the station, when given) until the ground takes
// a state that `wanted` accepts, into `state`; false after 5 s.
template <typename Wanted>
bool publish_until(LinkBridge& bridge, Ground& ground, const pipeline::ChainOutput& out,
                   link::VehicleState& state, Wanted wanted, const StateExtras& extras = {},
                   const link::VelocityCommand* fresh = nullptr) {
  std::vector<pipeline::ModeRequest> requests;
  return poll_until(bridge, requests, [&] {
    if (fresh != nullptr) ground.commands.write(*fresh);
    bridge.publish_state(out, extras);
    dds_sample_info_t info{};
    return ground.states.take(state, info) && wanted(state);
  });
}

TEST(LinkBridge, TakesGoodSamplesRejectsMalformedOnesAndReportsThem) {
  const link::LinkConfig config = private_link();
  LinkBridge bridge(config, FailsafeConfig{});
  Ground ground(config);
  std::vector<pipeline::ModeRequest> requests;

  // Commands are best-effort: keep writing until one is taken.
  link::VelocityCommand good{};
  good.vehicle_id = 1;
  good.station_id = 1;
  good.v_H_mps = {0.25F, 0.0F, 0.0F};
  ASSERT_TRUE(poll_until(bridge, requests, [&] {
    ground.commands.write(good);
    return bridge.failsafe().counters().commands_accepted > 0;
  }));
  EXPECT_FLOAT_EQ(static_cast<float>(bridge.failsafe().state().command.v_H_mps.x()), 0.25F);

  link::VelocityCommand bad = good;
  bad.v_H_mps.y = std::numeric_limits<float>::quiet_NaN();
  bad.sequence_number = std::numeric_limits<std::uint64_t>::max();
  ASSERT_TRUE(poll_until(bridge, requests, [&] {
    ground.commands.write(bad);
    return bridge.failsafe().counters().commands_rejected > 0;
  }));

  link::ModeRequest request{};
  request.vehicle_id = 1;
  request.station_id = 1;
  request.vehicle_session_id = bridge.session_id();
  request.requested_mode = hq::testing::wire_enum<hq_msgs_Mode>(99);
  ground.mode_requests.write(request);
  request.requested_mode = hq_msgs_MODE_HOVER;
  request.vehicle_session_id = bridge.session_id() + 1;  // made to a previous instance
  ground.mode_requests.write(request);
  request.station_id = 2;  // station 1 commands: not station 2's to ask
  request.vehicle_session_id = bridge.session_id();
  ground.mode_requests.write(request);
  request.station_id = 1;
  request.requested_mode = hq_msgs_MODE_TELEOP;
  ground.mode_requests.write(request);
  ASSERT_TRUE(poll_until(bridge, requests, [&] { return !requests.empty(); }));
  ASSERT_EQ(requests.size(), 1U);
  EXPECT_EQ(requests.front().mode, modes::Mode::kTeleop);
  EXPECT_NE(bridge.session_id(), 0U);
  EXPECT_EQ(bridge.failsafe().counters().mode_requests_rejected, 3U);
  EXPECT_EQ(bridge.failsafe().counters().mode_requests_wrong_session, 1U);
  EXPECT_EQ(bridge.failsafe().counters().mode_requests_not_commander, 1U);
  EXPECT_EQ(bridge.failsafe().counters().heartbeats_rejected, 0U);  // its own are not counted
  bridge.acknowledge(now_ns(), {modes::Mode::kTeleop, std::nullopt}, {true, ""});

  // Events are reliable and transient-local: the rejection and the acknowledgement arrive.
  std::vector<std::string> texts;
  ASSERT_TRUE(poll_until(bridge, requests, [&] {
    link::Event event{};
    dds_sample_info_t info{};
    while (ground.events.take(event, info)) {
      EXPECT_EQ(event.session_id, bridge.session_id());
      texts.emplace_back(event.text);
    }
    bool ack = false;
    bool rejected_mode = false;
    bool rejected_command = false;
    bool rejected_session = false;
    bool rejected_station = false;
    for (const std::string& t : texts) {
      ack = ack || t.find("mode teleop accepted") != std::string::npos;
      rejected_mode = rejected_mode || t.find("Mode enum") != std::string::npos;
      rejected_command = rejected_command || t.find("NaN or Inf") != std::string::npos;
      rejected_session = rejected_session || t.find("another vehicle session") != std::string::npos;
      rejected_station = rejected_station || t.find("station 2 (session") != std::string::npos;
    }
    return ack && rejected_mode && rejected_command && rejected_session && rejected_station;
  })) << ::testing::PrintToString(texts);
}

TEST(LinkBridge, PublishesStateAndRateLimitedCamera) {
  const link::LinkConfig config = private_link();
  BridgeOptions options;
  options.camera_rate_hz = 10.0;
  LinkBridge bridge(config, FailsafeConfig{}, options);
  Ground ground(config);
  const cv::Mat image(48, 64, CV_8UC3, cv::Scalar(40, 120, 200));
  // 1 s of 200 Hz control steps on a stamp clock: 10 frames, not 200.
  int sent = 0;
  for (int i = 0; i < 200; ++i) sent += bridge.publish_camera(i * 5'000'000LL, image) ? 1 : 0;
  EXPECT_EQ(sent, 10);

  pipeline::ChainOutput out;
  out.t_ns = 123;
  out.estimate.v_H_mps = {0.5, -0.25, 0.125};
  out.mode.mode = modes::Mode::kLand;
  link::VehicleState state{};
  ASSERT_TRUE(publish_until(bridge, ground, out, state, [](const auto&) { return true; }));
  EXPECT_EQ(state.mode, hq_msgs_MODE_LAND);
  EXPECT_FLOAT_EQ(state.v_H_mps.y, -0.25F);
  EXPECT_EQ(state.link_health, hq_msgs_HEALTH_DEGRADED);  // no command yet: holding
  EXPECT_TRUE(link::validate(state).ok);
  // Who it is and who commands it: its session, nobody yet, no input.
  EXPECT_EQ(state.session_id, bridge.session_id());
  EXPECT_NE(state.session_id, 0U);
  EXPECT_EQ(state.commanding_station_id, 0U);
  EXPECT_EQ(state.operator_input, hq_msgs_INPUT_NONE);
  // Flight state, motors, height and clearance ride along; an unknown height goes out as
  // HEIGHT_NONE and 0, never NaN.
  EXPECT_EQ(state.flight_state, hq_msgs_FLIGHT_LANDED);
  EXPECT_FALSE(state.motors_armed);
  EXPECT_EQ(state.height_source, hq_msgs_HEIGHT_NONE);
  EXPECT_EQ(state.height_m, 0.0F);
  EXPECT_EQ(state.clearance_m, -1.0F);
  out.flight_state = modes::FlightState::kAirborne;
  out.height_m = 1.02;
  out.height_source = pipeline::HeightSource::kDepth;
  out.clearance_m = 0.6;
  StateExtras extras;
  extras.motors_armed = true;
  ASSERT_TRUE(publish_until(
      bridge, ground, out, state,
      [](const link::VehicleState& s) { return s.flight_state == hq_msgs_FLIGHT_AIRBORNE; },
      extras));
  EXPECT_TRUE(state.motors_armed);
  EXPECT_EQ(state.height_source, hq_msgs_HEIGHT_DEPTH);
  EXPECT_FLOAT_EQ(state.height_m, 1.02F);
  EXPECT_FLOAT_EQ(state.clearance_m, 0.6F);
  EXPECT_TRUE(link::validate(state).ok);
}

// A teleop command cut by the seen-space limit goes out as flown, and says so.
TEST(LinkBridge, PublishesTheCommandAsFlownAndWhetherTheSeenSpaceCutIt) {
  const link::LinkConfig config = private_link();
  LinkBridge bridge(config, FailsafeConfig{});
  Ground ground(config);
  pipeline::ChainOutput out;
  out.mode.mode = modes::Mode::kTeleop;
  out.v_cmd_flown_H_mps = {0.4, 0.0, -0.1};
  out.command_limited = true;
  // A fresh command from the station: the fail-safe flies it, the limit cuts it.
  link::VelocityCommand fresh{};
  fresh.vehicle_id = 1;
  fresh.station_id = 1;
  link::VehicleState state{};
  ASSERT_TRUE(publish_until(
      bridge, ground, out, state,
      [](const link::VehicleState& s) { return s.operator_input == hq_msgs_INPUT_LIMITED_UNSEEN; },
      {}, &fresh));
  EXPECT_FLOAT_EQ(state.v_cmd_flown_H_mps.x, 0.4F);
  EXPECT_FLOAT_EQ(state.v_cmd_flown_H_mps.z, -0.1F);
  EXPECT_EQ(state.operator_input, hq_msgs_INPUT_LIMITED_UNSEEN);
  EXPECT_TRUE(link::validate(state).ok);
  out.command_limited = false;
  ASSERT_TRUE(publish_until(
      bridge, ground, out, state,
      [](const link::VehicleState& s) { return s.operator_input == hq_msgs_INPUT_FLOWN; }, {},
      &fresh));
  EXPECT_NE(state.operator_input, hq_msgs_INPUT_LIMITED_UNSEEN);
}

// A climb cut by the flight envelope's ceiling says so, apart from the seen space's cut.
TEST(LinkBridge, SaysWhenTheFlightEnvelopeCutTheClimb) {
  const link::LinkConfig config = private_link();
  LinkBridge bridge(config, FailsafeConfig{});
  Ground ground(config);
  pipeline::ChainOutput out;
  out.mode.mode = modes::Mode::kTeleop;
  out.v_cmd_flown_H_mps = {0.0, 0.0, -0.05};
  out.command_limited = true;
  out.command_envelope_limited = true;
  link::VelocityCommand fresh{};
  fresh.vehicle_id = 1;
  fresh.station_id = 1;
  link::VehicleState state{};
  ASSERT_TRUE(publish_until(
      bridge, ground, out, state,
      [](const link::VehicleState& s) {
        return s.operator_input == hq_msgs_INPUT_LIMITED_ENVELOPE;
      },
      {}, &fresh));
  EXPECT_FLOAT_EQ(state.v_cmd_flown_H_mps.z, -0.05F);
  EXPECT_TRUE(link::validate(state).ok);
}

// The hover thrust the chain learnt reaches the station, so the operator sees a vehicle whose
// file or FC maximum thrust is off.
TEST(LinkBridge, CarriesTheLearntHoverThrust) {
  const link::LinkConfig config = private_link();
  LinkBridge bridge(config, FailsafeConfig{});
  Ground ground(config);
  pipeline::ChainOutput out;
  out.hover_thrust.gain = 1.43;
  out.hover_thrust.converged = true;
  link::VehicleState state{};
  ASSERT_TRUE(publish_until(bridge, ground, out, state,
                            [](const link::VehicleState& s) { return s.hover_thrust_converged; }));
  EXPECT_FLOAT_EQ(state.hover_thrust_gain, 1.43F);
  EXPECT_TRUE(link::validate(state).ok);
}

// The chain's odom pose and the velocity's sigma reach the state as computed; a non-finite
// pose goes out as absent (odom_valid false, zeros), never as garbage.
TEST(LinkBridge, CarriesTheOdomPoseAndTheVelocitySigma) {
  const link::LinkConfig config = private_link();
  LinkBridge bridge(config, FailsafeConfig{});
  Ground ground(config);
  pipeline::ChainOutput out;
  out.odom.valid = true;
  out.odom.p_odom_m = {1.5, -0.5, -1.0};
  out.odom.yaw_rad = 0.75;
  out.odom.position_sigma_m = 0.2;
  out.odom.yaw_sigma_rad = 0.03;
  out.estimate.v_H_covariance = Eigen::Vector3d(0.0004, 0.0009, 0.0016).asDiagonal();
  link::VehicleState state{};
  ASSERT_TRUE(publish_until(bridge, ground, out, state,
                            [](const link::VehicleState& s) { return s.odom_valid; }));
  EXPECT_FLOAT_EQ(state.p_odom_m.x, 1.5F);
  EXPECT_FLOAT_EQ(state.p_odom_m.z, -1.0F);
  EXPECT_FLOAT_EQ(state.yaw_odom_rad, 0.75F);
  EXPECT_FLOAT_EQ(state.odom_position_sigma_m, 0.2F);
  EXPECT_FLOAT_EQ(state.odom_yaw_sigma_rad, 0.03F);
  EXPECT_TRUE(state.odom_yaw_relative_to_start);
  EXPECT_FLOAT_EQ(state.v_H_sigma_mps.x, 0.02F);
  EXPECT_FLOAT_EQ(state.v_H_sigma_mps.z, 0.04F);
  EXPECT_TRUE(link::validate(state).ok);
  out.odom.p_odom_m.x() = std::nan("");
  ASSERT_TRUE(publish_until(bridge, ground, out, state,
                            [](const link::VehicleState& s) { return !s.odom_valid; }));
  EXPECT_FLOAT_EQ(state.p_odom_m.x, 0.0F);
  EXPECT_TRUE(link::validate(state).ok);
}

// GIVEN two bridges (a vehicle and its restart) THEN their sessions differ and the state of each
// carries the station whose commands it flies.
TEST(LinkBridge, EachInstanceHasItsOwnSessionAndReportsItsCommander) {
  link::LinkConfig config = private_link();
  LinkBridge first(config, FailsafeConfig{});
  EXPECT_NE(first.session_id(), LinkBridge(config, FailsafeConfig{}).session_id());
  Ground ground(config);
  link::VelocityCommand c{};
  c.vehicle_id = 1;
  c.station_id = 7;
  std::vector<pipeline::ModeRequest> requests;
  ASSERT_TRUE(poll_until(first, requests, [&] {
    ground.commands.write(c);
    return first.failsafe().state().commanding_station_id == 7U;
  }));
  pipeline::ChainOutput out;
  out.mode.mode = modes::Mode::kTeleop;
  link::VehicleState state{};
  ASSERT_TRUE(poll_until(first, requests, [&] {
    ground.commands.write(c);  // fresh: flown
    first.publish_state(out);
    dds_sample_info_t info{};
    return ground.states.take(state, info) && state.commanding_station_id == 7U;
  }));
  EXPECT_EQ(state.operator_input, hq_msgs_INPUT_FLOWN);
}

// GIVEN a station matched to the vehicle WHEN the run ends THEN say_goodbye returns only once
// the station acknowledged the goodbye: it is already in the station's reader, as an info event
// with its own code, the reason and the session, the last of the session.
TEST(LinkBridge, GoodbyeIsAcknowledgedBeforeItReturns) {
  link::LinkConfig config = private_link();
  Ground ground(config);
  LinkBridge bridge(config, FailsafeConfig{});
  pipeline::ChainOutput out;
  link::VehicleState state{};
  ASSERT_TRUE(publish_until(bridge, ground, out, state, [](const link::VehicleState&) {
    return true;
  }));  // discovered both ways
  EXPECT_TRUE(bridge.say_goodbye(now_ns(), "stopped by SIGTERM; landed"));
  link::Event event{};
  dds_sample_info_t info{};
  bool found = false;
  while (ground.events.take(event, info)) {
    if (!info.valid_data) continue;
    found = event.code == link::kEventCodeVehicleEnded;
  }
  ASSERT_TRUE(found) << "the goodbye was not in the station's reader when say_goodbye returned";
  EXPECT_EQ(event.code, static_cast<std::uint32_t>(EventCode::kVehicleEnded));
  EXPECT_EQ(event.severity, hq_msgs_SEVERITY_INFO);
  EXPECT_STREQ(event.text, "vehicle ended: stopped by SIGTERM; landed");
  EXPECT_EQ(event.session_id, bridge.session_id());
  EXPECT_EQ(bridge.events_sent(), event.sequence_number);
}

// GIVEN no station WHEN the vehicle says goodbye THEN it does not wait (nobody to acknowledge).
TEST(LinkBridge, GoodbyeWithNoStationReturnsAtOnce) {
  LinkBridge bridge(private_link(), FailsafeConfig{});
  const std::int64_t start_ns = now_ns();
  EXPECT_TRUE(bridge.say_goodbye(start_ns, "run length 1 s reached", 5'000'000'000));
  EXPECT_LT(now_ns() - start_ns, 1'000'000'000);
}

// The memory's cloud rides on the state at the cloud rate, bounded, in the body frame.
// The memory holds a wall 2 m along the camera's optical axis; whatever pose the body has in the
// memory's world, the published points must sit 2 m along that axis seen from the body.
/// An obstacle memory that has seen a wall 2 m along the optical axis of the core paper's camera
/// mount (45 deg right, 30 deg down, calib/vehicle_core_paper.yaml), from a camera pose T_O_C
/// rotated and moved so that O, C and B all differ.
struct RememberedWall {
  RememberedWall() : memory(config, camera_for_wall(), R_B_C_core_paper(), p_B_C_m) {
    T_O_C.linear() =
        Eigen::AngleAxisd(0.7, Eigen::Vector3d(0.2, -0.3, 1.0).normalized()).toRotationMatrix();
    T_O_C.translation() = Eigen::Vector3d(1.5, -2.0, 0.4);
    const cv::Mat wall(camera.height, camera.width, CV_32FC1, cv::Scalar(2.0F));
    for (int i = 0; i < 3; ++i) {
      (void)memory.update(i * 33'000'000LL, wall, T_O_C, Eigen::Matrix3d::Identity(), 1.35);
    }
  }
  static geometry::PinholeCamera camera_for_wall() {
    geometry::PinholeCamera c;
    c.width = 160;
    c.height = 120;
    c.fx = c.fy = 120.0;
    c.cx = 79.5;
    c.cy = 59.5;
    return c;
  }
  static Eigen::Matrix3d R_B_C_core_paper() {
    const Eigen::Matrix3d R_B_forward = (Eigen::AngleAxisd(M_PI / 4, Eigen::Vector3d::UnitZ()) *
                                         Eigen::AngleAxisd(-M_PI / 6, Eigen::Vector3d::UnitY()))
                                            .toRotationMatrix();
    Eigen::Matrix3d optical_to_forward;  // optical (x right, y down, z forward) -> FRD body
    optical_to_forward << 0, 0, 1, 1, 0, 0, 0, 1, 0;
    return R_B_forward * optical_to_forward;
  }
  /// The body's pose in the memory's world (the odometry origin O).
  [[nodiscard]] Eigen::Isometry3d T_O_B() const {
    Eigen::Isometry3d T_B_C = Eigen::Isometry3d::Identity();
    T_B_C.linear() = R_B_C;
    T_B_C.translation() = p_B_C_m;
    return T_O_C * T_B_C.inverse();
  }

  geometry::PinholeCamera camera = camera_for_wall();
  Eigen::Matrix3d R_B_C = R_B_C_core_paper();
  Eigen::Vector3d p_B_C_m{0.10, 0.05, 0.03};
  obstacle_memory::MemoryConfig config;
  obstacle_memory::ObstacleMemory memory;
  Eigen::Isometry3d T_O_C = Eigen::Isometry3d::Identity();
};

// The memory's cloud rides on the state at the cloud rate, bounded, in the body frame.
// The memory holds a wall 2 m along the camera's optical axis; whatever pose the body has in the
// memory's world, the published points must sit 2 m along that axis seen from the body.
TEST(LinkBridge, PublishesTheRememberedCloudInTheBodyFrameAtItsRate) {
  const link::LinkConfig config = private_link();
  BridgeOptions options;
  options.obstacle_cloud_rate_hz = 1.0;
  options.max_obstacle_points = 300;
  LinkBridge bridge(config, FailsafeConfig{}, options);
  Ground ground(config);
  const RememberedWall wall;
  ASSERT_GT(wall.memory.size(), options.max_obstacle_points);  // the bound limits the cloud

  StateExtras source;
  source.cloud = {&wall.memory, wall.T_O_B()};
  pipeline::ChainOutput out;
  // 2 s of 100 Hz states on a stamp clock: clouds at 0 s and 1 s only.
  for (int i = 0; i < 200; ++i) {
    out.t_ns = i * 10'000'000LL;
    bridge.publish_state(out, source);
    EXPECT_EQ(bridge.last_cloud_size() > 0, i % 100 == 0) << "state " << i;
  }
  EXPECT_EQ(bridge.clouds_sent(), 2U);
  EXPECT_EQ(bridge.states_sent(), 200U);

  link::Sample<link::VehicleState> state;
  std::vector<pipeline::ModeRequest> requests;
  ASSERT_TRUE(poll_until(bridge, requests, [&] {
    out.t_ns += 1'000'000'000;  // one cloud per call
    bridge.publish_state(out, source);
    dds_sample_info_t info{};
    while (ground.states.take(*state, info)) {
      if (state->obstacle_points_B_m._length > 0) return true;
    }
    return false;
  }));
  const auto& cloud = state->obstacle_points_B_m;
  EXPECT_LE(cloud._length, static_cast<std::uint32_t>(options.max_obstacle_points));
  EXPECT_GE(cloud._length, static_cast<std::uint32_t>(options.max_obstacle_points) / 2);
  EXPECT_TRUE(link::validate(*state).ok);
  for (std::uint32_t i = 0; i < cloud._length; ++i) {
    const Eigen::Vector3d p_B(cloud._buffer[i].x, cloud._buffer[i].y, cloud._buffer[i].z);
    ASSERT_TRUE(p_B.allFinite()) << i;
    // Back into the camera: on the wall, within the voxel leaf.
    const Eigen::Vector3d p_C = wall.R_B_C.transpose() * (p_B - wall.p_B_C_m);
    EXPECT_NEAR(p_C.z(), 2.0, wall.config.leaf_m) << i;
    EXPECT_LT(std::abs(p_C.x()), 2.0 * wall.camera.cx / wall.camera.fx + wall.config.leaf_m) << i;
  }

  // No memory, or a non-finite pose: an empty cloud, still a state.
  out.t_ns += 10'000'000'000LL;
  bridge.publish_state(out, {});
  EXPECT_EQ(bridge.last_cloud_size(), 0);
  source.cloud.T_O_B.translation().x() = std::numeric_limits<double>::quiet_NaN();
  bridge.publish_state(out, source);
  EXPECT_EQ(bridge.last_cloud_size(), 0);
}

TEST(LinkBridge, BadOptionsNameTheKey) {
  const link::LinkConfig config = private_link();
  BridgeOptions options;
  options.jpeg_quality = 0;
  EXPECT_THAT(hq::testing::input_error_message([&] { LinkBridge b(config, {}, options); }),
              HasSubstr("jpeg_quality = 0"));
  options = {};
  options.max_obstacle_points = 5000;
  EXPECT_THAT(hq::testing::input_error_message([&] { LinkBridge b(config, {}, options); }),
              HasSubstr("max_obstacle_points = 5000, expected in [1, 2048]"));
  options = {};
  options.obstacle_cloud_rate_hz = -1.0;
  EXPECT_THAT(hq::testing::input_error_message([&] { LinkBridge b(config, {}, options); }),
              HasSubstr("obstacle_cloud_rate_hz = -1"));
}

}  // namespace
}  // namespace hq::link_bridge

namespace hq::link_bridge {
namespace {

// Position, markers and truth go out as given and flagged; non-finite ones as absent.
TEST(LinkBridge, PublishesPositionMarkersAndTruthOnlyWhenGivenAndFinite) {
  const link::LinkConfig config = private_link();
  LinkBridge bridge(config, FailsafeConfig{}, BridgeOptions{});
  Ground ground(config);
  pipeline::ChainOutput out;
  out.t_ns = 5'000'000;
  std::array<markers::MarkerDetection, 1> detections{};
  detections[0].id = 7;
  detections[0].T_camera_marker.translation() = Eigen::Vector3d(0.1, -0.2, 1.5);
  detections[0].T_camera_marker.linear() =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  StateExtras extras;
  extras.position_valid = true;
  extras.p_W_m = Eigen::Vector3d(1.0, 2.0, -1.0);
  extras.yaw_rad = 0.5;
  extras.markers = detections;
  extras.truth_valid = true;
  extras.v_truth_H_mps = Eigen::Vector3d(0.3, 0.0, -0.1);

  link::Sample<link::VehicleState> state;
  std::vector<pipeline::ModeRequest> requests;
  const auto publish_and_take = [&](const StateExtras& e) {
    bool got = false;
    EXPECT_TRUE(poll_until(bridge, requests, [&] {
      bridge.publish_state(out, e);
      dds_sample_info_t info{};
      while (ground.states.take(*state, info)) got = true;
      return got;
    }));
  };
  publish_and_take(extras);
  EXPECT_TRUE(state->position_valid);
  EXPECT_FLOAT_EQ(state->p_W_m.y, 2.0F);
  EXPECT_FLOAT_EQ(state->yaw_W_rad, 0.5F);
  ASSERT_EQ(state->markers._length, 1u);
  EXPECT_EQ(state->markers._buffer[0].id, 7);
  EXPECT_FLOAT_EQ(state->markers._buffer[0].p_camera_marker_m.z, 1.5F);
  EXPECT_NEAR(state->markers._buffer[0].q_camera_marker.z, std::sin(0.15), 1e-6);
  EXPECT_TRUE(state->truth_valid);
  EXPECT_FLOAT_EQ(state->v_truth_H_mps.z, -0.1F);
  EXPECT_TRUE(link::validate(*state).ok);

  // A non-finite position or truth is sent as absent, never as garbage.
  extras.p_W_m.x() = std::numeric_limits<double>::quiet_NaN();
  extras.v_truth_H_mps.y() = std::numeric_limits<double>::infinity();
  extras.markers = {};
  publish_and_take(extras);
  EXPECT_FALSE(state->position_valid);
  EXPECT_FALSE(state->truth_valid);
  EXPECT_EQ(state->markers._length, 0u);
  EXPECT_TRUE(link::validate(*state).ok);
}

// GIVEN an invalid marker pose THEN the state says why, how old and how uncertain it is, and
// sends no position; a valid one goes out with no reason.
TEST(LinkBridge, CarriesWhyThePositionIsInvalid) {
  const link::LinkConfig config = private_link();
  LinkBridge bridge(config, FailsafeConfig{});
  Ground ground(config);
  pipeline::ChainOutput out;
  StateExtras extras;
  extras.position_valid = false;
  extras.p_W_m = Eigen::Vector3d(-34.0, -122.0, -1.0);
  extras.position_invalid_reason = 2;  // no marker
  extras.position_age_s = 3.4;
  extras.position_sigma_m = 0.31;
  link::Sample<link::VehicleState> state;
  std::vector<pipeline::ModeRequest> requests;
  const auto publish_until_age = [&](float age_s) {
    return poll_until(bridge, requests, [&] {
      bridge.publish_state(out, extras);
      dds_sample_info_t info{};
      bool got = false;
      while (ground.states.take(*state, info)) got = state->position_age_s == age_s;
      return got;
    });
  };
  ASSERT_TRUE(publish_until_age(3.4F));
  EXPECT_FALSE(state->position_valid);
  EXPECT_EQ(state->position_invalid_reason, 2);
  EXPECT_FLOAT_EQ(state->position_sigma_m, 0.31F);
  EXPECT_EQ(state->p_W_m.x, 0.0F) << "an invalid position must not be sent";
  EXPECT_TRUE(link::validate(*state).ok);
  extras.position_valid = true;
  extras.position_invalid_reason = 0;
  extras.position_age_s = 0.1;
  ASSERT_TRUE(publish_until_age(0.1F));
  EXPECT_TRUE(state->position_valid);
  EXPECT_EQ(state->position_invalid_reason, 0);
  EXPECT_FLOAT_EQ(state->p_W_m.y, -122.0F);
  EXPECT_TRUE(link::validate(*state).ok);
}

}  // namespace
}  // namespace hq::link_bridge

namespace hq::link_bridge {
namespace {

const geometry::PinholeCamera kMarkerCamera{260.0, 260.0, 159.5, 119.5, 320, 240};

pipeline::OnboardConfig chain_config(bool markers_enabled) {
  pipeline::OnboardConfig config;
  config.markers.enabled = markers_enabled;
  return config;
}

// A forward-looking camera (eq. 9 needs a horizontal viewing direction).
VehicleConfig forward_camera_vehicle() {
  VehicleConfig vehicle;
  vehicle.camera = camera_mount_from_angles(0.0, 0.0, 0.0, Eigen::Vector3d::Zero());
  return vehicle;
}

link::ModeRequest marker_request(hq_msgs_MarkerTask task, std::int32_t target_id,
                                 std::uint64_t session = 0) {
  link::ModeRequest request{};
  request.vehicle_id = 1;
  request.station_id = 1;
  request.vehicle_session_id = session;
  request.requested_mode = hq_msgs_MODE_MARKER;
  request.marker_task = task;
  request.target_id = target_id;
  return request;
}

// GIVEN link requests with marker tasks, WHEN they become chain requests, THEN a malformed task
// or target is refused with its reason and NONE carries no task.
TEST(ToModeRequest, CarriesTheMarkerTaskOrRefusesAMalformedOne) {
  pipeline::ModeRequest out;
  Verdict v =
      to_mode_request(marker_request(hq_msgs_MARKER_TASK_LAND, 7), modes::Mode::kMarker, out);
  EXPECT_TRUE(v.accepted) << v.reason;
  EXPECT_EQ(out.mode, modes::Mode::kMarker);
  ASSERT_TRUE(out.marker.has_value());
  EXPECT_EQ(out.marker->task, marker_modes::MarkerTask::kLand);
  EXPECT_EQ(out.marker->marker_id, 7);
  EXPECT_TRUE(
      to_mode_request(marker_request(hq_msgs_MARKER_TASK_NONE, 0), modes::Mode::kMarker, out)
          .accepted);
  EXPECT_FALSE(out.marker.has_value());
  v = to_mode_request(marker_request(hq::testing::wire_enum<hq_msgs_MarkerTask>(9), 3),
                      modes::Mode::kMarker, out);
  EXPECT_FALSE(v.accepted);
  EXPECT_THAT(v.reason, HasSubstr("MarkerTask enum"));
  v = to_mode_request(marker_request(hq_msgs_MARKER_TASK_HOLD, -2), modes::Mode::kMarker, out);
  EXPECT_FALSE(v.accepted);
  EXPECT_THAT(v.reason, HasSubstr("negative"));
}

TEST(ToModeRequest, CarriesTheTakeOff) {
  link::ModeRequest request = marker_request(hq_msgs_MARKER_TASK_NONE, 0);
  pipeline::ModeRequest out;
  ASSERT_TRUE(to_mode_request(request, modes::Mode::kTeleop, out).accepted);
  EXPECT_FALSE(out.take_off);
  request.take_off = true;
  ASSERT_TRUE(to_mode_request(request, modes::Mode::kTeleop, out).accepted);
  EXPECT_TRUE(out.take_off);
  EXPECT_EQ(out.mode, modes::Mode::kTeleop);
}

// GIVEN a chain with its marker stage on, WHEN it is asked for a mode with a marker task, THEN
// the stage's marker mode takes task and target; without a stage it is refused with a reason.
TEST(ChainModeRequest, SetsTheStageTaskOrRefusesWithoutAStage) {
  pipeline::OnboardChain with_stage(chain_config(true), forward_camera_vehicle(), kMarkerCamera);
  ASSERT_NE(with_stage.markers(), nullptr);
  const pipeline::ModeRequest land{modes::Mode::kMarker,
                                   pipeline::MarkerTarget{marker_modes::MarkerTask::kLand, 7}};
  modes::ModeSwitch result = with_stage.request_mode(land);
  EXPECT_TRUE(result.accepted) << result.reason;
  EXPECT_EQ(with_stage.markers()->marker_mode().task(), marker_modes::MarkerTask::kLand);
  EXPECT_EQ(with_stage.markers()->marker_mode().marker_id(), 7);
  EXPECT_EQ(with_stage.mode(), modes::Mode::kMarker);

  pipeline::OnboardChain without_stage(chain_config(false), forward_camera_vehicle(),
                                       kMarkerCamera);
  result = without_stage.request_mode(land);
  EXPECT_FALSE(result.accepted);
  EXPECT_THAT(result.reason, HasSubstr("marker stage is off"));
  EXPECT_NE(without_stage.mode(), modes::Mode::kMarker);
}

// Over DDS: a marker request reaches the vehicle as a chain request with its task; the chain's
// answer goes back as an event naming the task: refused when the stage is off, accepted with it.
TEST(LinkBridge, PassesMarkerRequestsOnAndAcknowledgesTheChainsAnswer) {
  const link::LinkConfig config = private_link();
  LinkBridge bridge(config, FailsafeConfig{});
  Ground ground(config);
  std::vector<pipeline::ModeRequest> requests;
  std::vector<std::string> texts;
  const auto event_seen = [&](const char* needle) {
    link::Event event{};
    dds_sample_info_t info{};
    while (ground.events.take(event, info)) texts.emplace_back(event.text);
    for (const std::string& t : texts) {
      if (t.find(needle) != std::string::npos) return true;
    }
    return false;
  };
  pipeline::OnboardChain without_stage(chain_config(false), forward_camera_vehicle(),
                                       kMarkerCamera);
  ground.mode_requests.write(marker_request(hq_msgs_MARKER_TASK_LAND, 4, bridge.session_id()));
  ASSERT_TRUE(poll_until(bridge, requests, [&] { return !requests.empty(); }));
  ASSERT_TRUE(requests.front().marker.has_value());
  EXPECT_EQ(requests.front().marker->marker_id, 4);
  bridge.acknowledge(now_ns(), requests.front(), without_stage.request_mode(requests.front()));
  ASSERT_TRUE(poll_until(bridge, requests, [&] { return event_seen("marker stage is off"); }))
      << ::testing::PrintToString(texts);
  EXPECT_THAT(texts.back(), HasSubstr("marker task land on marker 4 refused"));

  requests.clear();
  pipeline::OnboardChain with_stage(chain_config(true), forward_camera_vehicle(), kMarkerCamera);
  ground.mode_requests.write(marker_request(hq_msgs_MARKER_TASK_LAND, 4, bridge.session_id()));
  ASSERT_TRUE(poll_until(bridge, requests, [&] { return !requests.empty(); }));
  EXPECT_EQ(requests.front().mode, modes::Mode::kMarker);
  bridge.acknowledge(now_ns(), requests.front(), with_stage.request_mode(requests.front()));
  EXPECT_EQ(with_stage.markers()->marker_mode().task(), marker_modes::MarkerTask::kLand);
  EXPECT_EQ(with_stage.markers()->marker_mode().marker_id(), 4);
  ASSERT_TRUE(poll_until(bridge, requests, [&] { return event_seen("on marker 4"); }))
      << ::testing::PrintToString(texts);
  EXPECT_THAT(texts.back(), HasSubstr("accepted"));
}

}  // namespace
}  // namespace hq::link_bridge

namespace hq::link_bridge {
namespace {

// GIVEN ROS 2 on WHEN a ROS teleop node sends TwistStamped on cmd_vel_in THEN the vehicle
// follows it as station 250 (converted FLU -> H); a native station's commands take over and the
// ROS ones are dropped and counted; a NaN or out-of-envelope value from ROS is rejected like
// any station's; once the native station has been silent for its lease, the ROS commands fly
// again.
TEST(LinkBridge, Ros2CommandsAreTheWeakestStation) {
  link::LinkConfig config = private_link();
  config.ros2.enabled = true;
  LinkBridge bridge(config, FailsafeConfig{});
  ASSERT_NE(bridge.ros2(), nullptr);
  Ground ground(config);
  link::Topic<ros2_bridge::TwistStamped> twist_topic(ground.participant, "rt/hq1/cmd_vel_in");
  link::Writer<ros2_bridge::TwistStamped> twists(ground.participant, twist_topic,
                                                 ros2_bridge::ros2_qos());
  std::string frame = "base_link";
  ros2_bridge::TwistStamped twist{};
  twist.header.frame_id = frame.data();
  twist.twist.linear = {0.3, 0.1, 0.0};
  twist.twist.angular = {0.0, 0.0, 0.2};
  std::vector<pipeline::ModeRequest> requests;
  const FailsafeState& state = bridge.failsafe().state();

  ASSERT_TRUE(poll_until(bridge, requests, [&] {
    twists.write(twist);
    return state.commanding_station_id == 250 && !state.hold;
  }));
  EXPECT_FLOAT_EQ(static_cast<float>(state.command.v_H_mps.x()), 0.3F);
  EXPECT_FLOAT_EQ(static_cast<float>(state.command.v_H_mps.y()), -0.1F);
  EXPECT_FLOAT_EQ(static_cast<float>(state.command.yaw_rate_radps), -0.2F);

  link::VelocityCommand native{};
  native.vehicle_id = 1;
  native.station_id = 1;
  native.v_H_mps = {0.05F, 0.0F, 0.0F};
  ASSERT_TRUE(poll_until(bridge, requests, [&] {
    ground.commands.write(native);
    twists.write(twist);
    return state.commanding_station_id == 1 && bridge.ros2()->counters().commands_overridden > 2;
  }));
  EXPECT_FLOAT_EQ(static_cast<float>(state.command.v_H_mps.x()), 0.05F);

  // The native station stops; past its lease (500 ms) a NaN from ROS is rejected and counted.
  const std::int64_t quiet_until_ns = now_ns() + config.command_lease_ns + 100'000'000;
  while (now_ns() < quiet_until_ns) {
    bridge.poll(now_ns(), requests);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const std::uint64_t rejected = bridge.failsafe().counters().commands_rejected;
  ros2_bridge::TwistStamped bad = twist;
  bad.twist.linear.y = std::numeric_limits<double>::quiet_NaN();
  ASSERT_TRUE(poll_until(bridge, requests, [&] {
    twists.write(bad);
    return bridge.failsafe().counters().commands_rejected > rejected;
  }));
  // Beyond the envelope (2 m/s forward by default): rejected too, never clipped. (NaN samples
  // still queued may be rejected first: wait for the envelope's reason.)
  ros2_bridge::TwistStamped too_fast = twist;
  too_fast.twist.linear.x = 5.0;
  ASSERT_TRUE(poll_until(bridge, requests, [&] {
    twists.write(too_fast);
    return std::string(bridge.failsafe().last_command_rejection()) ==
           "v_H_mps.x outside envelope max_v_x_mps";
  })) << bridge.failsafe().last_command_rejection();
  EXPECT_EQ(state.commanding_station_id, 1U);  // a rejected command takes nothing over
  ASSERT_TRUE(poll_until(bridge, requests, [&] {
    twists.write(twist);
    return state.commanding_station_id == 250 && !state.hold;
  }));
}

// ROS 2 on: the vehicle state also goes out as odometry on rt/<ns>/odom.
TEST(LinkBridge, Ros2OdometryGoesOutWithTheState) {
  link::LinkConfig config = private_link();
  config.ros2.enabled = true;
  config.ros2.ros_namespace = "quad";
  LinkBridge bridge(config, FailsafeConfig{});
  bridge.ros2()->set_clock(ros2_bridge::RosClock::simulated_time());  // stamps = the chain's
  link::Participant ros(config.domain_id);
  link::Topic<ros2_bridge::Odometry> topic(ros, "rt/quad/odom");
  link::Reader<ros2_bridge::Odometry> odom(ros, topic, ros2_bridge::ros2_qos());
  link::Sample<ros2_bridge::Odometry> sample;
  pipeline::ChainOutput out;
  out.t_ns = 1'500'000'000;
  out.estimate.v_H_mps = {0.4, 0.0, 0.0};
  std::vector<pipeline::ModeRequest> requests;
  ASSERT_TRUE(poll_until(bridge, requests, [&] {
    bridge.publish_state(out);
    dds_sample_info_t info{};
    return odom.take(*sample, info);
  }));
  EXPECT_STREQ(sample->child_frame_id, "quad/base_link");
  EXPECT_NEAR(sample->twist.twist.linear.x, 0.4, 1e-6);
  EXPECT_EQ(sample->header.stamp.sec, 1);
  EXPECT_EQ(bridge.ros2()->counters().states_published, bridge.states_sent());
}

// GIVEN ROS 2 on WHEN a ROS node sends mode texts THEN they reach the chain through the same
// fail-safe as the ground's (as station 250 of this session, marked from_ros2), the chain's
// answer and every refusal (unknown text, unprintable bytes, a station that does not command)
// go back on mode_status and as events, and nothing unreadable is requested.
TEST(LinkBridge, Ros2ModeRequestsMeetTheGroundsGateAndAreAnswered) {
  link::LinkConfig config = private_link();
  config.ros2.enabled = true;
  LinkBridge bridge(config, FailsafeConfig{});
  Ground ground(config);
  link::Topic<ros2_bridge::RosString> request_topic(ground.participant, "rt/hq1/mode_request");
  link::Writer<ros2_bridge::RosString> ros_requests(ground.participant, request_topic,
                                                    ros2_bridge::ros2_qos());
  link::Topic<ros2_bridge::RosString> status_topic(ground.participant, "rt/hq1/mode_status");
  link::Reader<ros2_bridge::RosString> status(ground.participant, status_topic,
                                              ros2_bridge::ros2_qos());
  link::Sample<ros2_bridge::RosString> answer;
  std::vector<std::string> answers;
  const auto answered = [&](const char* needle) {
    dds_sample_info_t info{};
    while (status.take(*answer, info)) answers.emplace_back(answer->data);
    return !answers.empty() && answers.back().find(needle) != std::string::npos;
  };
  std::vector<pipeline::ModeRequest> requests;
  ASSERT_TRUE(poll_until(bridge, requests, [&] {
    return ros_requests.matched_readers() > 0 && status.matched_writers() > 0;
  }));
  const auto send = [&](std::string text) {
    ros2_bridge::RosString sample{};
    sample.data = text.data();
    ros_requests.write(sample);
  };

  send("fly_upside_down");
  ASSERT_TRUE(poll_until(bridge, requests, [&] { return answered("refused"); }));
  EXPECT_THAT(answers.back(), HasSubstr("\"fly_upside_down\" on /hq1/mode_request refused: "
                                        "unknown mode"));
  send("hover\x01\x7f");
  ASSERT_TRUE(poll_until(bridge, requests, [&] { return answered("\"hover??\""); }))
      << ::testing::PrintToString(answers);
  EXPECT_TRUE(requests.empty());

  send("take_off");
  ASSERT_TRUE(poll_until(bridge, requests, [&] { return !requests.empty(); }));
  EXPECT_EQ(requests.front().mode, modes::Mode::kTeleop);
  EXPECT_TRUE(requests.front().take_off);
  EXPECT_TRUE(requests.front().from_ros2);
  bridge.acknowledge(now_ns(), requests.front(), {true, ""});
  ASSERT_TRUE(poll_until(bridge, requests, [&] { return answered("mode teleop accepted"); }));
  requests.clear();
  send("marker go_to 5");
  ASSERT_TRUE(poll_until(bridge, requests, [&] { return !requests.empty(); }));
  ASSERT_TRUE(requests.front().marker.has_value());
  EXPECT_EQ(requests.front().marker->task, marker_modes::MarkerTask::kGoTo);
  EXPECT_EQ(requests.front().marker->marker_id, 5);
  bridge.acknowledge(now_ns(), requests.front(), {false, "marker stage is off"});
  ASSERT_TRUE(poll_until(bridge, requests, [&] { return answered("marker stage is off"); }));

  // A native station takes command: the ROS node's requests are refused by the same gate.
  link::VelocityCommand native{};
  native.vehicle_id = 1;
  native.station_id = 1;
  ASSERT_TRUE(poll_until(bridge, requests, [&] {
    ground.commands.write(native);
    return bridge.failsafe().state().commanding_station_id == 1;
  }));
  requests.clear();
  send("land");
  ASSERT_TRUE(poll_until(bridge, requests, [&] { return answered("does not command"); }));
  EXPECT_THAT(answers.back(), HasSubstr("\"land\" (station 250) refused"));
  EXPECT_TRUE(requests.empty());
  // Each refusal is also the vehicle's event, for the ground and the flight record.
  std::vector<std::string> events;
  link::Event event{};
  dds_sample_info_t info{};
  while (ground.events.take(event, info)) events.emplace_back(event.text);
  EXPECT_THAT(events, ::testing::Contains(HasSubstr("\"land\" (station 250) refused")));
}

TEST(LinkBridge, NoRos2TopicsUnlessAskedFor) {
  LinkBridge bridge(private_link(), FailsafeConfig{});
  EXPECT_EQ(bridge.ros2(), nullptr);
}

}  // namespace
}  // namespace hq::link_bridge
