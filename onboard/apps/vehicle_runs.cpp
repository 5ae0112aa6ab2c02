// hq-onboard on a vehicle runtime: a recorded sequence (--source replay), a live camera
// (--source openni2|freenect) or hq-sim's SITL frame channel (--source sitl), each with a flight
// controller (--fc none | mavlink:<transport>) and, with --link, a ground station over DDS. One
// loop (hq::vehicle::VehicleRuntime) for all of them: the fail-safes are the same code.
//
// Replay IMU: a sequence with accelerometer.txt and gyro.txt (the simulator writes both, body
// NED frame) is replayed as recorded, with --vehicle's extrinsics. TUM RGB-D has no gyro and the
// bundled fr1_360 has no accelerometer.txt either, so there the IMU is SYNTHESISED from the ground
// truth at 200 Hz (gyro = body rate between consecutive ground-truth orientations + white noise;
// accelerometer = gravity and the finite-difference acceleration in the body frame). The camera
// is then the tracked sensor, so the body frame Q is the camera's NED-equivalent (Q x = optical
// z, Q y = optical x, Q z = optical y; Q_p_C = 0) and --vehicle contributes only mass and limits.
//
// A live camera without a flight controller has no gyro: the chain gets zero rate and, for
// tilt, the Kinect's accelerometer or else a level vehicle, with the camera as the body.

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/base/log.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/config/camera_info.hpp"
#include "hq/link/link.hpp"
#include "hq/link_bridge/link_operator_port.hpp"
#include "hq/pipeline/stage_timing.hpp"
#include "hq/replay/replay_imu.hpp"
#include "hq/sources/camera_sources.hpp"
#include "hq/sources/sitl_frame_source.hpp"
#include "hq/sources/threaded_frame_source.hpp"
#include "hq/sources/tum_frame_source.hpp"
#include "hq/vehicle/mavlink_flight_controller.hpp"
#include "hq/vehicle/vehicle_runtime.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include "onboard_runs.hpp"

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <fmt/format.h>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <unistd.h>
#include <utility>
#include <vector>

namespace hq::onboard_app {

namespace {

void write_csv_header(std::FILE* csv) {
  fmt::print(csv,
             "# hq-onboard per-step log. Frames (hq/geometry/frames.hpp): C camera optical (x "
             "right, y down, z forward); B body FRD; H horizontal (B without roll and pitch, yaw "
             "kept). SI units as named; frame = 0 rows are camera-timeout steps between "
             "frames.\n");
  fmt::print(csv,
             "t_s,frame,tracking,valid_ratio,estimate_ok,v_C_raw_x_mps,v_C_raw_y_mps,"
             "v_C_raw_z_mps,v_C_x_mps,v_C_y_mps,v_C_z_mps,v_B_x_mps,v_B_y_mps,v_B_z_mps,"
             "v_H_x_mps,v_H_y_mps,v_H_z_mps,roll_est_rad,pitch_est_rad,obstacle_count,"
             "near_hazard,v_obs_H_x_mps,v_obs_H_y_mps,v_obs_H_z_mps,mode,v_des_H_x_mps,"
             "v_des_H_y_mps,v_des_H_z_mps,thrust_n,roll_cmd_rad,pitch_cmd_rad,"
             "yaw_rate_cmd_radps,safe_hover,total_ms,reason\n");
}

void write_csv_row(std::FILE* csv, const hq::pipeline::ChainOutput& out) {
  const auto& e = out.estimate;
  const auto& s = out.mode.control.setpoint;
  const auto v3 = [csv](const Eigen::Vector3d& v) {
    fmt::print(csv, "{:.6f},{:.6f},{:.6f},", v.x(), v.y(), v.z());
  };
  fmt::print(csv, "{:.6f},{},{},{:.4f},{},", hq::to_seconds(out.t_ns), out.frame ? 1 : 0,
             out.frame ? hq::odometry::to_string(out.tracking) : "none", out.valid_ratio,
             e.ok() ? 1 : 0);
  v3(e.v_C_raw_mps);
  v3(e.v_C_mps);
  v3(e.v_B_mps);
  v3(e.v_H_mps);
  fmt::print(csv, "{:.6f},{:.6f},{},{},", e.roll_rad, e.pitch_rad, out.obstacles.count,
             out.obstacles.near_hazard ? 1 : 0);
  v3(out.obstacles.v_obs_H_mps);
  fmt::print(csv, "{},", hq::modes::to_string(out.mode.mode));
  v3(out.mode.v_des_H_mps);
  fmt::print(csv, "{:.6f},{:.6f},{:.6f},{:.6f},{},{:.3f},\"{}\"\n", s.thrust_n, s.roll_rad,
             s.pitch_rad, s.yaw_rate_radps, out.safe_hover ? 1 : 0,
             1e-6 * static_cast<double>(out.durations.total_ns),
             out.safe_hover ? out.safe_hover_reason : "");
}

/// The run's own operator-side duties around the link (or nobody): the CSV log, the live status
/// line, counts for the summary, and runtime events on stderr.
class RunPort final : public hq::vehicle::OperatorPort {
 public:
  RunPort(hq::vehicle::OperatorPort* link, std::FILE* csv, bool live)
      : link_(link), csv_(csv), live_(live) {}

  hq::modes::OperatorCommand poll(std::int64_t t_ns,
                                  std::vector<hq::pipeline::ModeRequest>& requests) override {
    return link_ != nullptr ? link_->poll(t_ns, requests) : hq::modes::OperatorCommand{};
  }
  void on_mode_result(std::int64_t t_ns, const hq::pipeline::ModeRequest& request,
                      const hq::modes::ModeSwitch& result) override {
    if (link_ != nullptr) link_->on_mode_result(t_ns, request, result);
  }
  void on_output(const hq::pipeline::ChainOutput& out,
                 const hq::vehicle::VehicleStatus& status) override {
    if (out.frame) {
      ++frames;
      ok += out.estimate.ok() ? 1 : 0;
      safe_hover += out.safe_hover ? 1 : 0;
      if (frames > 1) timing.add(out.durations);  // the first frame sizes the buffers
      if (live_) print_status(out, frames);
    } else {
      ++ticks;
    }
    // The clearance sent in the state (ClearanceFilter): the summary's closest distance is the
    // same figure the ground shows and hq-report finds.
    if (out.clearance_m >= 0.0 &&
        (closest_clearance_m < 0.0 || out.clearance_m < closest_clearance_m)) {
      closest_clearance_m = out.clearance_m;
    }
    if (csv_ != nullptr) write_csv_row(csv_, out);
    if (link_ != nullptr) link_->on_output(out, status);
  }
  void on_frame(const hq::sources::RgbdFrame& frame) override {
    if (link_ != nullptr) link_->on_frame(frame);
  }
  void on_event(std::int64_t t_ns, hq::vehicle::FcSeverity severity,
                std::string_view text) override {
    // The link port prints its own events; without it they go to stderr here.
    if (link_ != nullptr) {
      link_->on_event(t_ns, severity, text);
    } else {
      hq::log::note("{}hq-onboard: {}\n", live_ ? "\n" : "", text);
    }
    ++events;
  }

  double closest_clearance_m = -1.0;  ///< Smallest clearance sent; < 0: none seen.
  int frames = 0;
  int ok = 0;
  int safe_hover = 0;
  int ticks = 0;
  int events = 0;
  hq::pipeline::StageTimingLog timing;

 private:
  hq::vehicle::OperatorPort* link_;
  std::FILE* csv_;
  bool live_;
};

/// The truth a SITL frame carries (simulation only), for the ground's "vs truth" plots.
class SitlTruth final : public hq::vehicle::TruthSource {
 public:
  explicit SitlTruth(const hq::sources::SitlFrameSource& source) : source_(source) {}
  [[nodiscard]] std::optional<hq::vehicle::TruthSample> truth() const override {
    const auto t = source_.truth();
    if (!t) return std::nullopt;
    hq::vehicle::TruthSample s;
    s.v_H_mps = Eigen::Vector3d(t->v_H_mps[0], t->v_H_mps[1], t->v_H_mps[2]);
    s.p_W_m = Eigen::Vector3d(t->p_W_m[0], t->p_W_m[1], t->p_W_m[2]);
    s.on_ground = t->on_ground;
    return s;
  }

 private:
  const hq::sources::SitlFrameSource& source_;
};

/// hq-sim may still be starting: its frame channel is waited for, not failed on at once.
std::unique_ptr<hq::sources::SitlFrameSource> open_sitl(const std::string& channel, double wait_s) {
  const std::int64_t end_ns = hq::monotonic_now_ns() + static_cast<std::int64_t>(wait_s * 1e9);
  bool said = false;
  while (true) {
    try {
      return std::make_unique<hq::sources::SitlFrameSource>(channel);
    } catch (const hq::InputError& e) {
      if (hq::monotonic_now_ns() >= end_ns || g_stop) {
        throw hq::InputError(std::string(e.what()) + " (waited " + std::to_string(wait_s) +
                             " s for hq-sim --sitl)");
      }
      if (!said) hq::log::note("hq-onboard: waiting for hq-sim's frame channel: {}\n", e.what());
      said = true;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
}

}  // namespace

namespace {

/// --fc as given, or the default for the source; rejects combinations that cannot fly.
std::string flight_controller_spec(const Options& o) {
  const bool replay = o.source_kind == "replay";
  const bool sitl = o.source_kind == "sitl";
  if (replay && (o.sequence_dir.empty() || o.camera_path.empty())) {
    throw hq::InputError("--source replay needs <sequence-dir> and --camera <camera.yaml>");
  }
  std::string fc_spec = o.fc_spec;
  if (fc_spec.empty()) fc_spec = sitl ? "mavlink:udp:127.0.0.1:14560" : "none";
  if (fc_spec != "none" && fc_spec.rfind("mavlink:", 0) != 0) {
    throw hq::InputError("--fc " + fc_spec +
                         ": expected none or mavlink:udp:HOST:PORT | mavlink:serial:DEVICE:BAUD");
  }
  if (replay && fc_spec != "none") {
    throw hq::InputError("--source replay flies no vehicle: it takes --fc none, not --fc " +
                         fc_spec);
  }
  if (!o.gcs_spec.empty() && fc_spec == "none") {
    throw hq::InputError("--gcs " + o.gcs_spec +
                         ": a GCS is routed to a flight controller, and --fc is none");
  }
  if (sitl && fc_spec == "none") {
    throw hq::InputError(
        "--source sitl needs the simulator's flight controller: --fc mavlink:udp:HOST:PORT");
  }
  return fc_spec;
}

/// The frame source, with the kind-specific views the run needs (null when not that kind).
struct OpenedSource {
  std::unique_ptr<hq::sources::FrameSource> source;
  hq::sources::TumFrameSource* tum = nullptr;
  hq::sources::SitlFrameSource* sitl = nullptr;
};

OpenedSource open_source(const Options& o, const std::string& fc_spec,
                         hq::pipeline::OnboardConfig& config) {
  OpenedSource opened;
  if (o.source_kind == "replay") {
    auto t = std::make_unique<hq::sources::TumFrameSource>(
        o.sequence_dir, hq::config::load_camera_info(o.camera_path));
    opened.tum = t.get();
    opened.source = std::move(t);
    config.modes.start_landed = false;  // a recording starts in motion, not resting on the floor
  } else if (o.source_kind == "sitl") {
    auto s = open_sitl(o.sitl_channel, o.sitl_wait_s);
    opened.sitl = s.get();
    opened.source = std::move(s);
  } else {
    // Anything else must be a camera this build has; parse_camera_spec says what is wrong.
    (void)hq::sources::parse_camera_spec(o.source_kind);
    hq::sources::CameraSourceOptions camera_options;
    camera_options.camera_file = o.camera_path;
    opened.source = std::make_unique<hq::sources::ThreadedFrameSource>(
        hq::sources::open_camera_source(o.source_kind, camera_options));
    if (fc_spec == "none") config.modes.start_landed = false;  // carried by hand
  }
  hq::log::note("hq-onboard: {}\n", opened.source->describe().c_str());
  return opened;
}

/// The flight controller: the recording's (or synthesised) IMU on replay, none for a hand-held
/// camera, else MAVLink. The first two fly the camera as the body, so they set the vehicle's
/// extrinsics to the camera-as-body ones.
std::unique_ptr<hq::vehicle::FlightController> open_flight_controller(const Options& o,
                                                                      const std::string& fc_spec,
                                                                      const OpenedSource& opened,
                                                                      hq::VehicleConfig& vehicle) {
  std::unique_ptr<hq::vehicle::FlightController> fc;
  if (opened.tum != nullptr) {
    const hq::replay::ReplayImu imu =
        hq::replay::load_replay_imu(opened.tum->sequence(), hq::replay::R_B_C_for_camera_as_body());
    hq::log::note("hq-onboard: {}\n", imu.description.c_str());
    if (imu.synthesised) {
      vehicle.camera = hq::replay::camera_as_body_mount();
      hq::log::note(
          "hq-onboard: body frame = the camera's NED-equivalent (camera-as-body "
          "extrinsics); {} supplies mass and limits only\n",
          o.vehicle_path.c_str());
    }
    std::vector<hq::vehicle::FcImuSample> samples;
    samples.reserve(imu.samples.size());
    for (const hq::replay::ImuMeasurement& m : imu.samples) {
      samples.push_back({m.t_ns, m.gyro_radps, m.accel_mps2});
    }
    fc = std::make_unique<hq::vehicle::NoFlightController>(std::move(samples));
  } else if (fc_spec == "none") {
    auto none = std::make_unique<hq::vehicle::NoFlightController>();
    // A hand-held camera is the body; the Kinect's accelerometer is in its optical axes.
    vehicle.camera = hq::replay::camera_as_body_mount();
    none->set_tilt_source(opened.source.get(), hq::replay::R_B_C_for_camera_as_body());
    hq::log::note("hq-onboard: camera-as-body, no gyro (zero rate), tilt from {}\n",
                  o.source_kind.rfind("freenect", 0) == 0 ? "the Kinect's accelerometer"
                                                          : "a level-camera assumption");
    fc = std::move(none);
  } else {
    hq::vehicle::MavlinkFcConfig fc_config;
    fc_config.transport = fc_spec.substr(std::string("mavlink:").size());
    if (o.fc_max_thrust_n > 0.0) fc_config.max_thrust_n = o.fc_max_thrust_n;
    const auto velocity_message = hq::vehicle::parse_velocity_message(o.fc_velocity_message);
    if (!velocity_message) {
      throw hq::InputError("--fc-velocity-message " + o.fc_velocity_message +
                           ": expected odometry or vision_speed_estimate");
    }
    fc_config.velocity_message = *velocity_message;
    fc_config.gcs = o.gcs_spec;
    fc = std::make_unique<hq::vehicle::MavlinkFlightController>(fc_config);
  }
  hq::log::note("hq-onboard: flight controller: {}\n", fc->describe().c_str());
  return fc;
}

/// Paces a wall-time loop at one step a millisecond, with no burst of catch-up steps when late.
class WallStepper {
 public:
  explicit WallStepper(hq::vehicle::VehicleRuntime& runtime)
      : runtime_(runtime), next_ns_(hq::monotonic_now_ns()) {}
  void sleep() {
    next_ns_ += kLoopPeriodNs;
    const std::int64_t now_ns = hq::monotonic_now_ns();
    if (next_ns_ < now_ns) next_ns_ = now_ns;  // late: no burst of catch-up steps
    hq::sleep_until_monotonic_ns(next_ns_);
  }
  /// One step of the wind-down (the source may have ended: the chain is still ticked).
  std::int64_t operator()() {
    sleep();
    const std::int64_t t_ns = hq::monotonic_now_ns();
    runtime_.step(t_ns);
    return t_ns;
  }

 private:
  static constexpr std::int64_t kLoopPeriodNs = 1'000'000;
  hq::vehicle::VehicleRuntime& runtime_;
  std::int64_t next_ns_;
};

/// Recorded time, as fast as the chain goes (with --link: at the recording's own pace, so a
/// ground station sees it as it happened); the clock jumps to the first frame and over gaps.
void run_recorded_time(const Options& o, hq::vehicle::VehicleRuntime& runtime,
                       const RunPort& port) {
  std::int64_t t_ns = 0;
  std::int64_t wall_minus_recorded_ns = 0;
  bool paced = false;
  while (!g_stop && runtime.step(t_ns)) {
    const std::optional<std::int64_t> next = runtime.pending_frame_t_ns();
    t_ns += 5'000'000;
    if (next && *next > t_ns && (t_ns < *next - 1'000'000'000LL || port.frames == 0)) {
      t_ns = *next;
      paced = false;
    }
    if (o.link) {
      if (!paced) wall_minus_recorded_ns = hq::monotonic_now_ns() - t_ns;
      paced = true;
      hq::sleep_until_monotonic_ns(t_ns + wall_minus_recorded_ns);
    }
  }
}

/// Wall time: the loop wakes every millisecond (frames and FC input within 1 ms); a camera
/// blocks only its own thread. Returns why the run ended.
std::string run_wall_time(const Options& o, hq::vehicle::VehicleRuntime& runtime) {
  const std::int64_t start_ns = hq::monotonic_now_ns();
  const std::int64_t end_ns = o.duration_s > 0.0
                                  ? start_ns + static_cast<std::int64_t>(o.duration_s * 1e9)
                                  : std::numeric_limits<std::int64_t>::max();
  // In SITL the flight controller is the simulator: once it is gone for good there is no
  // vehicle left to fly, so the process stops (a real companion keeps waiting for its FC).
  const bool sitl = o.source_kind == "sitl";
  const double fc_lost_exit_s = o.fc_lost_exit_s >= 0.0 ? o.fc_lost_exit_s : (sitl ? 3.0 : 0.0);
  std::int64_t fc_lost_since_ns = -1;
  WallStepper stepper(runtime);
  char text[96];
  while (true) {
    if (g_stop) return signal_reason();
    if (!runtime.step(hq::monotonic_now_ns())) {
      return sitl ? "the simulator's frames ended" : "the camera's frames ended";
    }
    if (hq::monotonic_now_ns() >= end_ns) {
      hq::format_into(text, "run length {:g} s reached", o.duration_s);
      return text;
    }
    if (runtime.status().fc_lost) {
      if (fc_lost_since_ns < 0) fc_lost_since_ns = hq::monotonic_now_ns();
      if (fc_lost_exit_s > 0.0 && hq::monotonic_now_ns() - fc_lost_since_ns >
                                      static_cast<std::int64_t>(fc_lost_exit_s * 1e9)) {
        hq::log::info("hq-onboard: flight controller lost for {:.1f} s: stopping\n",
                      fc_lost_exit_s);
        hq::format_into(text, "flight controller lost for {:.1f} s", fc_lost_exit_s);
        return text;
      }
    } else {
      fc_lost_since_ns = -1;
    }
    stepper.sleep();
  }
}

/// The routing lines of the summary: frames each way, drops by reason, the GCS as heard.
void print_gcs_summary(const std::optional<hq::vehicle::GcsRouting>& gcs) {
  if (!gcs) return;
  const hq::mavlink::RouterCounters& r = gcs->router;
  const hq::mavlink::ParserCounters& p = gcs->gcs_parser;
  hq::log::info("  {:<40} {} ({}), system {}\n", "GCS", gcs->spec,
                gcs->peer.empty() ? "never heard" : "at " + gcs->peer,
                gcs->gcs_system < 0 ? std::string("never heard") : std::to_string(gcs->gcs_system));
  hq::log::info("  {:<40} FC -> GCS {}, GCS -> FC {}, companion -> GCS {}\n",
                "GCS frames forwarded", gcs->fc_to_gcs, gcs->gcs_to_fc, gcs->companion_to_gcs);
  hq::log::info(
      "  {:<40} no route {}, target on its own link {}, loop {}, malformed {}, GCS not heard "
      "yet or send failed {}, FC send failed {}\n",
      "GCS frames not forwarded", r.no_route, r.target_on_source, r.loop, r.malformed,
      gcs->gcs_send_failures, gcs->fc_send_failures);
  hq::log::info(
      "  {:<40} bad crc {}, truncated {}, bad length {}; unknown id {} (forwarded as "
      "broadcasts, CRC unchecked: {} in all)\n",
      "GCS frames dropped by the parser", p.bad_crc, p.truncated, p.bad_length, p.unknown_id,
      r.unchecked_broadcast);
}

void print_run_summary(const Options& o, const std::string& fc_spec, const RunPort& port,
                       const hq::sources::FrameSource& source,
                       const hq::vehicle::FlightController& fc,
                       const hq::vehicle::VehicleRuntime& runtime, bool csv) {
  const hq::vehicle::RuntimeCounters& rc = runtime.counters();
  const hq::vehicle::FcCounters fcc = fc.counters();
  hq::log::info(
      "hq-onboard: {} frames from {}, {} estimates ok, {} safe-hover setpoints, {} "
      "camera-timeout steps{}{}\n",
      port.frames, source.describe().c_str(), port.ok, port.safe_hover, port.ticks,
      csv ? ", log in " : "", o.csv_path.c_str());
  // A live camera does not wait for the chain: a frame the chain was too busy to take is
  // replaced by the next one, and said here.
  if (const auto* threaded = dynamic_cast<const hq::sources::ThreadedFrameSource*>(&source)) {
    hq::log::info("  {:<40} {} (a newer one arrived while the chain was busy)\n",
                  "camera frames skipped", threaded->skipped());
  }
  hq::log::info("  {:<40} {}\n", "flight controller", fc.describe().c_str());
  hq::log::info("  {:<40} {} sent ({} withheld before the first estimate)\n", "setpoints",
                rc.setpoints, rc.setpoints_withheld);
  if (fc_spec != "none") {
    hq::log::info("  {:<40} {} sent, {} received, {} dropped, {} send failures\n",
                  "MAVLink messages", fcc.messages_sent, fcc.messages_received, fcc.frames_dropped,
                  fcc.send_failures);
    if (const auto* mavlink = dynamic_cast<const hq::vehicle::MavlinkFlightController*>(&fc)) {
      print_gcs_summary(mavlink->gcs_routing());
    }
    hq::log::info("  {:<40} {} IMU samples, {} arm requests, FC {}\n", "flight controller input",
                  rc.imu_samples, rc.arm_requests,
                  runtime.status().fc_lost        ? "LOST"
                  : runtime.status().fc.connected ? "connected"
                                                  : "never heard");
    hq::log::info("  {:<40} {} sent, {} restarts (reset_counter)\n", "velocity to the FC",
                  fcc.velocity_reports_sent, rc.velocity_resets);
    if (fcc.clock_from_timesync) {
      hq::log::info(
          "  {:<40} TIMESYNC: offset {:.3f} ms, jitter {:.3f} ms, RTT {:.3f} ms "
          "({} answers, {} dropped)\n",
          "FC clock", 1e-6 * static_cast<double>(fcc.timesync_offset_ns),
          1e-6 * fcc.timesync_jitter_ns, 1e-6 * static_cast<double>(fcc.timesync_rtt_ns),
          fcc.timesync_samples, fcc.timesync_rejected);
    } else {
      hq::log::info("  {:<40} least-delayed packet (no TIMESYNC answers: {} taken, {} dropped)\n",
                    "FC clock", fcc.timesync_samples, fcc.timesync_rejected);
    }
  }
  if (const auto& last = runtime.last_output()) {
    const hq::control::HoverThrustEstimate& h = last->hover_thrust;
    hq::log::info(
        "  {:<40} gain {:.3f} +- {:.3f} ({}; {} fused, {} gated), hovers on {:.1f} N "
        "commanded",
        "hover thrust (learnt in flight)", h.gain, h.sigma,
        h.converged ? "converged" : "not converged", h.updates, h.rejected, last->hover_thrust_n);
    if (fc_spec != "none" && o.fc_max_thrust_n > 0.0) {
      hq::log::info(", {:.2f} of --fc-max-thrust-n", last->hover_thrust_n / o.fc_max_thrust_n);
    }
    hq::log::info("\n");
  }
  if (port.closest_clearance_m >= 0.0) {
    hq::log::info("  {:<40} {:.3f} m\n", "closest distance (clearance)", port.closest_clearance_m);
  } else {
    hq::log::info("  {:<40} none seen\n", "closest distance (clearance)");
  }
  hq::log::info("  {:<40} {}\n", "runtime events", port.events);
}

}  // namespace

int run_vehicle(const Options& o) {
  const std::string fc_spec = flight_controller_spec(o);
  hq::pipeline::OnboardConfig config = hq::pipeline::load_onboard_config(o.config_path);
  hq::VehicleConfig vehicle = hq::load_vehicle_config(o.vehicle_path);
  // --record: before the source and the link, so an unwritable folder stops the start.
  const std::unique_ptr<hq::onboard_log::OnboardRecorder> recorder = make_recorder(o, vehicle);
  const OpenedSource opened = open_source(o, fc_spec, config);
  if (recorder) recorder->set_camera(opened.source->camera());
  const std::unique_ptr<hq::vehicle::FlightController> fc =
      open_flight_controller(o, fc_spec, opened, vehicle);

  std::FILE* csv = nullptr;
  if (!o.csv_path.empty()) {
    csv = std::fopen(o.csv_path.c_str(), "w");
    if (!csv) throw hq::InputError(o.csv_path + ": cannot open for writing");
    write_csv_header(csv);
  }
  const bool live = isatty(fileno(stderr)) != 0;
  const SteadyClock clock;
  hq::pipeline::OnboardChain chain(config, vehicle, opened.source->camera(), &clock);

  // The operator link, when asked for.
  std::unique_ptr<hq::link_bridge::LinkBridge> bridge;
  std::unique_ptr<hq::link_bridge::LinkOperatorPort> link_port;
  if (o.link) {
    bridge = make_link_bridge(o);
    if (bridge->ros2() != nullptr) {
      bridge->ros2()->set_camera(opened.source->camera());
      bridge->ros2()->set_camera_mount(vehicle.camera);
      // The record's ROS 2 bag stamped as the bridge publishes.
      if (recorder) recorder->set_ros_clock(bridge->ros2()->clock());
    }
    link_port = std::make_unique<hq::link_bridge::LinkOperatorPort>(*bridge, chain,
                                                                    vehicle.camera.T_B_C(), stdout);
  }
  RunPort port(link_port.get(), csv, live);
  std::unique_ptr<SitlTruth> truth;
  if (opened.sitl != nullptr) truth = std::make_unique<SitlTruth>(*opened.sitl);
  // --record: the recorder behind the port (chain outputs) and the FC (IMU samples).
  std::optional<hq::onboard_log::RecordingPort> record_port;
  std::optional<hq::onboard_log::RecordingFlightController> record_fc;
  if (recorder) {
    record_port.emplace(&port, *recorder);
    record_fc.emplace(*fc, *recorder);
  }
  hq::vehicle::VehicleRuntime runtime(
      chain, *opened.source,
      record_fc ? static_cast<hq::vehicle::FlightController&>(*record_fc) : *fc,
      record_port ? static_cast<hq::vehicle::OperatorPort*>(&*record_port) : &port, truth.get());

  std::signal(SIGINT, request_stop);
  std::signal(SIGTERM, request_stop);
  // Every way the run ends lands or holds (a live vehicle), then says goodbye on the link, so
  // the operator reads why instead of a link loss: the run length, a signal, the FC or camera
  // lost, or an error thrown from the loop.
  StopOutcome stop;
  try {
    if (opened.tum != nullptr) {
      run_recorded_time(o, runtime, port);
      stop = {g_stop ? signal_reason() : "the recording ended", "replay, nothing flown"};
    } else {
      stop.reason = run_wall_time(o, runtime);
      wind_down(o, runtime, hq::monotonic_now_ns(), WallStepper(runtime), stop);
    }
  } catch (const std::exception& e) {
    if (bridge) {
      say_goodbye(*bridge, hq::monotonic_now_ns(),
                  {std::string("fatal error: ") + e.what(), "not landed by hq-onboard"});
    }
    throw;
  }
  if (bridge) say_goodbye(*bridge, hq::monotonic_now_ns(), stop);
  if (live) hq::log::note("\n");
  if (csv && std::fclose(csv) != 0) throw hq::InputError(o.csv_path + ": write failed");

  print_run_summary(o, fc_spec, port, *opened.source, *fc, runtime, csv != nullptr);
  if (bridge) print_link_summary(*bridge);
  hq::log::info("per-stage time from frame arrival to setpoint (first frame excluded):\n");
  port.timing.print(stdout);
  bool record_ok = true;
  if (recorder) {
    const hq::vehicle::RuntimeCounters& rc = runtime.counters();
    record_ok =
        close_recorder(*recorder,
                       {{"source", opened.source->describe()},
                        {"frames", std::to_string(port.frames)},
                        {"camera_timeout_steps", std::to_string(port.ticks)},
                        {"estimates_ok", std::to_string(port.ok)},
                        {"frames_out_of_order_dropped", std::to_string(rc.frames_out_of_order)},
                        {"imu_overflow_dropped", std::to_string(rc.imu_overflow)},
                        {"setpoints", std::to_string(rc.setpoints)}},
                       bridge.get());
  }
  // A vehicle that lost its flight controller did not end well: say so in the exit status.
  return with_record_status(runtime.status().fc_lost ? 4 : 0, record_ok);
}

}  // namespace hq::onboard_app
