// The flight recorder against real DDS writers on loopback (a domain of this test process's
// own): samples in, MCAP out, read back with hq::mcap::McapReader: counts, stamps, CDR bytes
// decoded here by hand (independently of Cyclone) and by the console's reader (replay,
// hq-report), the Foxglove channels, the ground queue,
// a file read while the recorder still runs (what a SIGKILL leaves), and write failures.
#include "hq/mcap_recorder/flight_recorder.hpp"

#include "hq/base/format_into.hpp"
#include "hq/console/recording.hpp"
#include "hq/link/link.hpp"
#include "hq/mcap/mcap.hpp"
#include "hq/testing/input_error.hpp"
#include "hq/testing/loopback_dds.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sys/resource.h>
#include <thread>
#include <unistd.h>

namespace hq::mcap_recorder {
namespace {

namespace fs = std::filesystem;

class FlightRecorderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    hq::testing::use_loopback_dds();
    options_.link.domain_id = hq::testing::private_domain_id(0);
    options_.link.security.enabled = false;  // the test's writers share this process: plain DDS
    dir_ = fs::temp_directory_path() /
           ("hq_mcap_recorder_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    options_.path = (dir_ / "flight.mcap").string();
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  FlightRecorderOptions options_;
  fs::path dir_;
};

// The link's writers, as hq-onboard and hq-ground create them.
struct Publishers {
  explicit Publishers(const link::LinkConfig& config)
      : participant(config.domain_id),
        topics(participant),
        state(participant, topics.vehicle_state, link::vehicle_state_qos()),
        camera(participant, topics.camera, link::camera_qos()),
        event(participant, topics.event, link::event_qos()),
        heartbeat(participant, topics.heartbeat, link::heartbeat_qos(config)),
        command(participant, topics.command, link::command_qos(config, link::End::kWriter)),
        mode(participant, topics.mode_request, link::mode_request_qos()) {}
  bool all_matched() const {
    return state.matched_readers() > 0 && camera.matched_readers() > 0 &&
           event.matched_readers() > 0 && heartbeat.matched_readers() > 0 &&
           command.matched_readers() > 0 && mode.matched_readers() > 0;
  }
  link::Participant participant;
  link::Topics topics;
  link::Writer<link::VehicleState> state;
  link::Writer<link::CameraFrame> camera;
  link::Writer<link::Event> event;
  link::Writer<link::Heartbeat> heartbeat;
  link::Writer<link::VelocityCommand> command;
  link::Writer<link::ModeRequest> mode;
};

bool wait_matched(const Publishers& p) {
  for (int i = 0; i < 300 && !p.all_matched(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return p.all_matched();
}

// Little-endian CDR (XCDR1 plain or XCDR2 plain, final types): alignment relative to the end
// of the 4-byte encapsulation header, at most 4 for XCDR2 and 8 for XCDR1.
class CdrIn {
 public:
  explicit CdrIn(const std::vector<std::uint8_t>& data) : data_(data) {
    EXPECT_GE(data.size(), 4u);
    EXPECT_EQ(data[0], 0x00);
    // 0x01: CDR_LE (XCDR1), 0x07: PLAIN_CDR2_LE.
    EXPECT_TRUE(data[1] == 0x01 || data[1] == 0x07) << "representation " << int{data[1]};
    max_align_ = data[1] == 0x07 ? 4 : 8;
  }
  template <typename T>
  T get() {
    const std::size_t align = std::min(sizeof(T), max_align_);
    at_ = (at_ + align - 1) / align * align;
    T v{};
    if (4 + at_ + sizeof(T) > data_.size()) {
      ADD_FAILURE() << "CDR too short";
      return v;
    }
    std::memcpy(&v, data_.data() + 4 + at_, sizeof(T));
    at_ += sizeof(T);
    return v;
  }

 private:
  const std::vector<std::uint8_t>& data_;
  std::size_t at_ = 0;
  std::size_t max_align_ = 8;
};

const mcap::Channel* channel_of(const mcap::McapReader& r, const std::string& topic) {
  for (const mcap::Channel& c : r.channels()) {
    if (c.topic == topic) return &c;
  }
  return nullptr;
}

std::vector<const mcap::Message*> messages_of(const mcap::McapReader& r, const std::string& topic) {
  std::vector<const mcap::Message*> out;
  const mcap::Channel* c = channel_of(r, topic);
  if (c == nullptr) return out;
  for (const mcap::Message& m : r.messages()) {
    if (m.channel_id == c->id) out.push_back(&m);
  }
  return out;
}

constexpr std::int64_t kSourceStampBase_ns = 1'700'000'000'000'000'000;

constexpr int kCount = 40;

// Sample i of every link topic (events and mode requests every 10th), source-stamped, and a
// ground sample, paced like a link (the state and camera readers keep the latest sample only).
void publish_flight(Publishers& pub, FlightRecorder& recorder) {
  link::Sample<link::VehicleState> state;
  link::reserve(state->obstacle_points_B_m, 3);
  link::Sample<link::CameraFrame> frame;
  link::reserve(frame->rgb_jpeg, 5);
  for (int i = 0; i < kCount; ++i) {
    const dds_time_t stamp = kSourceStampBase_ns + i * 1'000'000;
    link::VelocityCommand command{};
    command.vehicle_id = 1;
    command.station_id = 7;
    command.sequence_number = 100u + static_cast<unsigned>(i);
    command.t_ns = 5'000 + i;
    command.v_H_mps = {0.25F * static_cast<float>(i), -1.0F, 0.5F};
    command.yaw_rate_radps = 0.125F;
    ASSERT_GE(dds_write_ts(pub.command.handle(), &command, stamp), 0);

    state->vehicle_id = 1;
    state->sequence_number = static_cast<unsigned>(i);
    // The odometry's pose from the second half on: 1 m north, 2 m east (NED-like odom).
    state->odom_valid = i >= kCount / 2;
    state->p_odom_m = {1.0F, 2.0F, 0.0F};
    state->obstacle_points_B_m._length = 3;
    for (std::uint32_t k = 0; k < 3; ++k) {
      state->obstacle_points_B_m._buffer[k] = {1.0F + static_cast<float>(k), 2.0F, -0.5F};
    }
    ASSERT_GE(dds_write_ts(pub.state.handle(), &*state, stamp), 0);

    frame->vehicle_id = 1;
    frame->sequence_number = static_cast<unsigned>(i);
    const std::uint8_t jpeg[5] = {0xFF, 0xD8, 0xFF, static_cast<std::uint8_t>(i), 0xD9};
    std::memcpy(frame->rgb_jpeg._buffer, jpeg, 5);
    frame->rgb_jpeg._length = 5;
    ASSERT_GE(dds_write_ts(pub.camera.handle(), &*frame, stamp), 0);

    link::Heartbeat heartbeat{};
    heartbeat.vehicle_id = 1;
    heartbeat.sequence_number = static_cast<unsigned>(i);
    ASSERT_GE(dds_write_ts(pub.heartbeat.handle(), &heartbeat, stamp), 0);

    if (i % 10 == 0) {
      link::Event event{};
      event.vehicle_id = 1;
      event.sequence_number = static_cast<unsigned>(i);
      hq::format_into(event.text, "event {}", i);
      ASSERT_GE(dds_write_ts(pub.event.handle(), &event, stamp), 0);
      link::ModeRequest mode{};
      mode.vehicle_id = 1;
      mode.requested_mode = hq_msgs_MODE_HOVER;
      ASSERT_GE(dds_write_ts(pub.mode.handle(), &mode, stamp), 0);
    }
    GroundSample g;
    g.t_ns = dds_time();
    g.command_valid = true;
    g.F_D_n[2] = 1.5F;
    g.latency_ms = 2.0F;
    EXPECT_TRUE(recorder.push(g));
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

// The file holds what the recorder reports, channel by channel.
void expect_counts_as_reported(const mcap::McapReader& r, const RecorderReport& report,
                               const std::string& path) {
  EXPECT_TRUE(r.report().has_summary);
  EXPECT_EQ(r.statistics().message_count, report.messages);
  EXPECT_EQ(r.channels().size(), report.channels);
  EXPECT_EQ(fs::file_size(path), report.bytes);
  for (const ChannelReport& c : report.per_channel) {
    const auto got = messages_of(r, c.topic);
    EXPECT_EQ(got.size(), c.messages) << c.topic;
    if (!got.empty()) {
      EXPECT_EQ(got.front()->log_time_ns, c.first_log_time_ns) << c.topic;
      EXPECT_EQ(got.back()->log_time_ns, c.last_log_time_ns) << c.topic;
    }
  }
  // Reliable topics: every sample; best-effort ones on loopback, paced: nearly all.
  EXPECT_EQ(messages_of(r, "/hq/event").size(), 4u);
  EXPECT_EQ(messages_of(r, "/hq/mode_request").size(), 4u);
  EXPECT_GE(messages_of(r, "/hq/velocity_command").size(), kCount * 9u / 10u);
  EXPECT_GE(messages_of(r, "/hq/vehicle_state").size(), kCount * 9u / 10u);
  EXPECT_EQ(messages_of(r, "/camera/image/compressed").size(),
            messages_of(r, "/hq/camera_frame").size());
  EXPECT_EQ(messages_of(r, "/obstacles").size(), messages_of(r, "/hq/vehicle_state").size());
  EXPECT_EQ(messages_of(r, "/ground/haptics").size(), static_cast<std::size_t>(kCount));
  EXPECT_EQ(messages_of(r, "/ground/link").size(), static_cast<std::size_t>(kCount));
}

// The CDR as Cyclone serialised it: decoded here field by field; publish time is the source
// timestamp the writer gave, log time the receipt (after it on this host's clock). The schema
// is the IDL as omgidl, named by its module-qualified type.
void expect_commands_as_cdr(const mcap::McapReader& r) {
  const mcap::Channel* commands = channel_of(r, "/hq/velocity_command");
  ASSERT_NE(commands, nullptr);
  EXPECT_EQ(commands->message_encoding, "cdr");
  const mcap::Schema* schema = r.schema(commands->schema_id);
  ASSERT_NE(schema, nullptr);
  EXPECT_EQ(schema->name, "hq_msgs::VelocityCommand");
  EXPECT_EQ(schema->encoding, "omgidl");
  EXPECT_EQ(std::string(schema->data.begin(), schema->data.end()), link_idl_text());
  EXPECT_NE(link_idl_text().find("struct VelocityCommand"), std::string::npos);
  std::uint64_t previous_sequence = 0;
  for (const mcap::Message* m : messages_of(r, "/hq/velocity_command")) {
    CdrIn in(m->data);
    EXPECT_EQ(in.get<std::uint32_t>(), 1u);
    EXPECT_EQ(in.get<std::uint32_t>(), 7u);
    const auto sequence = in.get<std::uint64_t>();
    const auto t_ns = in.get<std::int64_t>();
    const float vx = in.get<float>();
    EXPECT_EQ(in.get<float>(), -1.0F);
    EXPECT_EQ(in.get<float>(), 0.5F);
    EXPECT_EQ(in.get<float>(), 0.125F);
    const auto i = static_cast<std::int64_t>(sequence) - 100;
    ASSERT_GE(i, 0);
    ASSERT_LT(i, kCount);
    EXPECT_GT(sequence, previous_sequence);
    previous_sequence = sequence;
    EXPECT_EQ(t_ns, 5'000 + i);
    EXPECT_EQ(vx, 0.25F * static_cast<float>(i));
    EXPECT_EQ(m->publish_time_ns, kSourceStampBase_ns + i * 1'000'000);
    EXPECT_GT(m->log_time_ns, 1'600'000'000'000'000'000);
  }
}

// Foxglove channels: JSON with the right schema names and base64 payloads.
void expect_foxglove_channels(const mcap::McapReader& r) {
  const mcap::Channel* image = channel_of(r, "/camera/image/compressed");
  ASSERT_NE(image, nullptr);
  EXPECT_EQ(image->message_encoding, "json");
  EXPECT_EQ(r.schema(image->schema_id)->name, "foxglove.CompressedImage");
  const auto images = messages_of(r, "/camera/image/compressed");
  ASSERT_FALSE(images.empty());
  const std::string first_image(images[0]->data.begin(), images[0]->data.end());
  const nlohmann::json image_json = nlohmann::json::parse(first_image, nullptr, false);
  ASSERT_TRUE(image_json.is_object()) << first_image;
  EXPECT_EQ(image_json.value("format", ""), "jpeg") << first_image;
  EXPECT_EQ(image_json.value("frame_id", ""), "camera_optical") << first_image;
  EXPECT_TRUE(image_json.value("data", "").starts_with("/9j/")) << first_image;  // FF D8 FF
  const auto clouds = messages_of(r, "/obstacles");
  ASSERT_FALSE(clouds.empty());
  EXPECT_EQ(r.schema(channel_of(r, "/obstacles")->schema_id)->name, "foxglove.PointCloud");
  const std::string cloud(clouds[0]->data.begin(), clouds[0]->data.end());
  const nlohmann::json cloud_json = nlohmann::json::parse(cloud, nullptr, false);
  ASSERT_TRUE(cloud_json.is_object()) << cloud;
  // FRD (1, 2, -0.5) is FLU (1, -2, 0.5), float32 LE: 0000803F 000000C0 0000003F.
  EXPECT_TRUE(cloud_json.value("data", "").starts_with("AACAPwAAAMAAAAA/")) << cloud;
  EXPECT_EQ(cloud_json.value("point_stride", 0), 12) << cloud;
  EXPECT_EQ(cloud_json.value("frame_id", ""), "base_link") << cloud;
}

nlohmann::json json_of(const mcap::Message& m) {
  return nlohmann::json::parse(std::string(m.data.begin(), m.data.end()), nullptr, false);
}

// The frame tree Foxglove's 3D panel needs: odom -> base_link per state (heading north, ENU's
// y; at the origin until the state carries the odometry's pose), and the camera mount's
// base_link -> camera_link -> camera_optical on /tf_static.
void expect_frame_transforms(const mcap::McapReader& r) {
  const auto tf = messages_of(r, "/tf");
  EXPECT_EQ(tf.size(), messages_of(r, "/hq/vehicle_state").size());
  ASSERT_FALSE(tf.empty());
  EXPECT_EQ(r.schema(channel_of(r, "/tf")->schema_id)->name, "foxglove.FrameTransform");
  const nlohmann::json odom = json_of(*tf[0]);
  EXPECT_EQ(odom.value("parent_frame_id", ""), "odom") << odom;
  EXPECT_EQ(odom.value("child_frame_id", ""), "base_link") << odom;
  EXPECT_NEAR(odom["rotation"]["z"].get<double>(), std::sqrt(0.5), 1e-9) << odom;
  EXPECT_NEAR(odom["rotation"]["w"].get<double>(), std::sqrt(0.5), 1e-9) << odom;
  EXPECT_EQ(odom["timestamp"]["sec"].get<std::int64_t>(), tf[0]->log_time_ns / 1'000'000'000);
  EXPECT_EQ(odom["translation"]["x"].get<double>(), 0.0) << odom;  // nothing integrated yet
  // Once the state carries the odometry's pose: (1 N, 2 E) is ENU (2, 1, 0).
  const nlohmann::json moved = json_of(*tf.back());
  EXPECT_NEAR(moved["translation"]["x"].get<double>(), 2.0, 1e-6) << moved;
  EXPECT_NEAR(moved["translation"]["y"].get<double>(), 1.0, 1e-6) << moved;
  EXPECT_NEAR(moved["translation"]["z"].get<double>(), 0.0, 1e-6) << moved;

  const auto statics = messages_of(r, "/tf_static");
  ASSERT_GE(statics.size(), 2u);
  const nlohmann::json base_camera = json_of(*statics[0]);
  EXPECT_EQ(base_camera.value("parent_frame_id", ""), "base_link") << base_camera;
  EXPECT_EQ(base_camera.value("child_frame_id", ""), "camera_link") << base_camera;
  // The lever arm p_B_C = (0.1, 0.02, -0.03) FRD is (0.1, -0.02, 0.03) in FLU; a camera
  // looking forward: camera_link is base_link's orientation.
  EXPECT_NEAR(base_camera["translation"]["x"].get<double>(), 0.1, 1e-9);
  EXPECT_NEAR(base_camera["translation"]["y"].get<double>(), -0.02, 1e-9);
  EXPECT_NEAR(base_camera["translation"]["z"].get<double>(), 0.03, 1e-9);
  EXPECT_NEAR(std::abs(base_camera["rotation"]["w"].get<double>()), 1.0, 1e-9) << base_camera;
  const nlohmann::json optical = json_of(*statics[1]);
  EXPECT_EQ(optical.value("parent_frame_id", ""), "camera_link") << optical;
  EXPECT_EQ(optical.value("child_frame_id", ""), "camera_optical") << optical;
  EXPECT_TRUE(messages_of(r, "/camera/calibration").empty());  // no camera given
}

// A camera looking forward (optical z = body x, x = body y, y = body z), 10 cm ahead.
geometry::CameraMount forward_camera() {
  Eigen::Isometry3d T_B_C = Eigen::Isometry3d::Identity();
  T_B_C.linear() << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  T_B_C.translation() = Eigen::Vector3d(0.1, 0.02, -0.03);
  return geometry::CameraMount(T_B_C);
}

TEST_F(FlightRecorderTest, RecordsEveryLinkTopicAsCdrWithStampsAndFoxgloveChannels) {
  const fs::path config = dir_ / "vehicle.yaml";
  std::ofstream(config) << "vehicle:\n  mass_kg: 0.5\n";
  options_.attachments = {{config.string(), ""}, {(dir_ / "missing.yaml").string(), ""}};
  options_.camera_mount = forward_camera();
  FlightRecorder recorder(options_);
  Publishers pub(options_.link);
  ASSERT_TRUE(wait_matched(pub));
  publish_flight(pub, recorder);
  ASSERT_FALSE(HasFatalFailure());
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const RecorderReport& report = recorder.close({{"duration_s", "1.5"}});
  EXPECT_TRUE(report.error.empty()) << report.error;
  EXPECT_FALSE(recorder.failed());
  EXPECT_EQ(report.attachments, 1u);
  ASSERT_EQ(report.attachments_skipped.size(), 1u);
  EXPECT_NE(report.attachments_skipped[0].find("missing.yaml"), std::string::npos);

  const mcap::McapReader r(options_.path);
  expect_counts_as_reported(r, report, options_.path);
  expect_commands_as_cdr(r);
  expect_foxglove_channels(r);
  expect_frame_transforms(r);
  ASSERT_EQ(r.attachments().size(), 1u);
  EXPECT_EQ(r.attachments()[0].name, config.string());
  EXPECT_EQ(r.attachments()[0].media_type, "application/yaml");
  std::map<std::string, mcap::KeyValues> metadata;
  for (const mcap::Metadata& m : r.metadata()) metadata[m.name] = m.values;
  EXPECT_EQ(metadata["flight_summary"]["duration_s"], "1.5");
  EXPECT_EQ(metadata["recorder"]["/hq/event.messages"], "4");
}

// What Cyclone serialised, decoded back through the console's reader (hq::console's
// load_recording: the replay's and hq-report's source), field for field as sent.
TEST_F(FlightRecorderTest, RecordedSamplesReadBackAsTheReplaysRecording) {
  FlightRecorder recorder(options_);
  Publishers pub(options_.link);
  ASSERT_TRUE(wait_matched(pub));
  link::Sample<link::VehicleState> state;
  link::reserve(state->obstacle_points_B_m, 2);
  link::Sample<link::CameraFrame> frame;
  link::reserve(frame->rgb_jpeg, 4);
  for (int i = 0; i < 10; ++i) {
    state->vehicle_id = 1;
    state->sequence_number = 50u + static_cast<unsigned>(i);
    state->v_H_mps = {0.5F, -0.25F * static_cast<float>(i), 0.125F};
    state->mode = hq_msgs_MODE_TELEOP;
    state->obstacle_points_B_m._length = 2;
    state->obstacle_points_B_m._buffer[0] = {0.0F, 3.0F, 4.0F};
    state->obstacle_points_B_m._buffer[1] = {2.0F, 0.0F, 0.0F};
    state->session_id = 99;
    state->flight_state = hq_msgs_FLIGHT_AIRBORNE;
    state->height_source = hq_msgs_HEIGHT_DEPTH;
    state->height_m = 1.5F;
    state->clearance_m = 0.75F;
    ASSERT_TRUE(pub.state.write(*state));
    const std::uint8_t jpeg[4] = {0xFF, 0xD8, static_cast<std::uint8_t>(i), 0xD9};
    std::memcpy(frame->rgb_jpeg._buffer, jpeg, 4);
    frame->rgb_jpeg._length = 4;
    ASSERT_TRUE(pub.camera.write(*frame));
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  link::Event event{};
  event.vehicle_id = 1;
  event.severity = hq_msgs_SEVERITY_WARNING;
  event.code = 7;
  hq::format_into(event.text, "ground heartbeat lost");
  ASSERT_TRUE(pub.event.write(event));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ASSERT_TRUE(recorder.close().error.empty());

  const console::Recording r = console::load_recording(options_.path);
  EXPECT_EQ(r.problem_count, 0u) << (r.problems.empty() ? "" : r.problems[0]);
  ASSERT_GE(r.states.size(), 9u);
  const console::RecordedState& s = r.states.back();
  EXPECT_EQ(s.sequence, 59u);
  EXPECT_EQ(s.v_H_mps[1], -2.25F);
  EXPECT_STREQ(s.mode, "teleop");
  EXPECT_DOUBLE_EQ(s.closest_obstacle_m, 2.0);
  EXPECT_EQ(s.session_id, 99u);
  EXPECT_STREQ(s.flight_state, "airborne");
  EXPECT_DOUBLE_EQ(s.height_m, 1.5);
  EXPECT_DOUBLE_EQ(s.clearance_m, 0.75);
  EXPECT_GE(s.latency_ms, 0.0);
  ASSERT_GE(r.rgb.size(), 9u);
  EXPECT_EQ(r.rgb.back().data, (std::vector<std::uint8_t>{0xFF, 0xD8, 9, 0xD9}));
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].text, "ground heartbeat lost");
  EXPECT_EQ(r.events[0].severity, 1);
  EXPECT_EQ(r.events[0].code, 7);
}

TEST_F(FlightRecorderTest, FileOnDiskIsReadableWhileRecordingAsAfterSigkill) {
  options_.writer.chunk_time_limit_ns = 200'000'000;
  FlightRecorder recorder(options_);
  Publishers pub(options_.link);
  ASSERT_TRUE(wait_matched(pub));
  link::Heartbeat heartbeat{};
  heartbeat.vehicle_id = 3;
  const auto start = std::chrono::steady_clock::now();
  int sent = 0;
  while (std::chrono::steady_clock::now() - start < std::chrono::milliseconds(1200)) {
    heartbeat.sequence_number = static_cast<unsigned>(sent++);
    ASSERT_TRUE(pub.heartbeat.write(heartbeat));
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  // Not closed: no summary, as a killed process leaves it. Everything but the open chunk
  // (at most chunk_time_limit_ns plus a wake period old) is on disk.
  const mcap::McapReader r(options_.path);
  EXPECT_FALSE(r.report().has_summary);
  const auto got = messages_of(r, "/hq/heartbeat");
  EXPECT_GE(got.size(), static_cast<std::size_t>(sent) * 6 / 10) << "of " << sent;
  for (std::size_t i = 1; i < got.size(); ++i) {
    EXPECT_EQ(got[i]->sequence, got[i - 1]->sequence + 1);
  }
  EXPECT_TRUE(recorder.close().error.empty());
}

TEST_F(FlightRecorderTest, BurstFasterThanTheRecorderTakesIsKeptWhole) {
  // The link's own readers keep only the latest state; the recorder's keep a history, so a
  // burst arriving while its (niced) thread is elsewhere is recorded whole.
  FlightRecorder recorder(options_);
  Publishers pub(options_.link);
  ASSERT_TRUE(wait_matched(pub));
  constexpr int kBurst = 50;
  link::Sample<link::VehicleState> state;
  link::VelocityCommand command{};
  for (int i = 0; i < kBurst; ++i) {
    state->vehicle_id = 1;
    state->sequence_number = static_cast<unsigned>(i);
    ASSERT_TRUE(pub.state.write(*state));
    command.vehicle_id = 1;
    command.sequence_number = static_cast<unsigned>(i);
    ASSERT_TRUE(pub.command.write(command));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  EXPECT_TRUE(recorder.close().error.empty());
  const mcap::McapReader r(options_.path);
  EXPECT_EQ(messages_of(r, "/hq/vehicle_state").size(), static_cast<std::size_t>(kBurst));
  EXPECT_EQ(messages_of(r, "/hq/velocity_command").size(), static_cast<std::size_t>(kBurst));
  EXPECT_EQ(messages_of(r, "/obstacles").size(), static_cast<std::size_t>(kBurst));
}

TEST_F(FlightRecorderTest, FullGroundQueueDropsAndCountsWithoutBlocking) {
  options_.ground_queue_capacity = 8;
  FlightRecorder recorder(options_);
  constexpr int kPushed = 20'000;
  int refused = 0;
  GroundSample g;
  for (int i = 0; i < kPushed; ++i) {
    g.t_ns = 1'700'000'000'000'000'000 + i;
    if (!recorder.push(g)) ++refused;
  }
  const RecorderReport& report = recorder.close();
  EXPECT_GT(refused, 0);  // 20000 pushes outrun a thread draining every 100 ms
  EXPECT_EQ(report.ground_samples_dropped, static_cast<std::uint64_t>(refused));
  const mcap::McapReader r(options_.path);
  EXPECT_EQ(messages_of(r, "/ground/haptics").size(), static_cast<std::size_t>(kPushed - refused));
  EXPECT_FALSE(recorder.push(g));  // closed
}

TEST_F(FlightRecorderTest, UnwritableFolderIsAClearError) {
  options_.path = "/nonexistent_hq_dir/flight.mcap";
  const std::string message =
      testing::input_error_message([&] { FlightRecorder recorder(options_); });
  EXPECT_NE(message.find("/nonexistent_hq_dir/flight.mcap"), std::string::npos) << message;
}

TEST_F(FlightRecorderTest, ExistingFlightRecordIsRefusedNotTruncated) {
  std::ofstream(options_.path) << "an earlier flight";
  const std::string message =
      testing::input_error_message([&] { FlightRecorder recorder(options_); });
  EXPECT_NE(message.find("flight.mcap: exists"), std::string::npos) << message;
  EXPECT_EQ(fs::file_size(options_.path), 17u);
}

TEST_F(FlightRecorderTest, WriteFailureMidFlightStopsRecordingAndSaysWhy) {
  // A file size limit stands in for a full disk: write(2) fails with EFBIG mid-flight (the
  // limit above the opening: schemas, Foxglove's among them, and the first chunks).
  std::signal(SIGXFSZ, SIG_IGN);
  rlimit saved{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
  rlimit limited = saved;
  limited.rlim_cur = 256 * 1024;
  options_.writer.chunk_size_bytes = 8 * 1024;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &limited), 0);
  {
    FlightRecorder recorder(options_);
    Publishers pub(options_.link);
    ASSERT_TRUE(wait_matched(pub));
    link::Sample<link::CameraFrame> frame;
    link::reserve(frame->rgb_jpeg, 20'000);
    frame->rgb_jpeg._length = 20'000;
    // Bytes a chunk's compression cannot shrink, as a JPEG's: 100 frames are 2 MB on disk.
    std::mt19937 noise(7);
    for (int i = 0; i < 100 && !recorder.failed(); ++i) {
      for (std::uint32_t b = 0; b < frame->rgb_jpeg._length; ++b) {
        frame->rgb_jpeg._buffer[b] = static_cast<std::uint8_t>(noise());
      }
      frame->sequence_number = static_cast<unsigned>(i);
      ASSERT_TRUE(pub.camera.write(*frame));
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      GroundSample g;
      const auto t0 = std::chrono::steady_clock::now();
      recorder.push(g);
      EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::milliseconds(5));
    }
    EXPECT_TRUE(recorder.failed());
    EXPECT_NE(recorder.error().find("flight.mcap"), std::string::npos) << recorder.error();
    EXPECT_NE(recorder.error().find("File too large"), std::string::npos) << recorder.error();
    const RecorderReport& report = recorder.close();
    EXPECT_EQ(report.error, recorder.error());
  }
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &saved), 0);
  std::signal(SIGXFSZ, SIG_DFL);
}

}  // namespace
}  // namespace hq::mcap_recorder
