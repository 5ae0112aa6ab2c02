// hq_ros2_probe: the other side of a vehicle run with --ros2, for test/ros2_topics.sh.
//   hq_ros2_probe --domain-id D --out DIR [--ns hq1] [--seconds 20] [--heading-deg 45]
// As a native ground station (station 1) it takes the vehicle off in teleop; then, as a ROS 2
// teleop node, it publishes TwistStamped (0.3 m/s along the camera's heading, --heading-deg
// right of forward: the vehicle limits what it flies to the space its camera has seen) on
// rt/<ns>/cmd_vel_in and checks in the vehicle's state that station 250 commands and the command
// flown is the ROS one in H; then the native station commands 0.1 m/s along the heading beside
// the ROS node and must take over. Meanwhile it
// takes every rt/ topic as raw CDR (dds_takecdr, the bytes a ROS 2 machine receives) into
// DIR/<topic>.cdr (records: uint32 little-endian length, bytes) and writes each native state's
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
      for (dds_return_t i = 0; i < n; ++i) {
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
                 const std::string& dds_name, const std::string& file, int max_samples) {
  topics.emplace_back(participant, dds_name);
  RawDump d;
  d.name = dds_name;
  d.max_samples = max_samples;
  d.reader = hq::link::check(dds_create_reader(participant.handle(), topics.back().handle(),
                                               hq::ros2_bridge::ros2_qos().get(), nullptr),
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

}  // namespace

int main(int argc, char** argv) {
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--domain-id")
      a.domain_id = std::atoi(argv[i + 1]);
    else if (key == "--out")
      a.out = argv[i + 1];
    else if (key == "--ns")
      a.ns = argv[i + 1];
    else if (key == "--seconds")
      a.seconds = std::atof(argv[i + 1]);
    else if (key == "--heading-deg")
      a.heading_deg = std::atof(argv[i + 1]);
    else {
      std::fprintf(stderr, "hq_ros2_probe: unknown option %s\n", key.c_str());
      return 2;
    }
  }
  if (a.out.empty()) {
    std::fprintf(stderr, "hq_ros2_probe: --out DIR is required\n");
    return 2;
  }
  try {
    hq::link::LinkConfig config;
    config.domain_id = a.domain_id;
    config.security.enabled = false;
    Participant participant(config.domain_id);
    hq::link::Topics topics(participant);
    hq::link::Reader<hq::link::VehicleState> states(participant, topics.vehicle_state,
                                                    hq::link::vehicle_state_qos());
    hq::link::Writer<hq::link::ModeRequest> requests(participant, topics.mode_request,
                                                     hq::link::mode_request_qos());
    hq::link::Writer<hq::link::Heartbeat> heartbeats(participant, topics.heartbeat,
                                                     hq::link::heartbeat_qos(config));
    hq::link::Writer<hq::link::VelocityCommand> commands(
        participant, topics.command, hq::link::command_qos(config, hq::link::End::kWriter));

    using namespace hq::ros2_bridge;
    const auto rt = [&](const char* name) { return dds_topic_name(a.ns, name); };
    const auto file = [&](const char* name) { return a.out + "/" + name + ".cdr"; };
    std::vector<hq::link::Topic<Odometry>> odom_topics;
    std::vector<hq::link::Topic<Imu>> imu_topics;
    std::vector<hq::link::Topic<TfMessage>> tf_topics;
    std::vector<hq::link::Topic<PointCloud2>> cloud_topics;
    std::vector<hq::link::Topic<CompressedImage>> image_topics;
    std::vector<hq::link::Topic<CameraInfo>> info_topics;
    odom_topics.reserve(1);
    imu_topics.reserve(1);
    tf_topics.reserve(1);
    cloud_topics.reserve(1);
    image_topics.reserve(1);
    info_topics.reserve(1);
    std::vector<RawDump> dumps;
    dumps.push_back(raw_dump(participant, odom_topics, rt("odom"), file("odom"), 400));
    dumps.push_back(raw_dump(participant, imu_topics, rt("imu"), file("imu"), 40));
    dumps.push_back(raw_dump(participant, tf_topics, "rt/tf", file("tf"), 40));
    dumps.push_back(raw_dump(participant, cloud_topics, rt("obstacles"), file("obstacles"), 10));
    dumps.push_back(
        raw_dump(participant, image_topics, rt("camera/image/compressed"), file("image"), 10));
    dumps.push_back(
        raw_dump(participant, info_topics, rt("camera/camera_info"), file("camera_info"), 10));

    hq::link::Topic<TwistStamped> twist_topic(participant, rt("cmd_vel_in"));
    hq::link::Writer<TwistStamped> twists(participant, twist_topic, ros2_qos());
    std::string twist_frame = a.ns + "/base_link";
    TwistStamped twist{};
    twist.header.frame_id = twist_frame.data();
    // Along the heading, in H: (cos, sin) right of forward; in the ROS body FLU y is left.
    const float c = static_cast<float>(std::cos(a.heading_deg * M_PI / 180.0));
    const float s = static_cast<float>(std::sin(a.heading_deg * M_PI / 180.0));
    twist.twist.linear = {0.3 * c, -0.3 * s, 0.0};

    std::FILE* csv = std::fopen((a.out + "/states.csv").c_str(), "w");
    if (csv == nullptr) throw hq::InputError(a.out + "/states.csv: cannot open for writing");
    std::fprintf(csv, "t_ns,v_H_x,v_H_y,v_H_z,roll_rad,pitch_rad\n");

    enum class Phase { kTakeOff, kRos, kNative, kDone };
    Phase phase = Phase::kTakeOff;
    std::uint64_t session = 0;
    std::uint64_t sequence = 0;
    std::int64_t phase_start_ns = now_ns();
    std::int64_t next_request_ns = 0;
    std::int64_t next_heartbeat_ns = 0;
    int ros_seen = 0;
    int native_seen = 0;
    const std::int64_t end_ns = now_ns() + static_cast<std::int64_t>(a.seconds * 1e9);
    hq::link::Sample<hq::link::VehicleState> state;
    bool have_state = false;
    while (now_ns() < end_ns && phase != Phase::kDone) {
      const std::int64_t t_ns = now_ns();
      dds_sample_info_t info{};
      while (states.take(*state, info)) {
        have_state = true;
        session = state->session_id;
        std::fprintf(csv, "%lld,%.6f,%.6f,%.6f,%.6f,%.6f\n", static_cast<long long>(state->t_ns),
                     state->v_H_mps.x, state->v_H_mps.y, state->v_H_mps.z, state->roll_rad,
                     state->pitch_rad);
        const auto& v = state->v_cmd_flown_H_mps;
        if (phase == Phase::kRos && state->commanding_station_id == 250 &&
            std::abs(v.x - 0.3F * c) < 0.02F && std::abs(v.y - 0.3F * s) < 0.02F) {
          ++ros_seen;
        }
        if (phase == Phase::kNative && state->commanding_station_id == 1 &&
            std::abs(v.x - 0.1F * c) < 0.02F && std::abs(v.y - 0.1F * s) < 0.02F) {
          ++native_seen;
        }
      }
      if (t_ns >= next_heartbeat_ns) {
        next_heartbeat_ns = t_ns + 100'000'000;
        hq::link::Heartbeat h{};
        h.vehicle_id = 1;
        h.role = hq_msgs_ROLE_GROUND;
        h.sender_id = 1;
        h.sequence_number = ++sequence;
        h.t_ns = t_ns;
        h.session_id = 42;
        heartbeats.write(h);
      }
      switch (phase) {
        case Phase::kTakeOff:
          if (have_state && t_ns >= next_request_ns) {
            next_request_ns = t_ns + 1'000'000'000;
            hq::link::ModeRequest r{};
            r.vehicle_id = 1;
            r.station_id = 1;
            r.sequence_number = ++sequence;
            r.t_ns = t_ns;
            r.requested_mode = hq_msgs_MODE_TELEOP;
            r.vehicle_session_id = session;
            r.take_off = true;
            requests.write(r);
          }
          if (have_state && state->flight_state == hq_msgs_FLIGHT_AIRBORNE) {
            std::printf("probe: airborne after %.1f s\n", 1e-9 * (t_ns - phase_start_ns));
            phase = Phase::kRos;
            phase_start_ns = t_ns;
          }
          break;
        case Phase::kRos:
          twists.write(twist);
          if (ros_seen >= 10) {
            std::printf("probe: ROS 2 cmd_vel_in flown by station 250 after %.1f s\n",
                        1e-9 * (t_ns - phase_start_ns));
            phase = Phase::kNative;
            phase_start_ns = t_ns;
          } else if (t_ns - phase_start_ns > 5'000'000'000) {
            std::printf(
                "probe: FAILED: the ROS 2 command was not flown within 5 s "
                "(commanding station %u, v_cmd_flown_H x %.2f, operator input %d, "
                "mode %d)\n",
                state->commanding_station_id, state->v_cmd_flown_H_mps.x,
                static_cast<int>(state->operator_input), static_cast<int>(state->mode));
            return 1;
          }
          break;
        case Phase::kNative: {
          twists.write(twist);  // the ROS node goes on: the native station must win anyway
          hq::link::VelocityCommand command{};
          command.vehicle_id = 1;
          command.station_id = 1;
          command.sequence_number = ++sequence;
          command.t_ns = t_ns;
          command.v_H_mps = {0.1F * c, 0.1F * s, 0.0F};
          commands.write(command);
          if (native_seen >= 10) {
            std::printf("probe: native station 1 overrode the ROS 2 node after %.1f s\n",
                        1e-9 * (t_ns - phase_start_ns));
            phase = Phase::kDone;
          } else if (t_ns - phase_start_ns > 5'000'000'000) {
            std::printf(
                "probe: FAILED: the native station did not take over within 5 s "
                "(commanding station %u, v_cmd_flown_H x %.2f)\n",
                state->commanding_station_id, state->v_cmd_flown_H_mps.x);
            return 1;
          }
          break;
        }
        case Phase::kDone:
          break;
      }
      for (RawDump& d : dumps) d.drain();
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    for (RawDump& d : dumps) {
      d.drain();
      std::printf("probe: %s: %d samples\n", d.name.c_str(), d.samples);
      std::fclose(d.file);
    }
    std::fclose(csv);
    if (phase != Phase::kDone) {
      std::printf("probe: FAILED: %s\n",
                  phase == Phase::kTakeOff ? "the vehicle never got airborne" : "ran out of time");
      return 1;
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hq_ros2_probe: %s\n", e.what());
    return 2;
  }
}
