#include "hq/sitl/sitl_runner.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/base/log.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/frame_channel/frame_channel.hpp"
#include "hq/mavlink/codec.hpp"
#include "hq/mavlink/transport.hpp"

#include <algorithm>
#include <arpa/inet.h>
#include <array>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <memory>
#include <mutex>
#include <netinet/in.h>
#include <span>
#include <sys/socket.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace hq::sitl {

// The simulator this flight controller flies: its state, IMU and commands.
using sim::ImuSample;
using sim::kHardFloorImpactSpeedMps;
using sim::RgbdRenderer;
using sim::SimConfig;
using sim::Simulator;
using sim::TruthState;
using sim::World;

namespace {

/// The transport binds with SO_REUSEADDR, with which Linux lets a second UDP socket bind the
/// same port and steal its datagrams; a probe bind without it tells that a port is taken.
void ensure_listen_port_free(const std::string& spec) {
  const std::string prefix = "udp-listen:";
  if (spec.rfind(prefix, 0) != 0) return;
  const std::string rest = spec.substr(prefix.size());
  const std::size_t colon = rest.rfind(':');
  const std::string host = colon == std::string::npos ? "127.0.0.1" : rest.substr(0, colon);
  const std::string port_text = colon == std::string::npos ? rest : rest.substr(colon + 1);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  char* end = nullptr;
  const long port = std::strtol(port_text.c_str(), &end, 10);
  if (end == port_text.c_str() || *end != '\0' || port < 1 || port > 65535 ||
      inet_pton(AF_INET, host.c_str(), &addr.sin_addr) != 1) {
    return;  // open_transport names what is wrong with the spec
  }
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return;
  const int rc = ::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr));
  const int error = errno;
  ::close(fd);
  if (rc != 0 && error == EADDRINUSE) {
    throw InputError("--mavlink " + spec + ": UDP port " + port_text +
                     " is in use (another hq-sim --sitl?); choose another port");
  }
}

/// Encodes the autopilot's messages and sends each as one datagram.
class TransportSink final : public MessageSink {
 public:
  explicit TransportSink(mavlink::Transport& transport)
      : transport_(transport), encoder_(1, mavlink::kMavCompIdAutopilot1) {}
  void send(const mavlink::Message& message) override {
    const std::size_t n = encoder_.encode(message, buffer_);
    if (transport_.send(std::span<const std::uint8_t>(buffer_.data(), n))) {
      ++sent_;
    } else {
      ++failed_;
    }
  }
  [[nodiscard]] std::uint64_t sent() const { return sent_; }
  [[nodiscard]] std::uint64_t failed() const { return failed_; }

 private:
  mavlink::Transport& transport_;
  mavlink::Encoder encoder_;
  std::array<std::uint8_t, mavlink::kMaxFrameSize> buffer_{};
  std::uint64_t sent_ = 0;
  std::uint64_t failed_ = 0;
};

/// Renders and publishes frames on a thread of its own, so a render (4 ms at 320x240, 20-40 ms at
/// 640x480 on a shared core) does not stall the 500 Hz IMU and MAVLink loop: the flight
/// controller keeps its cadence, and a frame falling due while the previous one still renders is
/// skipped, as a camera driver drops frames, instead of slowing the simulation.
class RenderWorker {
 public:
  RenderWorker(const SimConfig& config, const World& world,
               frame_channel::FrameChannelWriter& channel)
      // The seed the Simulator gives its own renderer, so frames match a lock-step run's.
      : renderer_(config.camera, world, config.seed * 3u + 3u),
        channel_(channel),
        thread_([this] { loop(); }) {}
  ~RenderWorker() { finish(); }
  /// Renders a frame still pending, then ends the thread.
  void finish() {
    if (!thread_.joinable()) return;
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_one();
    thread_.join();
  }
  RenderWorker(const RenderWorker&) = delete;
  RenderWorker& operator=(const RenderWorker&) = delete;

  /// Hands over the due frame; false (skipped) while the previous one is still rendering.
  /// sim_t_ns: the simulated time the frame shows (where the people are); t_ns: its stamp.
  bool submit(const Eigen::Isometry3d& T_N_C, std::uint64_t frame_index, std::int64_t sim_t_ns,
              std::int64_t t_ns, const frame_channel::SitlTruth& truth) {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (pending_ || busy_) return false;
      job_.T_N_C = T_N_C;
      job_.frame_index = frame_index;
      job_.sim_t_ns = sim_t_ns;
      job_.t_ns = t_ns;
      job_.truth = truth;
      pending_ = true;
    }
    wake_.notify_one();
    return true;
  }
  /// Valid after finish().
  [[nodiscard]] std::int64_t published() const { return published_; }
  [[nodiscard]] double render_s() const { return render_s_; }

 private:
  struct Job {
    Eigen::Isometry3d T_N_C = Eigen::Isometry3d::Identity();
    std::uint64_t frame_index = 0;
    std::int64_t sim_t_ns = 0;
    std::int64_t t_ns = 0;
    frame_channel::SitlTruth truth;
  };

  void loop() {
    Job job;
    for (;;) {
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [this] { return pending_ || stop_; });
        if (!pending_) return;
        job = job_;
        pending_ = false;
        busy_ = true;
      }
      const std::int64_t start_ns = monotonic_now_ns();
      renderer_.render(job.T_N_C, static_cast<double>(job.sim_t_ns) * 1e-9, job.frame_index, image_,
                       depth_m_);
      render_s_ += static_cast<double>(monotonic_now_ns() - start_ns) * 1e-9;
      if (channel_.publish(job.t_ns, image_, depth_m_, &job.truth)) ++published_;
      const std::lock_guard<std::mutex> lock(mutex_);
      busy_ = false;
    }
  }

  RgbdRenderer renderer_;
  frame_channel::FrameChannelWriter& channel_;
  cv::Mat image_, depth_m_;
  std::mutex mutex_;
  std::condition_variable wake_;
  Job job_;
  bool pending_ = false;
  bool busy_ = false;
  bool stop_ = false;
  std::int64_t published_ = 0;
  double render_s_ = 0.0;
  std::thread thread_;  // last: starts once everything above is constructed
};

/// What one run counts, for the closing summary.
struct SitlRunStats {
  std::int64_t max_lag_ns = 0;
  std::int64_t collision_ticks = 0;
  std::int64_t frames_skipped = 0;
  double min_clearance_m = 1e9;
  double max_speed_mps = 0.0;
  std::uint64_t messages_received = 0;
};

frame_channel::ChannelGeometry channel_geometry(const SimConfig& config) {
  const geometry::PinholeCamera& pinhole = config.camera.pinhole;
  frame_channel::ChannelGeometry geometry;
  geometry.width = pinhole.width;
  geometry.height = pinhole.height;
  geometry.channels = config.camera.gray ? 1 : 3;
  geometry.fx = pinhole.fx;
  geometry.fy = pinhole.fy;
  geometry.cx = pinhole.cx;
  geometry.cy = pinhole.cy;
  return geometry;
}

void print_banner(const Simulator& sim, const frame_channel::FrameChannelWriter& channel,
                  const mavlink::Transport& transport, const SitlAutopilot& autopilot) {
  const SimConfig& config = sim.config();
  const geometry::PinholeCamera& pinhole = config.camera.pinhole;
  hq::log::info(
      "hq-sim --sitl: {}, seed {}, {}x{} {}-D at {:.0f} Hz on {}; MAVLink {} (system 1, "
      "component 1, PX4); max thrust {:.2f} N (4 x {:.3g} x {:.0f}^2), hover {:.2f} N\n",
      sim.world().name.c_str(), static_cast<unsigned long long>(config.seed), pinhole.width,
      pinhole.height, config.camera.gray ? "gray" : "BGR", config.camera.rate_hz,
      channel.name().c_str(), transport.describe().c_str(), autopilot.max_thrust_n(),
      config.vehicle.thrust_coefficient, config.vehicle.max_rotor_speed_radps,
      config.vehicle.mass_kg * 9.81);
  std::fflush(stdout);
}

/// Hands every datagram waiting on the transport to the autopilot.
void receive_mavlink(mavlink::Transport& transport, mavlink::Parser& parser,
                     SitlAutopilot& autopilot, std::int64_t t_ns, const TruthState& truth,
                     MessageSink& sink, std::span<std::uint8_t> rx, SitlRunStats& stats) {
  for (std::size_t n = transport.receive(rx); n > 0; n = transport.receive(rx)) {
    parser.feed(std::span<const std::uint8_t>(rx.data(), n), [&](const mavlink::FrameHeader& header,
                                                                 const mavlink::Message& message) {
      ++stats.messages_received;
      autopilot.on_message(t_ns, header.system_id, header.component_id, message, truth, sink);
    });
    if (transport.datagrams()) parser.end_of_datagram();
  }
}

/// Submits the due camera frame, stamped with the host clock of its exposure (wall origin +
/// simulated time), with the truth the onboard side is scored against.
void publish_camera(Simulator& sim, RenderWorker& renderer, std::int64_t wall_origin_ns,
                    SitlRunStats& stats) {
  const TruthState& truth = sim.truth();
  frame_channel::SitlTruth frame_truth;
  const Eigen::Vector3d& v_H = truth.v_H_mps;
  const Eigen::Vector3d& p_N = truth.T_N_B.translation();
  frame_truth.v_H_mps = {v_H.x(), v_H.y(), v_H.z()};
  frame_truth.p_W_m = {p_N.x(), p_N.y(), p_N.z()};
  frame_truth.on_ground = truth.on_ground;
  if (!renderer.submit(sim.camera_T_N_C(), sim.camera_frame_index(), sim.camera_t_ns(),
                       wall_origin_ns + sim.camera_t_ns(), frame_truth)) {
    ++stats.frames_skipped;
  }
  sim.hand_off_camera();
}

void account_truth(const TruthState& truth, SitlRunStats& stats) {
  if (!truth.on_ground) {
    if (truth.collision) ++stats.collision_ticks;
    stats.min_clearance_m = std::min(stats.min_clearance_m, truth.clearance_m);
  }
  stats.max_speed_mps = std::max(stats.max_speed_mps, truth.v_N_mps.norm());
}

void print_summary(const Simulator& sim, const SitlAutopilot& autopilot,
                   const mavlink::Parser& parser, const TransportSink& sink,
                   const RenderWorker& renderer, const SitlRunStats& stats, double wall_s) {
  const std::int64_t frames = renderer.published();
  const double render_s = renderer.render_s();
  const double sim_s = static_cast<double>(sim.t_ns()) * 1e-9;
  const mavlink::ParserCounters& pc = parser.counters();
  const SitlAutopilotStats& st = autopilot.stats();
  hq::log::info(
      "simulated {:.2f} s in {:.2f} s wall: real-time factor {:.3f}, largest lag {:.1f} ms\n",
      sim_s, wall_s, wall_s > 0.0 ? sim_s / wall_s : 0.0,
      static_cast<double>(stats.max_lag_ns) * 1e-6);
  hq::log::info("frames published {} (render {:.1f} ms mean), skipped while rendering {}\n",
                static_cast<long long>(frames),
                frames > 0 ? 1e3 * render_s / static_cast<double>(frames) : 0.0,
                static_cast<long long>(stats.frames_skipped));
  char clearance[32] = "n/a (never airborne)";
  if (stats.min_clearance_m < 1e8) {
    hq::format_into(clearance, "{:.2f} m", stats.min_clearance_m);
  }
  hq::log::info("collision ticks airborne {}, smallest clearance {}, max true speed {:.2f} m/s\n",
                static_cast<long long>(stats.collision_ticks), clearance, stats.max_speed_mps);
  hq::log::info("floor contacts {} (fastest {:.2f} m/s), falls (faster than {:.1f} m/s) {}\n",
                sim.floor_impacts(), sim.max_floor_impact_speed_mps(), kHardFloorImpactSpeedMps,
                sim.hard_floor_impacts());
  hq::log::info(
      "mavlink: sent {}, send failures {}, received {}, dropped {} (bad crc {}, "
      "unknown id {}, truncated {}, bad length {})\n",
      static_cast<unsigned long long>(sink.sent()), static_cast<unsigned long long>(sink.failed()),
      static_cast<unsigned long long>(stats.messages_received),
      static_cast<unsigned long long>(pc.dropped()), static_cast<unsigned long long>(pc.bad_crc),
      static_cast<unsigned long long>(pc.unknown_id), static_cast<unsigned long long>(pc.truncated),
      static_cast<unsigned long long>(pc.bad_length));
  hq::log::info(
      "setpoints received {} (rejected {}), commands {}, armed {:.2f} s, offboard {:.2f} s\n",
      static_cast<unsigned long long>(st.setpoints),
      static_cast<unsigned long long>(st.setpoints_rejected),
      static_cast<unsigned long long>(st.commands), static_cast<double>(st.armed_ns) * 1e-9,
      static_cast<double>(st.offboard_ns) * 1e-9);
  hq::log::info("GCS heartbeats {}, parameters sent {}, set {}, refused or unknown {}\n",
                static_cast<unsigned long long>(st.gcs_heartbeats),
                static_cast<unsigned long long>(st.params_sent),
                static_cast<unsigned long long>(st.params_set),
                static_cast<unsigned long long>(st.params_rejected));
  auto rmse = [](double sum, std::uint64_t n) {
    return n > 0 ? std::sqrt(sum / static_cast<double>(n)) : std::nan("");
  };
  auto u = [](std::uint64_t n) { return static_cast<unsigned long long>(n); };
  hq::log::info(
      "vision: ODOMETRY received {}, fused {}, resets {}, rejected: frame {}, "
      "estimator {}, nan {}, quality {}, gate {}, stamp {}; VISION_SPEED_ESTIMATE "
      "ignored {}; TIMESYNC answered {}\n",
      u(st.odometry_received), u(st.odometry_fused), u(st.odometry_resets), u(st.rejected_frame),
      u(st.rejected_estimator), u(st.rejected_nan), u(st.rejected_quality), u(st.rejected_gate),
      u(st.rejected_stamp), u(st.vision_speed_ignored), u(st.timesync_answered));
  hq::log::info(
      "velocity RMSE against truth (NED): received {:.3f} m/s ({}), fused with the IMU {:.3f} m/s "
      "({} IMU steps); LAND descended on vision {:.2f} s, on baro {:.2f} s\n",
      rmse(st.raw_sq_error_sum, st.raw_samples), u(st.raw_samples),
      rmse(st.fused_sq_error_sum, st.fused_samples), u(st.fused_samples),
      static_cast<double>(st.descent_on_vision_ns) * 1e-9,
      static_cast<double>(st.descent_on_baro_ns) * 1e-9);
  hq::log::info("final: {} {}, battery {:.2f} V, {} at altitude {:.2f} m\n",
                autopilot.armed() ? "armed" : "disarmed", sitl_mode_name(autopilot.mode()).data(),
                autopilot.battery_v(), sim.truth().on_ground ? "on the ground" : "in the air",
                sim.truth().T_N_B.translation().z());
  std::fflush(stdout);
}

}  // namespace

int run_sitl(Simulator& sim, const SitlOptions& options, const std::atomic<bool>& stop) {
  const SimConfig& config = sim.config();
  frame_channel::FrameChannelWriter channel(options.channel, channel_geometry(config));
  ensure_listen_port_free(options.mavlink_spec);
  const std::unique_ptr<mavlink::Transport> transport =
      mavlink::open_transport(options.mavlink_spec);
  if (options.tick_ns <= 0) {
    throw InputError("sitl: tick_ns = " + std::to_string(options.tick_ns) + ", expected > 0");
  }

  SitlAutopilot autopilot(config.vehicle, options.autopilot);
  TransportSink sink(*transport);
  mavlink::Parser parser;
  print_banner(sim, channel, *transport, autopilot);

  std::vector<ImuSample> imu(2000);
  std::array<std::uint8_t, 2048> rx{};
  auto renderer = std::make_unique<RenderWorker>(config, sim.world(), channel);
  const std::int64_t end_ns =
      options.duration_s > 0.0 ? static_cast<std::int64_t>(std::llround(options.duration_s * 1e9))
                               : -1;
  const std::int64_t wall_origin_ns = monotonic_now_ns();
  channel.set_time_origin(wall_origin_ns);  // frame stamps and IMU time_usec share it
  std::int64_t next_status_wall_ns = wall_origin_ns + 1'000'000'000;
  SitlRunStats stats;

  std::int64_t t_ns = sim.t_ns();
  while (!stop.load() && (end_ns < 0 || t_ns < end_ns)) {
    const std::int64_t t_next_ns = t_ns + options.tick_ns;
    // Absolute deadlines: the simulation never runs ahead of the wall clock, and a slow tick
    // (a render) is caught up instead of delaying every later one.
    const std::int64_t deadline_ns = wall_origin_ns + t_next_ns;
    const std::int64_t now_ns = monotonic_now_ns();
    if (now_ns < deadline_ns) {
      sleep_until_monotonic_ns(deadline_ns, &stop);
    } else {
      stats.max_lag_ns = std::max(stats.max_lag_ns, now_ns - deadline_ns);
    }

    const TruthState& truth = sim.truth();
    receive_mavlink(*transport, parser, autopilot, t_ns, truth, sink, rx, stats);
    sim.set_command(autopilot.update(t_ns, truth, sink));
    sim.step_to(t_next_ns);
    t_ns = sim.t_ns();

    const std::size_t n_imu = sim.take_imu(imu.data(), imu.size());
    for (std::size_t i = 0; i < n_imu; ++i) autopilot.on_imu(imu[i], sim.truth(), sink);
    if (sim.camera_due()) publish_camera(sim, *renderer, wall_origin_ns, stats);
    channel.heartbeat();

    const TruthState& after = sim.truth();
    account_truth(after, stats);
    const std::int64_t wall_ns = monotonic_now_ns();
    if (options.status_lines && wall_ns >= next_status_wall_ns) {
      next_status_wall_ns += 1'000'000'000;
      hq::log::note("hq-sim: t {:.1f} s, RT {:.2f}, {} {}, altitude {:.2f} m\n",
                    static_cast<double>(t_ns) * 1e-9,
                    static_cast<double>(t_ns) / static_cast<double>(wall_ns - wall_origin_ns),
                    autopilot.armed() ? "armed" : "disarmed",
                    sitl_mode_name(autopilot.mode()).data(), after.T_N_B.translation().z());
    }
  }

  const double wall_s = static_cast<double>(monotonic_now_ns() - wall_origin_ns) * 1e-9;
  renderer->finish();
  print_summary(sim, autopilot, parser, sink, *renderer, stats, wall_s);
  return 0;
}

}  // namespace hq::sitl
