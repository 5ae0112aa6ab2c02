// hq_ros2_probe: the other side of a vehicle run with --ros2, for test/ros2_topics.sh.
//   hq_ros2_probe --domain-id D --out DIR [--ns hq1] [--seconds 20] [--heading-deg 45]
// As a native ground station (station 1) it takes the vehicle off in teleop; then, as a ROS 2
// teleop node, it publishes Twist (0.3 m/s along the camera's heading, --heading-deg
// right of forward: the vehicle limits what it flies to the space its camera has seen) as a
// geometry_msgs/Twist on rt/<ns>/cmd_vel (teleop_twist_keyboard's default) and checks in the
// vehicle's state that station 250 commands and the command flown is the ROS one in H; then, as
// the ROS node, it changes mode with std_msgs/String texts on rt/<ns>/mode_request (an unknown
// one refused, hover and teleop accepted, each answer read on rt/<ns>/mode_status); then the
// native station commands 0.1 m/s along the heading beside the ROS node and must take over, and
// the ROS node's "land" is refused by the vehicle's gate (a station that does not command).
// Meanwhile it takes every rt/ topic as raw CDR (dds_takecdr, the bytes a ROS 2 machine receives)
// into DIR/<topic>.cdr (records: uint32 little-endian length, bytes; rt/tf_static read by a reader
// created only once airborne, as a late tf2 listener; ros_discovery_info as `ros2 node list`
// reads it) and writes each native state's
// stamp, v_H and attitude to DIR/states.csv, for the independent decoder (decode_ros2.cjs).
// Exit 0 when both phases were seen, 1 naming the phase that was not, 2 on bad arguments.
#include "hq/link/link.hpp"
#include "hq/ros2_bridge/ros2_bridge.hpp"

#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fmt/format.h>
#include <iterator>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace {

using hq::link::Participant;
using Clock = std::chrono::steady_clock;

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
      .count();
}

// One rt/ topic read as raw CDR into a file.
struct RawDump {
  std::string name;
  dds_entity_t reader = 0;
  std::FILE* file = nullptr;
  int samples = 0;
  int max_samples = 0;

  void drain() {
    std::array<ddsi_serdata*, 8> samples_cdr{};
    std::array<dds_sample_info_t, 8> infos{};
    for (;;) {
      const dds_return_t n =
          dds_takecdr(reader, samples_cdr.data(), samples_cdr.size(), infos.data(), DDS_ANY_STATE);
      if (n <= 0) return;
      for (std::size_t i = 0; i < static_cast<std::size_t>(n); ++i) {
        if (infos[i].valid_data && samples < max_samples) {
          const std::uint32_t size = ddsi_serdata_size(samples_cdr[i]);
          std::vector<unsigned char> bytes(size);
          ddsi_serdata_to_ser(samples_cdr[i], 0, size, bytes.data());
          const unsigned char length[4] = {static_cast<unsigned char>(size & 0xFF),
                                           static_cast<unsigned char>((size >> 8) & 0xFF),
                                           static_cast<unsigned char>((size >> 16) & 0xFF),
                                           static_cast<unsigned char>((size >> 24) & 0xFF)};
          std::fwrite(length, 1, 4, file);
          std::fwrite(bytes.data(), 1, bytes.size(), file);
          ++samples;
        }
        ddsi_serdata_unref(samples_cdr[i]);
      }
    }
  }
};

template <typename T>
RawDump raw_dump(const Participant& participant, std::vector<hq::link::Topic<T>>& topics,
                 const std::string& dds_name, const std::string& file, int max_samples,
                 const hq::link::Qos& qos = hq::ros2_bridge::ros2_qos()) {
  topics.emplace_back(participant, dds_name);
  RawDump d;
  d.name = dds_name;
  d.max_samples = max_samples;
  d.reader = hq::link::check(
      dds_create_reader(participant.handle(), topics.back().handle(), qos.get(), nullptr),
      "dds_create_reader", dds_name);
  d.file = std::fopen(file.c_str(), "wb");
  if (d.file == nullptr) throw hq::InputError(file + ": cannot open for writing");
  return d;
}

struct Args {
  int domain_id = 0;
  std::string out;
  std::string ns = "hq1";
  double seconds = 20.0;
  double heading_deg = 45.0;  ///< The camera's heading in B (calib/vehicle_core_paper.yaml).
};

/// Parses --key value pairs; prints what is wrong and returns nullopt on bad arguments.
std::optional<Args> parse_args(int argc, char** argv) {
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--domain-id") {
      a.domain_id = std::atoi(argv[i + 1]);
    } else if (key == "--out") {
      a.out = argv[i + 1];
    } else if (key == "--ns") {
      a.ns = argv[i + 1];
    } else if (key == "--seconds") {
      a.seconds = std::atof(argv[i + 1]);
    } else if (key == "--heading-deg") {
      a.heading_deg = std::atof(argv[i + 1]);
    } else {
      fmt::print(stderr, "hq_ros2_probe: unknown option {}\n", key);
      return std::nullopt;
    }
  }
  if (a.out.empty()) {
    fmt::print(stderr, "hq_ros2_probe: --out DIR is required\n");
    return std::nullopt;
  }
  return a;
}

/// The native station and the ROS 2 node of the test, stepped every 20 ms through three phases.
class Probe {
 public:
  explicit Probe(const Args& a)
      : a_(a),
        participant_(a.domain_id),
        topics_(participant_),
        states_(participant_, topics_.vehicle_state, hq::link::vehicle_state_qos()),
        requests_(participant_, topics_.mode_request, hq::link::mode_request_qos()),
        heartbeats_(participant_, topics_.heartbeat, hq::link::heartbeat_qos(insecure(a))),
        commands_(participant_, topics_.command,
                  hq::link::command_qos(insecure(a), hq::link::End::kWriter)),
        twist_topic_(participant_, hq::ros2_bridge::dds_topic_name(a.ns, "cmd_vel")),
        twists_(participant_, twist_topic_, hq::ros2_bridge::ros2_qos()),
        mode_request_topic_(participant_, hq::ros2_bridge::dds_topic_name(a.ns, "mode_request")),
        mode_status_topic_(participant_, hq::ros2_bridge::dds_topic_name(a.ns, "mode_status")),
        ros_mode_requests_(participant_, mode_request_topic_, hq::ros2_bridge::ros2_qos()),
        ros_mode_status_(participant_, mode_status_topic_, hq::ros2_bridge::ros2_qos()),
        cos_heading_(static_cast<float>(std::cos(a.heading_deg * M_PI / 180.0))),
        sin_heading_(static_cast<float>(std::sin(a.heading_deg * M_PI / 180.0))) {
    open_dumps();
    // Along the heading, in H: (cos, sin) right of forward; in the ROS body FLU y is left.
    twist_.linear = {0.3 * static_cast<double>(cos_heading_),
                     -0.3 * static_cast<double>(sin_heading_), 0.0};
    csv_ = std::fopen((a.out + "/states.csv").c_str(), "w");
    if (csv_ == nullptr) throw hq::InputError(a.out + "/states.csv: cannot open for writing");
    fmt::print(csv_, "t_ns,v_H_x,v_H_y,v_H_z,roll_rad,pitch_rad\n");
  }

  /// Exit status: 0 when both phases were seen, 1 naming the one that was not.
  int run() {
    phase_start_ns_ = now_ns();
    const std::int64_t end_ns = now_ns() + static_cast<std::int64_t>(a_.seconds * 1e9);
    while (now_ns() < end_ns && phase_ != Phase::kDone) {
      const std::int64_t t_ns = now_ns();
      take_states();
      send_heartbeat(t_ns);
      if (!step(t_ns)) return 1;
      for (RawDump& d : dumps_) d.drain();
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    close_files();
    if (phase_ != Phase::kDone) {
      fmt::print("probe: FAILED: {}\n",
                 phase_ == Phase::kTakeOff ? "the vehicle never got airborne" : "ran out of time");
      return 1;
    }
    return 0;
  }

 private:
  enum class Phase { kTakeOff, kRos, kRosModes, kNative, kRosRefused, kDone };

  /// A mode text the ROS node sends and what the vehicle's answer must contain (re-sent each
  /// second until it does: the modes' dwell may refuse a change at first).
  struct ModeStep {
    const char* text;
    const char* answer;
    int mode;  ///< The state's mode once accepted; -1: none (a refusal).
  };
  static constexpr ModeStep kModeSteps[] = {
      {"fly_upside_down", "refused: unknown mode", -1},
      {"hover", "mode hover accepted", hq_msgs_MODE_HOVER},
      {"teleop", "mode teleop accepted", hq_msgs_MODE_TELEOP}};

  static hq::link::LinkConfig insecure(const Args& a) {
    hq::link::LinkConfig config;
    config.domain_id = a.domain_id;
    config.security.enabled = false;
    return config;
  }

  void open_dumps() {
    using namespace hq::ros2_bridge;
    const auto rt = [&](const char* name) { return dds_topic_name(a_.ns, name); };
    const auto file = [&](const char* name) { return a_.out + "/" + name + ".cdr"; };
    dumps_.push_back(raw_dump(participant_, odom_topics_, rt("odom"), file("odom"), 400));
    dumps_.push_back(raw_dump(participant_, imu_topics_, rt("imu"), file("imu"), 40));
    dumps_.push_back(raw_dump(participant_, tf_topics_, "rt/tf", file("tf"), 40));
    dumps_.push_back(raw_dump(participant_, cloud_topics_, rt("obstacles"), file("obstacles"), 10));
    dumps_.push_back(
        raw_dump(participant_, image_topics_, rt("camera/image/compressed"), file("image"), 10));
    dumps_.push_back(
        raw_dump(participant_, info_topics_, rt("camera/camera_info"), file("camera_info"), 10));
    dumps_.push_back(raw_dump(participant_, clock_topics_, "rt/clock", file("clock"), 400));
    // What this probe sends as teleop_twist_keyboard would, as the bytes on the wire.
    dumps_.push_back(raw_dump(participant_, cmd_vel_topics_, rt("cmd_vel"), file("cmd_vel"), 20));
    dumps_.push_back(
        raw_dump(participant_, status_topics_, rt("mode_status"), file("mode_status"), 20));
    dumps_.push_back(raw_dump(participant_, discovery_topics_, "ros_discovery_info",
                              file("ros_discovery_info"), 20, discovery_info_qos()));
  }

  /// Every new state: into states.csv, and counted when it shows the phase's commander flying
  /// the phase's command.
  void take_states() {
    dds_sample_info_t info{};
    while (states_.take(*state_, info)) {
      have_state_ = true;
      session_ = state_->session_id;
      fmt::print(csv_, "{},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f}\n",
                 static_cast<long long>(state_->t_ns), static_cast<double>(state_->v_H_mps.x),
                 static_cast<double>(state_->v_H_mps.y), static_cast<double>(state_->v_H_mps.z),
                 static_cast<double>(state_->roll_rad), static_cast<double>(state_->pitch_rad));
      if (phase_ == Phase::kRos && flies(250, 0.3F)) ++ros_seen_;
      if (phase_ == Phase::kNative && flies(1, 0.1F)) ++native_seen_;
    }
  }

  [[nodiscard]] bool flies(std::uint32_t station_id, float speed_mps) const {
    const auto& v = state_->v_cmd_flown_H_mps;
    return state_->commanding_station_id == station_id &&
           std::abs(v.x - speed_mps * cos_heading_) < 0.02F &&
           std::abs(v.y - speed_mps * sin_heading_) < 0.02F;
  }

  void send_heartbeat(std::int64_t t_ns) {
    if (t_ns < next_heartbeat_ns_) return;
    next_heartbeat_ns_ = t_ns + 100'000'000;
    hq::link::Heartbeat h{};
    h.vehicle_id = 1;
    h.role = hq_msgs_ROLE_GROUND;
    h.sender_id = 1;
    h.sequence_number = ++sequence_;
    h.t_ns = t_ns;
    h.session_id = 42;
    heartbeats_.write(h);
  }

  /// One step of the current phase; false when the phase failed (said on stdout).
  bool step(std::int64_t t_ns) {
    switch (phase_) {
      case Phase::kTakeOff:
        step_take_off(t_ns);
        return true;
      case Phase::kRos:
        return step_ros(t_ns);
      case Phase::kRosModes:
        return step_ros_modes(t_ns);
      case Phase::kNative:
        return step_native(t_ns);
      case Phase::kRosRefused:
        return step_ros_refused(t_ns);
      case Phase::kDone:
        return true;
    }
    return true;
  }

  void step_take_off(std::int64_t t_ns) {
    if (have_state_ && t_ns >= next_request_ns_) {
      next_request_ns_ = t_ns + 1'000'000'000;
      hq::link::ModeRequest r{};
      r.vehicle_id = 1;
      r.station_id = 1;
      r.sequence_number = ++sequence_;
      r.t_ns = t_ns;
      r.requested_mode = hq_msgs_MODE_TELEOP;
      r.vehicle_session_id = session_;
      r.take_off = true;
      requests_.write(r);
    }
    if (have_state_ && state_->flight_state == hq_msgs_FLIGHT_AIRBORNE) {
      fmt::print("probe: airborne after {:.1f} s\n",
                 1e-9 * static_cast<double>(t_ns - phase_start_ns_));
      next_phase(Phase::kRos, t_ns);
    }
  }

  bool step_ros(std::int64_t t_ns) {
    twists_.write(twist_);
    if (ros_seen_ >= 10) {
      fmt::print("probe: ROS 2 Twist on cmd_vel flown by station 250 after {:.1f} s\n",
                 1e-9 * static_cast<double>(t_ns - phase_start_ns_));
      next_phase(Phase::kRosModes, t_ns);
    } else if (t_ns - phase_start_ns_ > 5'000'000'000) {
      fmt::print(
          "probe: FAILED: the ROS 2 command was not flown within 5 s (commanding station {}, "
          "v_cmd_flown_H x {:.2f}, operator input {}, mode {})\n",
          state_->commanding_station_id, static_cast<double>(state_->v_cmd_flown_H_mps.x),
          static_cast<int>(state_->operator_input), static_cast<int>(state_->mode));
      return false;
    }
    return true;
  }

  bool step_native(std::int64_t t_ns) {
    twists_.write(twist_);  // the ROS node goes on: the native station must win anyway
    hq::link::VelocityCommand command{};
    command.vehicle_id = 1;
    command.station_id = 1;
    command.sequence_number = ++sequence_;
    command.t_ns = t_ns;
    command.v_H_mps = {0.1F * cos_heading_, 0.1F * sin_heading_, 0.0F};
    commands_.write(command);
    if (native_seen_ >= 10) {
      fmt::print("probe: native station 1 overrode the ROS 2 node after {:.1f} s\n",
                 1e-9 * static_cast<double>(t_ns - phase_start_ns_));
      next_phase(Phase::kRosRefused, t_ns);
    } else if (t_ns - phase_start_ns_ > 5'000'000'000) {
      fmt::print(
          "probe: FAILED: the native station did not take over within 5 s (commanding station {}, "
          "v_cmd_flown_H x {:.2f})\n",
          state_->commanding_station_id, static_cast<double>(state_->v_cmd_flown_H_mps.x));
      return false;
    }
    return true;
  }

  /// The newest mode_status answer, if one came since the last call.
  bool take_answer() {
    dds_sample_info_t info{};
    bool got = false;
    while (ros_mode_status_.take(*answer_, info)) {
      last_answer_ = answer_->data != nullptr ? answer_->data : "";
      got = true;
    }
    return got;
  }

  void send_mode_text(const char* text, std::int64_t t_ns) {
    std::string copy = text;
    hq::ros2_bridge::RosString sample{};
    sample.data = copy.data();
    ros_mode_requests_.write(sample);
    next_request_ns_ = t_ns + 1'000'000'000;
  }

  bool step_ros_modes(std::int64_t t_ns) {
    twists_.write(twist_);  // the ROS node still commands: it is the station that may ask
    const ModeStep& step = kModeSteps[mode_step_];
    if (t_ns >= next_request_ns_) send_mode_text(step.text, t_ns);
    const bool answered = take_answer() && last_answer_.find(step.answer) != std::string::npos;
    if (answered) step_answered_ = true;
    if (step_answered_ && (step.mode < 0 || static_cast<int>(state_->mode) == step.mode)) {
      fmt::print("probe: ROS 2 mode request \"{}\" answered \"{}\"\n", step.text, last_answer_);
      step_answered_ = false;
      next_request_ns_ = 0;
      if (++mode_step_ == std::size(kModeSteps)) next_phase(Phase::kNative, t_ns);
      return true;
    }
    if (t_ns - phase_start_ns_ > 8'000'000'000) {
      fmt::print("probe: FAILED: ROS 2 mode request \"{}\": last answer \"{}\", mode {}\n",
                 step.text, last_answer_, static_cast<int>(state_->mode));
      return false;
    }
    return true;
  }

  bool step_ros_refused(std::int64_t t_ns) {
    if (t_ns >= next_request_ns_) send_mode_text("land", t_ns);
    if (take_answer() && last_answer_.find("does not command") != std::string::npos) {
      fmt::print("probe: ROS 2 \"land\" while station 1 commands: \"{}\"\n", last_answer_);
      next_phase(Phase::kDone, t_ns);
    } else if (t_ns - phase_start_ns_ > 5'000'000'000) {
      fmt::print("probe: FAILED: ROS 2 \"land\" not refused by the gate (last answer \"{}\")\n",
                 last_answer_);
      return false;
    }
    return true;
  }

  void next_phase(Phase phase, std::int64_t t_ns) {
    if (phase == Phase::kRos) {
      // A late joiner, as tf2's static listener: /tf_static was written at the vehicle's first
      // state, seconds ago; transient local must still deliver it.
      tf_static_topics_.reserve(1);
      dumps_.push_back(raw_dump(participant_, tf_static_topics_, "rt/tf_static",
                                a_.out + "/tf_static.cdr", 5, hq::ros2_bridge::tf_static_qos()));
    }
    phase_ = phase;
    phase_start_ns_ = t_ns;
    next_request_ns_ = 0;
  }

  void close_files() {
    for (RawDump& d : dumps_) {
      d.drain();
      fmt::print("probe: {}: {} samples\n", d.name, d.samples);
      std::fclose(d.file);
    }
    std::fclose(csv_);
  }

  Args a_;
  Participant participant_;
  hq::link::Topics topics_;
  hq::link::Reader<hq::link::VehicleState> states_;
  hq::link::Writer<hq::link::ModeRequest> requests_;
  hq::link::Writer<hq::link::Heartbeat> heartbeats_;
  hq::link::Writer<hq::link::VelocityCommand> commands_;
  hq::link::Topic<hq::ros2_bridge::Twist> twist_topic_;
  hq::link::Writer<hq::ros2_bridge::Twist> twists_;
  hq::link::Topic<hq::ros2_bridge::RosString> mode_request_topic_;
  hq::link::Topic<hq::ros2_bridge::RosString> mode_status_topic_;
  hq::link::Writer<hq::ros2_bridge::RosString> ros_mode_requests_;
  hq::link::Reader<hq::ros2_bridge::RosString> ros_mode_status_;
  hq::link::Sample<hq::ros2_bridge::RosString> answer_;
  std::string last_answer_;
  std::size_t mode_step_ = 0;
  bool step_answered_ = false;
  // One topic each, in vectors so raw_dump can create them in place (a Topic does not move).
  std::vector<hq::link::Topic<hq::ros2_bridge::Odometry>> odom_topics_;
  std::vector<hq::link::Topic<hq::ros2_bridge::Imu>> imu_topics_;
  std::vector<hq::link::Topic<hq::ros2_bridge::TfMessage>> tf_topics_;
  std::vector<hq::link::Topic<hq::ros2_bridge::PointCloud2>> cloud_topics_;
  std::vector<hq::link::Topic<hq::ros2_bridge::CompressedImage>> image_topics_;
  std::vector<hq::link::Topic<hq::ros2_bridge::CameraInfo>> info_topics_;
  std::vector<hq::link::Topic<hq::ros2_bridge::RosClockMsg>> clock_topics_;
  std::vector<hq::link::Topic<hq::ros2_bridge::TfMessage>> tf_static_topics_;
  std::vector<hq::link::Topic<hq::ros2_bridge::Twist>> cmd_vel_topics_;
  std::vector<hq::link::Topic<hq::ros2_bridge::RosString>> status_topics_;
  std::vector<hq::link::Topic<hq::ros2_bridge::ParticipantEntitiesInfo>> discovery_topics_;
  std::vector<RawDump> dumps_;
  hq::ros2_bridge::Twist twist_{};
  float cos_heading_;
  float sin_heading_;
  std::FILE* csv_ = nullptr;
  hq::link::Sample<hq::link::VehicleState> state_;
  bool have_state_ = false;
  Phase phase_ = Phase::kTakeOff;
  std::uint64_t session_ = 0;
  std::uint64_t sequence_ = 0;
  std::int64_t phase_start_ns_ = 0;
  std::int64_t next_request_ns_ = 0;
  std::int64_t next_heartbeat_ns_ = 0;
  int ros_seen_ = 0;
  int native_seen_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  const std::optional<Args> args = parse_args(argc, argv);
  if (!args) return 2;
  try {
    Probe probe(*args);
    return probe.run();
  } catch (const std::exception& e) {
    fmt::print(stderr, "hq_ros2_probe: {}\n", e.what());
    return 2;
  }
}
