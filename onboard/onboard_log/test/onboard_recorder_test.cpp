// The on-board recorder in-process: chain outputs and IMU samples pushed as the runtime does,
// read back with hq::mcap::McapReader (channels, counts, values, stamps); the frame path
// allocates nothing; the folder errors; a write failure told once through the port.
#include "hq/onboard_log/onboard_recorder.hpp"

#include "hq/link/link.hpp"
#include "hq/mcap/mcap.hpp"
#include "hq/ros2_bridge/ros2_cdr.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"
#include "hq/testing/loopback_dds.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <sys/resource.h>
#include <thread>
#include <unistd.h>

namespace hq::onboard_log {
namespace {

namespace fs = std::filesystem;

class OnboardRecorderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    hq::testing::use_loopback_dds();
    options_.link.domain_id = hq::testing::private_domain_id(57);
    options_.link.security.enabled = false;
    dir_ = fs::temp_directory_path() /
           ("hq_onboard_log_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    options_.dir = (dir_ / "flight").string();  // created by the recorder
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  OnboardRecorderOptions options_;
  fs::path dir_;
};

pipeline::ChainOutput output(std::int64_t t_ns, bool frame) {
  pipeline::ChainOutput out;
  out.t_ns = t_ns;
  out.frame = frame;
  out.tracking = odometry::TrackingStatus::kOk;
  out.valid_ratio = 0.75;
  out.estimate.status = estimator::EstimateStatus::kOk;
  out.estimate.v_H_mps = Eigen::Vector3d(0.5, -0.25, 0.125);
  out.estimate.v_B_mps = Eigen::Vector3d(0.5, 0.0, 0.0);
  out.estimate.roll_rad = 0.0625;
  out.mode.mode = modes::Mode::kTeleop;
  out.mode.control.setpoint.thrust_n = 12.5;
  out.mode.control.setpoint.pitch_rad = -0.03125;
  out.durations.odometry_ns = 4'000'000;
  out.durations.total_ns = 6'000'000;
  return out;
}

std::map<std::string, std::vector<const mcap::Message*>> by_topic(const mcap::McapReader& r) {
  std::map<std::string, std::vector<const mcap::Message*>> m;
  for (const mcap::Message& msg : r.messages()) m[r.channel(msg.channel_id)->topic].push_back(&msg);
  return m;
}

std::string text(const mcap::Message& m) { return {m.data.begin(), m.data.end()}; }

TEST_F(OnboardRecorderTest, StepsAndImuAreWrittenAsTheirChannelsWithTheLinkOnes) {
  std::ofstream(dir_.string() + ".vehicle.yaml") << "mass_kg: 1.2\n";
  options_.attachments = {{dir_.string() + ".vehicle.yaml", ""}, {"/no/such/camera.yaml", ""}};
  OnboardRecorder recorder(options_);
  vehicle::VehicleStatus status;
  status.streaming = true;
  constexpr int kSteps = 300;
  for (int i = 0; i < kSteps; ++i) {
    const std::int64_t t_ns = 1'000'000'000 + std::int64_t{i} * 5'000'000;
    for (int k = 0; k < 5; ++k) {
      vehicle::FcImuSample imu;
      imu.t_ns = t_ns + k * 1'000'000;
      imu.omega_B_radps = Eigen::Vector3d(0.01 * k, 0, 0);
      imu.f_B_mps2 = Eigen::Vector3d(0, 0, -9.81);
      recorder.push_imu(imu);
    }
    recorder.push_step(output(t_ns, i % 6 == 0), status);
  }
  EXPECT_EQ(recorder.steps_pushed(), static_cast<std::uint64_t>(kSteps));
  const flight_log::RecorderReport& report = recorder.close({{"frames", "50"}});
  fs::remove(dir_.string() + ".vehicle.yaml");
  EXPECT_TRUE(report.error.empty()) << report.error;
  EXPECT_EQ(report.local_samples_dropped, 0u);
  EXPECT_EQ(report.attachments, 1u);
  EXPECT_EQ(report.path, (fs::path(options_.dir) / "onboard.mcap").string());

  const mcap::McapReader r(report.path);
  std::vector<std::string> topics;
  for (const mcap::Channel& c : r.channels()) topics.push_back(c.topic);
  for (const char* t :
       {"/hq/vehicle_state", "/hq/velocity_command", "/hq/mode_request", "/onboard/imu",
        "/onboard/odometry", "/onboard/estimator", "/onboard/control", "/onboard/timing"}) {
    EXPECT_NE(std::find(topics.begin(), topics.end(), t), topics.end()) << t;
  }
  const auto m = by_topic(r);
  EXPECT_EQ(m.at("/onboard/imu").size(), 5u * kSteps);
  EXPECT_EQ(m.at("/onboard/estimator").size(), static_cast<std::size_t>(kSteps));
  EXPECT_EQ(m.at("/onboard/control").size(), static_cast<std::size_t>(kSteps));
  EXPECT_EQ(m.at("/onboard/odometry").size(), static_cast<std::size_t>(kSteps / 6));
  EXPECT_EQ(m.at("/onboard/timing").size(), static_cast<std::size_t>(kSteps / 6));
  for (const auto& [topic, messages] : m) {
    for (std::size_t i = 1; i < messages.size(); ++i) {
      ASSERT_LT(messages[i - 1]->log_time_ns, messages[i]->log_time_ns) << topic;
    }
  }
  // One time base: the chain's clock mapped to the epoch by one offset, the file in log-time
  // order, the chain's own stamp kept in the payload.
  for (std::size_t i = 1; i < r.messages().size(); ++i) {
    ASSERT_LE(r.messages()[i - 1].log_time_ns, r.messages()[i].log_time_ns) << i;
  }
  const mcap::Metadata* recorder_meta = nullptr;
  for (const mcap::Metadata& md : r.metadata()) {
    if (md.name == "recorder") recorder_meta = &md;
  }
  ASSERT_NE(recorder_meta, nullptr);
  const std::int64_t offset_ns = std::stoll(recorder_meta->values.at("chain_to_epoch_offset_ns"));
  EXPECT_GT(offset_ns, 1'600'000'000'000'000'000);  // the epoch, not the chain's clock
  EXPECT_EQ(m.at("/onboard/estimator").front()->log_time_ns, 1'000'000'000 + offset_ns);
  EXPECT_EQ(m.at("/onboard/imu").back()->log_time_ns,
            std::int64_t{1'000'000'000} + (kSteps - 1) * 5'000'000 + 4'000'000 + offset_ns);
  const std::string estimator = text(*m.at("/onboard/estimator").front());
  EXPECT_NE(estimator.find("\"t_ns\":1000000000,"), std::string::npos) << estimator;
  EXPECT_NE(estimator.find("\"v_H_mps\":{\"x\":0.5,\"y\":-0.25,\"z\":0.125}"), std::string::npos)
      << estimator;
  EXPECT_NE(estimator.find("\"roll_rad\":0.0625"), std::string::npos) << estimator;
  const std::string control = text(*m.at("/onboard/control").front());
  EXPECT_NE(control.find("\"mode\":\"teleop\""), std::string::npos) << control;
  EXPECT_NE(control.find("\"thrust_n\":12.5"), std::string::npos) << control;
  EXPECT_NE(control.find("\"pitch_rad\":-0.03125"), std::string::npos) << control;
  EXPECT_NE(control.find("\"sent_to_fc\":true"), std::string::npos) << control;
  const std::string timing = text(*m.at("/onboard/timing").front());
  EXPECT_NE(timing.find("\"odometry_ns\":4000000"), std::string::npos) << timing;
  EXPECT_NE(timing.find("\"total_ns\":6000000"), std::string::npos) << timing;
  ASSERT_EQ(r.attachments().size(), 1u);
  EXPECT_EQ(std::string(r.attachments()[0].data.begin(), r.attachments()[0].data.end()),
            "mass_kg: 1.2\n");
}

TEST_F(OnboardRecorderTest, PushingAllocatesNothingAndAFullQueueDropsAndCounts) {
  options_.step_queue_capacity = 16;
  OnboardRecorder recorder(options_);
  const pipeline::ChainOutput out = output(1'000'000'000, true);
  const vehicle::VehicleStatus status;
  const vehicle::FcImuSample imu;
  // The log's thread grows its buffers on its first messages (its own thread, not the frame
  // path's; but the counter counts every thread): let it, then count.
  constexpr std::size_t kWarm = 10;
  for (std::size_t i = 0; i < kWarm; ++i) {
    recorder.push_step(out, status);
    recorder.push_imu(imu);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const long before = testing::allocation_count();
  for (int i = 0; i < 2000; ++i) {
    recorder.push_step(out, status);
    recorder.push_imu(imu);
  }
  EXPECT_EQ(testing::allocation_count() - before, 0);
  const flight_log::RecorderReport& report = recorder.close();
  EXPECT_GT(report.local_samples_dropped, 0u);  // 2000 steps outrun a 16-slot queue
  const mcap::McapReader r(report.path);
  const auto m = by_topic(r);
  // Every step and sample pushed is either written or counted as dropped.
  EXPECT_EQ(
      m.at("/onboard/control").size() + m.at("/onboard/imu").size() + report.local_samples_dropped,
      2 * (2000u + kWarm));
}

TEST_F(OnboardRecorderTest, AFolderThatCannotBeMadeIsNamedAtStartUp) {
  fs::create_directories(dir_);
  std::ofstream(dir_ / "a_file") << "x";
  options_.dir = (dir_ / "a_file" / "flight").string();
  const std::string message =
      hq::testing::input_error_message([&] { OnboardRecorder recorder(options_); });
  EXPECT_NE(message.find(options_.dir), std::string::npos) << message;
}

TEST_F(OnboardRecorderTest, AnEarlierFlightIsNeverOverwritten) {
  fs::create_directories(options_.dir);
  std::ofstream(fs::path(options_.dir) / "onboard.mcap") << "an earlier flight";
  const std::string message =
      hq::testing::input_error_message([&] { OnboardRecorder recorder(options_); });
  EXPECT_NE(message.find("onboard.mcap: exists"), std::string::npos) << message;
}

// The ROS 2 bag beside onboard.mcap: states and frames the vehicle publishes on the link become
// the bridge's messages (built by its own Ros2Messages, compared byte for byte), named and typed
// as ROS 2 names them, with the ros2 profile and the QoS rosbag2 reads.
TEST_F(OnboardRecorderTest, LinkStatesAndFramesBecomeTheBridgesMessagesInRos2Mcap) {
  Eigen::Isometry3d T_B_C = Eigen::Isometry3d::Identity();
  T_B_C.translation() = Eigen::Vector3d(0.1, 0.0, 0.05);
  options_.camera_mount = geometry::CameraMount(T_B_C);
  options_.link.vehicle_id = 7;
  OnboardRecorder recorder(options_);
  geometry::PinholeCamera camera;
  camera.width = 320;
  camera.height = 240;
  camera.fx = camera.fy = 300.0;
  camera.cx = 160.0;
  camera.cy = 120.0;
  recorder.set_camera(camera);
  recorder.set_ros_clock(ros2_bridge::RosClock::simulated_time());

  const link::Participant vehicle(options_.link.domain_id);
  const link::Topics topics(vehicle);
  link::Writer<link::VehicleState> states(vehicle, topics.vehicle_state, link::vehicle_state_qos());
  link::Writer<link::CameraFrame> frames(vehicle, topics.camera, link::camera_qos());
  for (int i = 0; i < 300 && (states.matched_readers() == 0 || frames.matched_readers() == 0);
       ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ASSERT_GT(states.matched_readers(), 0u);
  // The bridge's builder, fed the same samples: what --ros2 would have published.
  ros2_bridge::Ros2Messages bridge("hq7");
  bridge.set_clock(ros2_bridge::RosClock::simulated_time());
  bridge.set_camera(camera);
  bridge.set_camera_mount(*options_.camera_mount);
  ros2_bridge::CdrWriter cdr(1 << 20);
  std::vector<std::vector<std::uint8_t>> odoms;
  constexpr int kStates = 20;
  link::Sample<link::VehicleState> state;
  link::reserve(state->obstacle_points_B_m, 2);
  for (int i = 0; i < kStates; ++i) {
    state->vehicle_id = 7;
    state->t_ns = 5'000'000'000 + std::int64_t{i} * 33'000'000;
    state->v_H_mps = {0.1f * static_cast<float>(i), -0.2f, 0.05f};
    state->roll_rad = 0.01f * static_cast<float>(i);
    state->obstacle_points_B_m._length = i % 2 == 0 ? 2 : 0;  // a cloud every other state
    state->obstacle_points_B_m._buffer[0] = {1.0f, 2.0f, -0.5f};
    state->obstacle_points_B_m._buffer[1] = {1.5f, -1.0f, 0.25f};
    ASSERT_TRUE(states.write(*state));
    ASSERT_TRUE(ros2_bridge::serialize(*bridge.build_state(*state).odom, cdr));
    odoms.emplace_back(cdr.data().begin(), cdr.data().end());
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  link::Sample<link::CameraFrame> frame;
  frame->vehicle_id = 7;
  frame->t_ns = 5'100'000'000;
  link::reserve(frame->rgb_jpeg, 4);
  frame->rgb_jpeg._length = 4;
  const std::uint8_t jpeg[4] = {0xff, 0xd8, 0xff, 0xd9};
  std::copy(jpeg, jpeg + 4, frame->rgb_jpeg._buffer);
  ASSERT_TRUE(frames.write(*frame));
  ASSERT_TRUE(states.wait_for_acks(2'000'000'000));
  ASSERT_TRUE(frames.wait_for_acks(2'000'000'000));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // the log's thread takes them
  EXPECT_TRUE(recorder.close().error.empty());
  const Ros2RecordReport& report = recorder.ros2_report();
  EXPECT_TRUE(report.error.empty()) << report.error;
  ASSERT_EQ(report.path, (fs::path(options_.dir) / "ros2.mcap").string());

  const mcap::McapReader r(report.path);
  EXPECT_EQ(r.profile(), "ros2");
  const std::map<std::string, std::string> expected = {
      {"/clock", "rosgraph_msgs/msg/Clock"},
      {"/tf_static", "tf2_msgs/msg/TFMessage"},
      {"/tf", "tf2_msgs/msg/TFMessage"},
      {"/hq7/odom", "nav_msgs/msg/Odometry"},
      {"/hq7/imu", "sensor_msgs/msg/Imu"},
      {"/hq7/obstacles", "sensor_msgs/msg/PointCloud2"},
      {"/hq7/camera/image/compressed", "sensor_msgs/msg/CompressedImage"},
      {"/hq7/camera/camera_info", "sensor_msgs/msg/CameraInfo"}};
  std::map<std::string, std::string> found;
  for (const mcap::Channel& c : r.channels()) {
    const mcap::Schema* schema = r.schema(c.schema_id);
    ASSERT_NE(schema, nullptr) << c.topic;
    found[c.topic] = schema->name;
    EXPECT_EQ(c.message_encoding, "cdr") << c.topic;
    EXPECT_EQ(schema->encoding, "ros2msg") << c.topic;
    const std::string qos = c.metadata.count("offered_qos_profiles") != 0
                                ? c.metadata.at("offered_qos_profiles")
                                : std::string();
    EXPECT_NE(qos.find("reliability: 1"), std::string::npos) << c.topic << ": " << qos;
    EXPECT_EQ(qos.find("durability: 1") != std::string::npos, c.topic == "/tf_static") << qos;
  }
  EXPECT_EQ(found, expected);
  const auto m = by_topic(r);
  ASSERT_EQ(m.at("/hq7/odom").size(), static_cast<std::size_t>(kStates));
  for (int i = 0; i < kStates; ++i) {
    EXPECT_EQ(m.at("/hq7/odom")[static_cast<std::size_t>(i)]->data,
              odoms[static_cast<std::size_t>(i)])
        << "odom " << i << " is not what the bridge builds";
  }
  EXPECT_EQ(m.at("/clock").size(), static_cast<std::size_t>(kStates));
  EXPECT_EQ(m.at("/tf_static").size(), 1u);
  EXPECT_EQ(m.at("/hq7/obstacles").size(), static_cast<std::size_t>(kStates / 2));
  EXPECT_EQ(m.at("/hq7/camera/image/compressed").size(), 1u);
  EXPECT_EQ(m.at("/hq7/camera/camera_info").size(), 1u);
  const std::vector<std::uint8_t>& image = m.at("/hq7/camera/image/compressed")[0]->data;
  EXPECT_TRUE(std::equal(jpeg, jpeg + 4, image.end() - 4));  // uint8[] data is the last field
  for (std::size_t i = 1; i < r.messages().size(); ++i) {
    ASSERT_LE(r.messages()[i - 1].log_time_ns, r.messages()[i].log_time_ns) << i;
  }
  EXPECT_EQ(report.messages, r.messages().size());
}

// Off in the link config: no bag. And like onboard.mcap, an earlier one is never overwritten.
TEST_F(OnboardRecorderTest, Ros2McapIsOffOnRequestAndNeverOverwritten) {
  options_.link.ros2.record = false;
  {
    OnboardRecorder recorder(options_);
    recorder.close();
    EXPECT_TRUE(recorder.ros2_report().path.empty());
  }
  EXPECT_TRUE(fs::exists(fs::path(options_.dir) / "onboard.mcap"));
  EXPECT_FALSE(fs::exists(fs::path(options_.dir) / "ros2.mcap"));
  fs::remove(fs::path(options_.dir) / "onboard.mcap");
  std::ofstream(fs::path(options_.dir) / "ros2.mcap") << "an earlier flight";
  options_.link.ros2.record = true;
  const std::string message =
      hq::testing::input_error_message([&] { OnboardRecorder recorder(options_); });
  EXPECT_NE(message.find("ros2.mcap: exists"), std::string::npos) << message;
}

class EventPort final : public vehicle::OperatorPort {
 public:
  modes::OperatorCommand poll(std::int64_t, std::vector<pipeline::ModeRequest>&) override {
    return {};
  }
  void on_output(const pipeline::ChainOutput&, const vehicle::VehicleStatus&) override {
    ++outputs;
  }
  void on_event(std::int64_t, vehicle::FcSeverity severity, std::string_view text) override {
    events.emplace_back(text);
    error = severity == vehicle::FcSeverity::kError;
  }
  int outputs = 0;
  bool error = false;
  std::vector<std::string> events;
};

TEST_F(OnboardRecorderTest, AWriteFailureIsToldOnceAsAnErrorEventAndTheStepsGoOn) {
  // A file size limit stands in for a full disk: write(2) fails with EFBIG mid-flight.
  std::signal(SIGXFSZ, SIG_IGN);
  rlimit saved{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
  rlimit limited = saved;
  limited.rlim_cur = 96 * 1024;  // the header (six copies of the IDL) is about 45 KB
  options_.writer.chunk_size_bytes = 4 * 1024;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &limited), 0);
  {
    OnboardRecorder recorder(options_);
    EventPort inner;
    RecordingPort port(&inner, recorder);
    const vehicle::VehicleStatus status;
    int steps = 0;
    for (; steps < 20'000 && !port.failure_told(); ++steps) {
      port.on_output(output(1'000'000'000 + std::int64_t{steps} * 1'000'000, true), status);
      if (steps % 100 == 99) std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    for (int i = 0; i < 10; ++i) port.on_output(output(2'000'000'000'000 + i, true), status);
    EXPECT_TRUE(recorder.failed());
    EXPECT_EQ(inner.outputs, steps + 10);  // every step still reached the link port
    ASSERT_EQ(inner.events.size(), 1u);
    EXPECT_TRUE(inner.error);
    EXPECT_NE(inner.events[0].find("on-board record stopped"), std::string::npos);
    EXPECT_NE(inner.events[0].find("onboard.mcap"), std::string::npos) << inner.events[0];
    EXPECT_NE(inner.events[0].find("File too large"), std::string::npos) << inner.events[0];
    EXPECT_EQ(recorder.close().error, recorder.error());
  }
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &saved), 0);
  std::signal(SIGXFSZ, SIG_DFL);
}

}  // namespace
}  // namespace hq::onboard_log
