// hq-onboard: the on-board chain (odometry -> velocity estimator -> obstacle field -> modes ->
// velocity PID) on a frame source, printing a live status line and the per-stage timing.
//   hq-onboard --source replay <sequence-dir> --camera calib/tum_fr1.yaml
//              [--config config/onboard.yaml] [--vehicle calib/vehicle_core_paper.yaml]
//              [--csv out.csv]
//   hq-onboard --source sim --world onboard/sim/worlds/arena.yaml
//              --script onboard/closed_loop/flights/core_paper_box.yaml
//              [--sim-config onboard/sim/config/sim.yaml] [--resolution 320x240] [--seed N]
//              [--csv fig6-8.csv] [--save-map map.pcd|map.ply]
//   hq-onboard --source sim --world W --link [--duration-s 60] [--link-config config.yaml]
//              [--domain-id N] [--vehicle-id N] [--command-timeout-ms 200]
//              [--heartbeat-timeout-ms 2000] [--camera-rate-hz 10] [--link-log link.csv]
//
// Sim with --link: the closed loop is paced to wall time and flown by a ground station over DDS
// (hq-ground) instead of the script, through the on-board fail-safes (onboard/link_bridge):
// stale commands hold zero velocity, a silent ground lands the vehicle. --link-log writes one
// row per control step with the mode and the command and heartbeat ages.
//
// Sim: the simulator flies the chain in closed loop on simulated time, commanded by the
// scripted operator; the run ends with the flight summary (estimate and tracking RMSE per axis
// of H, closest distance, collisions) and the CSV holds the signals of the core paper's
// Fig. 6-8.
//
// Replay IMU: a sequence with accelerometer.txt and gyro.txt (the simulator writes both, body
// NED frame) is replayed as recorded, with --vehicle's extrinsics. TUM RGB-D has no gyro and the
// bundled fr1_360 has no accelerometer.txt, so there the IMU is SYNTHESISED from the ground
// truth at 200 Hz (gyro = body rate between consecutive ground-truth orientations + white noise;
// accelerometer = gravity and the finite-difference acceleration in the body frame). The camera
// is then the tracked sensor, so the body frame Q is the camera's NED-equivalent (Q x = optical
// z, Q y = optical x, Q z = optical y; Q_p_C = 0) and --vehicle contributes only mass and limits.
#include "hq/base/error.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/closed_loop/closed_loop.hpp"
#include "hq/closed_loop/flight_summary.hpp"
#include "hq/config/camera_info.hpp"
#include "hq/control/vehicle_config.hpp"
#include "hq/estimator/complementary_filter.hpp"
#include "hq/link/config.hpp"
#include "hq/link_bridge/link_bridge.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/pipeline/replay_imu.hpp"
#include "hq/pipeline/stage_timing.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/world.hpp"
#include "hq/sources/camera_sources.hpp"
#include "hq/sources/tum_frame_source.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <utility>
#include <unistd.h>

namespace {

class SteadyClock final : public hq::pipeline::Clock {
 public:
  std::int64_t now_ns() const override {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
};

void write_csv_header(std::FILE* csv) {
  std::fprintf(csv,
               "# hq-onboard per-step log. Frames: C camera optical (x right, y down, z forward);"
               " Q body NED; H horizontal NED (Q without roll and pitch, yaw kept). SI units as "
               "named; frame = 0 rows are camera-timeout steps between frames.\n");
  std::fprintf(csv,
               "t_s,frame,tracking,valid_ratio,estimate_ok,v_camera_raw_x_mps,v_camera_raw_y_mps,"
               "v_camera_raw_z_mps,v_camera_x_mps,v_camera_y_mps,v_camera_z_mps,v_body_x_mps,"
               "v_body_y_mps,v_body_z_mps,v_horizontal_x_mps,v_horizontal_y_mps,"
               "v_horizontal_z_mps,roll_est_rad,pitch_est_rad,obstacle_count,near_hazard,"
               "v_obs_horizontal_x_mps,v_obs_horizontal_y_mps,v_obs_horizontal_z_mps,mode,"
               "v_des_horizontal_x_mps,v_des_horizontal_y_mps,v_des_horizontal_z_mps,"
               "thrust_n,roll_cmd_rad,pitch_cmd_rad,yaw_rate_cmd_radps,safe_hover,total_ms,"
               "reason\n");
}

void write_csv_row(std::FILE* csv, const hq::pipeline::ChainOutput& out) {
  const auto& e = out.estimate;
  const auto& s = out.mode.control.setpoint;
  const auto v3 = [csv](const Eigen::Vector3d& v) {
    std::fprintf(csv, "%.6f,%.6f,%.6f,", v.x(), v.y(), v.z());
  };
  std::fprintf(csv, "%.6f,%d,%s,%.4f,%d,", 1e-9 * static_cast<double>(out.t_ns), out.frame ? 1 : 0,
               out.frame ? hq::odometry::to_string(out.tracking) : "none", out.valid_ratio,
               e.ok() ? 1 : 0);
  v3(e.v_camera_raw_mps);
  v3(e.v_camera_mps);
  v3(e.v_body_mps);
  v3(e.v_horizontal_mps);
  std::fprintf(csv, "%.6f,%.6f,%d,%d,", e.roll_rad, e.pitch_rad, out.obstacles.count,
               out.obstacles.near_hazard ? 1 : 0);
  v3(out.obstacles.v_obs_horizontal_mps);
  std::fprintf(csv, "%s,", hq::modes::to_string(out.mode.mode));
  v3(out.mode.v_des_horizontal_mps);
  std::fprintf(csv, "%.6f,%.6f,%.6f,%.6f,%d,%.3f,\"%s\"\n", s.thrust_n, s.roll_rad, s.pitch_rad,
               s.yaw_rate_radps, out.safe_hover ? 1 : 0,
               1e-6 * static_cast<double>(out.durations.total_ns),
               out.safe_hover ? out.safe_hover_reason : "");
}

void print_status(const hq::pipeline::ChainOutput& out, int frames) {
  const auto& v = out.estimate.v_horizontal_mps;
  const auto& s = out.mode.control.setpoint;
  // \033[K clears what a longer previous line left behind.
  std::fprintf(stderr,
               "\rt %8.3f s  frame %5d  %-5s  v_H [%+.2f %+.2f %+.2f] m/s  thrust %5.2f N  "
               "roll %+.3f pitch %+.3f rad  %5.2f ms  %s\033[K",
               1e-9 * static_cast<double>(out.t_ns), frames, out.estimate.ok() ? "ok" : "HOVER",
               v.x(), v.y(), v.z(), s.thrust_n, s.roll_rad, s.pitch_rad,
               1e-6 * static_cast<double>(out.durations.total_ns),
               out.safe_hover ? out.safe_hover_reason : "");
  std::fflush(stderr);
}

struct Options {
  std::string source_kind;
  std::string sequence_dir;
  std::string camera_path;
  std::string config_path = "config/onboard.yaml";
  std::string vehicle_path = "calib/vehicle_core_paper.yaml";
  std::string csv_path;
  std::string world_path;
  std::string script_path;
  std::string sim_config_path = "onboard/sim/config/sim.yaml";
  std::string resolution = "320x240";
  long long seed = -1;
  bool link = false;
  double duration_s = 60.0;
  std::string link_config_path;
  hq::link::LinkOverrides link_overrides;
  double command_timeout_ms = 200.0;
  double heartbeat_timeout_ms = 2000.0;
  double camera_rate_hz = 10.0;
  std::string link_log_path;
  std::string save_map_path;
};

std::atomic<bool> g_stop{false};

void request_stop(int /*signal*/) { g_stop = true; }

// The DDS link as the closed loop's operator: commands and mode requests through the fail-safes,
// vehicle state and camera frames back, one log row per control step.
class LinkOperator final : public hq::closed_loop::OperatorSource {
 public:
  LinkOperator(hq::link_bridge::LinkBridge& bridge, std::FILE* log) : bridge_(bridge), log_(log) {}
  /// The chain whose obstacle memory goes to the ground with the state (set once it exists).
  void set_chain(const hq::pipeline::OnboardChain* chain, const Eigen::Isometry3d& T_body_camera) {
    chain_ = chain;
    T_camera_body_ = T_body_camera.inverse();
  }

  hq::modes::OperatorCommand poll(std::int64_t t_ns,
                                  std::vector<hq::modes::Mode>& mode_requests) override {
    const hq::link_bridge::FailsafeState& state = bridge_.poll(t_ns, mode_requests);
    // Fail-safe transitions, at the control tick they happen (the log has a row per frame).
    if (state.hold_started) {
      std::printf("hq-onboard: t %.3f s: fail-safe hold, command age %.1f ms\n",
                  1e-9 * static_cast<double>(t_ns),
                  1e-6 * static_cast<double>(state.command_age_ns));
    }
    if (state.request_land) {
      std::printf("hq-onboard: t %.3f s: fail-safe land, heartbeat age %.1f ms\n",
                  1e-9 * static_cast<double>(t_ns),
                  1e-6 * static_cast<double>(state.heartbeat_age_ns));
    }
    return state.command;
  }
  void on_mode_result(std::int64_t t_ns, hq::modes::Mode mode,
                      const hq::modes::ModeSwitch& result) override {
    bridge_.acknowledge(t_ns, mode, result);
  }
  void on_output(const hq::pipeline::ChainOutput& out,
                 const hq::sim::TruthState& truth) override {
    hq::link_bridge::ObstacleCloudSource cloud;
    if (chain_ != nullptr && chain_->config().memory.enabled) {
      if (const auto T_world_camera = chain_->memory().T_world_camera()) {
        cloud.memory = &chain_->memory();
        cloud.T_world_body = *T_world_camera * T_camera_body_;
      }
    }
    bridge_.publish_state(out, cloud);
    if (log_ == nullptr) return;
    const hq::link_bridge::FailsafeState& f = bridge_.failsafe().state();
    const hq::link_bridge::FailsafeCounters& c = bridge_.failsafe().counters();
    const Eigen::Vector3d& v = f.command.v_horizontal_mps;
    std::fprintf(log_,
                 "%.4f,%s,%d,%d,%.2f,%.2f,%d,%d,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%d,%d,"
                 "%llu,%llu,%llu\n",
                 1e-9 * static_cast<double>(out.t_ns), hq::modes::to_string(out.mode.mode),
                 out.mode.landed ? 1 : 0, truth.on_ground ? 0 : 1,
                 f.command_age_ns < 0 ? -1.0 : 1e-6 * static_cast<double>(f.command_age_ns),
                 f.heartbeat_age_ns < 0 ? -1.0 : 1e-6 * static_cast<double>(f.heartbeat_age_ns),
                 f.hold ? 1 : 0, f.heartbeat_lost ? 1 : 0, v.x(), v.y(), v.z(),
                 f.command.yaw_rate_radps, truth.v_horizontal_mps.x(),
                 truth.v_horizontal_mps.y(), truth.v_horizontal_mps.z(),
                 truth.T_world_body.translation().z(), truth.collision ? 1 : 0,
                 out.estimate.ok() ? 1 : 0, static_cast<unsigned long long>(c.commands_accepted),
                 static_cast<unsigned long long>(c.commands_rejected),
                 static_cast<unsigned long long>(c.mode_requests_rejected));
  }
  void on_camera(std::int64_t t_ns, const cv::Mat& image) override {
    bridge_.publish_camera(t_ns, image);
  }

 private:
  hq::link_bridge::LinkBridge& bridge_;
  std::FILE* log_;
  const hq::pipeline::OnboardChain* chain_ = nullptr;
  Eigen::Isometry3d T_camera_body_ = Eigen::Isometry3d::Identity();
};

int run_sim_link(const Options& o) {
  if (o.world_path.empty()) throw hq::InputError("--source sim --link needs --world <world.yaml>");
  const hq::sim::World world = hq::sim::load_world(o.world_path);
  hq::sim::SimConfig sim_config = hq::sim::load_sim_config(o.sim_config_path);
  hq::sim::set_resolution(sim_config, o.resolution, "--resolution");
  sim_config.seed = o.seed >= 0 ? static_cast<std::uint64_t>(o.seed) : world.seed;
  const hq::pipeline::OnboardConfig config = hq::pipeline::load_onboard_config(o.config_path);
  const hq::control::VehicleConfig vehicle = hq::control::load_vehicle_config(o.vehicle_path);
  hq::link::LinkConfig link = o.link_config_path.empty()
                                  ? hq::link::LinkConfig{}
                                  : hq::link::load_link_config(o.link_config_path);
  hq::link::apply_overrides(o.link_overrides, link);
  hq::link_bridge::FailsafeConfig failsafe;
  failsafe.vehicle_id = link.vehicle_id;
  failsafe.envelope = link.envelope;
  failsafe.command_timeout_ns = std::llround(o.command_timeout_ms * 1e6);
  failsafe.heartbeat_timeout_ns = std::llround(o.heartbeat_timeout_ms * 1e6);
  hq::link_bridge::BridgeOptions bridge_options;
  bridge_options.camera_rate_hz = o.camera_rate_hz;
  hq::link_bridge::LinkBridge bridge(link, failsafe, bridge_options);

  std::FILE* log = nullptr;
  if (!o.link_log_path.empty()) {
    log = std::fopen(o.link_log_path.c_str(), "w");
    if (!log) throw hq::InputError(o.link_log_path + ": cannot open for writing");
    // Line-buffered: a row per frame is cheap, and tests follow the flight while it happens.
    std::setvbuf(log, nullptr, _IOLBF, 0);
    std::fprintf(log,
                 "t_s,mode,landed,airborne,command_age_ms,heartbeat_age_ms,hold,heartbeat_lost,"
                 "v_cmd_x_mps,v_cmd_y_mps,v_cmd_z_mps,yaw_rate_cmd_radps,v_true_x_mps,"
                 "v_true_y_mps,v_true_z_mps,altitude_m,collision,estimate_ok,commands_accepted,"
                 "commands_rejected,mode_requests_rejected\n");
  }
  LinkOperator source(bridge, log);
  hq::closed_loop::OperatorScript script;
  script.end_s = o.duration_s;
  hq::closed_loop::ClosedLoopOptions options;
  options.operator_source = &source;
  options.realtime = true;
  hq::closed_loop::ClosedLoop loop(
      sim_config, world, config, vehicle,
      hq::closed_loop::OperatorPlayer(script, hq::closed_loop::camera_heading_rad(vehicle.R_body_camera)),
      options);
  // The vehicle's own extrinsics (not the simulator's truth) place the cloud in the body.
  Eigen::Isometry3d T_body_camera = Eigen::Isometry3d::Identity();
  T_body_camera.linear() = vehicle.R_body_camera;
  T_body_camera.translation() = vehicle.p_body_camera_m;
  source.set_chain(&loop.chain(), T_body_camera);
  std::signal(SIGINT, request_stop);
  std::signal(SIGTERM, request_stop);
  std::fprintf(stderr,
               "hq-onboard: simulated %s over the link: domain %d, vehicle %u, %.1f s, command "
               "timeout %.0f ms, heartbeat timeout %.0f ms\n",
               world.name.c_str(), link.domain_id, link.vehicle_id, o.duration_s,
               o.command_timeout_ms, o.heartbeat_timeout_ms);
  double t_s = 0.0;
  while (t_s < o.duration_s && !g_stop) {
    t_s = std::min(o.duration_s, t_s + 0.1);
    loop.run_until(t_s);
  }
  if (log && std::fclose(log) != 0) throw hq::InputError(o.link_log_path + ": write failed");

  const hq::closed_loop::FlightSummary summary = hq::closed_loop::summarise(loop);
  hq::closed_loop::print_summary(stdout, "flight summary over the link (" + world.name + ")",
                                 summary);
  const hq::link_bridge::FailsafeCounters& c = bridge.failsafe().counters();
  const bool landed = !loop.samples().empty() && loop.samples().back().landed;
  const bool on_ground = loop.simulator().truth().on_ground;
  std::printf("  %-40s %llu accepted, %llu rejected\n", "velocity commands",
              static_cast<unsigned long long>(c.commands_accepted),
              static_cast<unsigned long long>(c.commands_rejected));
  std::printf("  %-40s %llu accepted, %llu rejected\n", "mode requests",
              static_cast<unsigned long long>(c.mode_requests_accepted),
              static_cast<unsigned long long>(c.mode_requests_rejected));
  std::printf("  %-40s %llu accepted, %llu rejected\n", "heartbeats",
              static_cast<unsigned long long>(c.heartbeats_accepted),
              static_cast<unsigned long long>(c.heartbeats_rejected));
  std::printf("  %-40s %llu holds, %llu land requests\n", "fail-safes",
              static_cast<unsigned long long>(c.holds),
              static_cast<unsigned long long>(c.land_requests));
  std::printf("  %-40s %llu states, %llu camera frames, %llu events\n", "published",
              static_cast<unsigned long long>(bridge.states_sent()),
              static_cast<unsigned long long>(bridge.camera_frames_sent()),
              static_cast<unsigned long long>(bridge.events_sent()));
  std::printf("  %-40s %.1f ms\n", "largest lag behind real time", 1e3 * loop.max_realtime_lag_s());
  std::printf("  %-40s %s (vehicle believes %s)\n", "final state", on_ground ? "on the ground" : "in the air",
              landed ? "landed, motors idle" : "flying");
  for (const std::string& refusal : loop.refusals()) {
    std::printf("  mode request refused at %s\n", refusal.c_str());
  }
  return summary.collision_ticks == 0 ? 0 : 3;
}

int run_sim(const Options& o) {
  if (o.world_path.empty() || o.script_path.empty()) {
    throw hq::InputError("--source sim needs --world <world.yaml> and --script <timeline.yaml>");
  }
  const hq::sim::World world = hq::sim::load_world(o.world_path);
  hq::sim::SimConfig sim_config = hq::sim::load_sim_config(o.sim_config_path);
  hq::sim::set_resolution(sim_config, o.resolution, "--resolution");
  sim_config.seed = o.seed >= 0 ? static_cast<std::uint64_t>(o.seed) : world.seed;
  const hq::pipeline::OnboardConfig config = hq::pipeline::load_onboard_config(o.config_path);
  const hq::control::VehicleConfig vehicle = hq::control::load_vehicle_config(o.vehicle_path);
  hq::closed_loop::OperatorPlayer player(hq::closed_loop::load_operator_script(o.script_path),
                                         hq::closed_loop::camera_heading_rad(vehicle.R_body_camera));
  const SteadyClock clock;
  hq::closed_loop::ClosedLoopOptions options;
  options.clock = &clock;
  hq::closed_loop::ClosedLoop loop(sim_config, world, config, vehicle, std::move(player), options);
  std::fprintf(stderr, "hq-onboard: simulated %s, %dx%d, seed %llu, script %s (%.1f s)\n",
               world.name.c_str(), sim_config.camera.pinhole.width,
               sim_config.camera.pinhole.height, static_cast<unsigned long long>(sim_config.seed),
               o.script_path.c_str(), loop.player().script().end_s);
  const auto wall_start = std::chrono::steady_clock::now();
  loop.run();
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();

  const hq::closed_loop::FlightSummary summary = hq::closed_loop::summarise(loop);
  hq::closed_loop::print_summary(stdout, "flight summary (" + world.name + ")", summary);
  std::printf("  %-40s %s\n", "obstacle memory (outside the view)",
              config.memory.enabled ? "on" : "off");
  std::printf("  %-40s %.1fx real time (%.1f s wall)\n", "simulation speed",
              summary.duration_s / std::max(wall_s, 1e-9), wall_s);
  for (const std::string& refusal : loop.refusals()) {
    std::printf("  mode request refused at %s\n", refusal.c_str());
  }
  std::printf("per-stage time from frame arrival to setpoint:\n");
  loop.timing().print(stdout);
  if (!o.save_map_path.empty()) {
    // Issue 10: the obstacle memory's map at the end of the flight (points in the world of the
    // odometry), for PCL's viewers and CloudCompare.
    loop.chain().memory().save(o.save_map_path);
    std::printf("obstacle memory map (%d points) written to %s\n", loop.chain().memory().size(),
                o.save_map_path.c_str());
  }
  if (!o.csv_path.empty()) {
    hq::closed_loop::write_figure_csv(o.csv_path, loop.samples());
    std::printf("Fig. 6-8 signals written to %s\n", o.csv_path.c_str());
  }
  return summary.collision_ticks == 0 ? 0 : 3;
}

// A live camera (OpenNI2, libfreenect) on a bench or hand-held: the chain runs with the camera as
// the body (camera-as-body extrinsics). Neither camera has a gyro, so the chain gets zero rate
// and, for tilt, the Kinect's accelerometer or else a level vehicle; eq. 2's camera velocity is
// exact, the velocity in H only as good as that tilt. A lost camera is the chain's own
// fail-safe path (camera timeout -> IMU coast -> safe hover) while the source reconnects.
int run_live(const Options& o) {
  hq::sources::CameraSourceOptions camera_options;
  camera_options.camera_file = o.camera_path;
  const std::unique_ptr<hq::sources::CameraSource> source =
      hq::sources::open_camera_source(o.source_kind, camera_options);
  const hq::pipeline::OnboardConfig config = hq::pipeline::load_onboard_config(o.config_path);
  hq::control::VehicleConfig vehicle = hq::control::load_vehicle_config(o.vehicle_path);
  vehicle.R_body_camera = hq::pipeline::R_body_camera_for_camera_as_body();
  vehicle.p_body_camera_m.setZero();
  std::fprintf(stderr,
               "hq-onboard: %s; camera-as-body, no gyro (zero rate), tilt from %s\n",
               source->describe().c_str(),
               o.source_kind.rfind("freenect", 0) == 0 ? "the Kinect's accelerometer"
                                                      : "a level-camera assumption");
  const SteadyClock clock;
  hq::pipeline::OnboardChain chain(config, vehicle, source->camera(), &clock);
  hq::pipeline::StageTimingLog timing;
  std::signal(SIGINT, request_stop);
  std::signal(SIGTERM, request_stop);
  const bool live = isatty(fileno(stderr)) != 0;
  const std::int64_t start_ns = clock.now_ns();
  const auto end_ns = start_ns + static_cast<std::int64_t>(o.duration_s * 1e9);
  hq::sources::RgbdFrame frame;
  std::int64_t frame_to_wall_ns = 0;  // device stamp minus wall time, from the first frame
  bool have_frame = false;
  int frames = 0;
  int lost_steps = 0;
  while (!g_stop && clock.now_ns() < end_ns) {
    const hq::sources::FrameStatus status = source->next(frame);
    if (status == hq::sources::FrameStatus::kEndOfStream) break;
    const std::int64_t wall_ns = clock.now_ns();
    if (status == hq::sources::FrameStatus::kNoFrame) {
      ++lost_steps;
      if (lost_steps % 20 == 1) {
        std::fprintf(stderr, "\nhq-onboard: camera: %s\n", source->error().c_str());
      }
      if (have_frame) {
        const std::int64_t t_ns = wall_ns + frame_to_wall_ns;
        chain.on_imu(t_ns, Eigen::Vector3d::Zero(),
                     Eigen::Vector3d(0.0, 0.0, -hq::estimator::kGravityMps2));
        if (const auto held = chain.on_tick(t_ns); held && live) print_status(*held, frames);
      }
      continue;
    }
    if (!have_frame) frame_to_wall_ns = frame.t_ns - wall_ns;
    have_frame = true;
    // The Kinect's accelerometer is in its optical axes; the body is the camera's NED twin.
    Eigen::Vector3d accel_body(0.0, 0.0, -hq::estimator::kGravityMps2);
    if (const auto accel = source->accelerometer()) {
      accel_body = hq::pipeline::R_body_camera_for_camera_as_body() * accel->accel_mps2;
    }
    chain.on_imu(frame.t_ns, Eigen::Vector3d::Zero(), accel_body);
    const hq::pipeline::ChainOutput out = chain.on_frame(frame.t_ns, frame.gray, frame.depth_m);
    if (++frames > 1) timing.add(out.durations);
    if (live) print_status(out, frames);
  }
  if (live) std::fprintf(stderr, "\n");
  std::printf("hq-onboard: %d frames from %s, %d polls without a frame\n", frames,
              source->describe().c_str(), lost_steps);
  std::printf("per-stage time from frame arrival to setpoint (first frame excluded):\n");
  timing.print(stdout);
  return 0;
}

int run_replay(const Options& o) {
  if (o.sequence_dir.empty() || o.camera_path.empty()) {
    throw hq::InputError("--source replay needs <sequence-dir> and --camera <camera.yaml>");
  }
  const std::string& config_path = o.config_path;
  const std::string& vehicle_path = o.vehicle_path;
  const std::string& csv_path = o.csv_path;
  const std::string& sequence_dir = o.sequence_dir;
  const std::string& camera_path = o.camera_path;
  const hq::pipeline::OnboardConfig config = hq::pipeline::load_onboard_config(config_path);
  hq::control::VehicleConfig vehicle = hq::control::load_vehicle_config(vehicle_path);
  hq::sources::TumFrameSource source(sequence_dir, hq::config::load_camera_info(camera_path));
  std::fprintf(stderr, "hq-onboard: %s\n", source.describe().c_str());
  const hq::pipeline::ReplayImu imu = hq::pipeline::load_replay_imu(
      source.sequence(), hq::pipeline::R_body_camera_for_camera_as_body());
  std::fprintf(stderr, "hq-onboard: %s\n", imu.description.c_str());
  if (imu.synthesised) {
    vehicle.R_body_camera = hq::pipeline::R_body_camera_for_camera_as_body();
    vehicle.p_body_camera_m.setZero();
    std::fprintf(stderr,
                 "hq-onboard: body frame = the camera's NED-equivalent (camera-as-body "
                 "extrinsics); %s supplies mass and limits only\n",
                 vehicle_path.c_str());
  }

  std::FILE* csv = nullptr;
  if (!csv_path.empty()) {
    csv = std::fopen(csv_path.c_str(), "w");
    if (!csv) throw hq::InputError(csv_path + ": cannot open for writing");
    write_csv_header(csv);
  }
  const bool live = isatty(fileno(stderr)) != 0;
  const SteadyClock clock;
  hq::pipeline::OnboardChain chain(config, vehicle, source.camera(), &clock);
  hq::pipeline::StageTimingLog timing(source.sequence().size());
  hq::sources::RgbdFrame frame;
  std::size_t next_imu = 0;
  int frames = 0;
  int ok = 0;
  int safe_hover = 0;
  int timeouts = 0;
  while (source.next(frame) == hq::sources::FrameStatus::kFrame) {
    while (next_imu < imu.samples.size() && imu.samples[next_imu].t_ns <= frame.t_ns) {
      const hq::pipeline::ImuMeasurement& m = imu.samples[next_imu++];
      chain.on_imu(m.t_ns, m.gyro_radps, m.accel_mps2);
      // Between frames the chain checks the camera timeout at IMU rate.
      if (frames > 0 && m.t_ns < frame.t_ns) {
        if (const auto held = chain.on_tick(m.t_ns)) {
          ++timeouts;
          if (csv) write_csv_row(csv, *held);
        }
      }
    }
    const hq::pipeline::ChainOutput out = chain.on_frame(frame.t_ns, frame.gray, frame.depth_m);
    ++frames;
    ok += out.estimate.ok() ? 1 : 0;
    safe_hover += out.safe_hover ? 1 : 0;
    if (frames > 1) timing.add(out.durations);  // the first frame sizes the buffers
    if (csv) write_csv_row(csv, out);
    if (live) print_status(out, frames);
  }
  if (live) std::fprintf(stderr, "\n");
  if (csv && std::fclose(csv) != 0) throw hq::InputError(csv_path + ": write failed");
  std::printf(
      "hq-onboard: %d frames, %d estimates ok, %d safe-hover setpoints, %d camera-timeout "
      "steps%s%s\n",
      frames, ok, safe_hover, timeouts, csv ? ", log in " : "", csv_path.c_str());
  std::printf("per-stage time from frame arrival to setpoint (first frame excluded):\n");
  timing.print(stdout);
  return 0;
}

int run(int argc, char** argv) {
  CLI::App app{"hq-onboard: the on-board velocity chain of the core paper on a frame source"};
  Options o;
  std::string kinds = "replay (a TUM-layout sequence) | sim (closed loop in simulation)";
  for (const std::string& camera : hq::sources::available_camera_sources()) {
    kinds += " | " + camera + (camera == "openni2" ? "[:uri] (Xtion, .oni)" : "[:index] (Kinect v1)");
  }
  app.add_option("--source", o.source_kind, "frame source: " + kinds)->required();
  app.add_option("sequence-dir", o.sequence_dir, "sequence folder for --source replay");
  app.add_option("--camera", o.camera_path, "replay: camera file, e.g. calib/tum_fr1.yaml; cameras: intrinsics instead of the device's");
  app.add_option("--config", o.config_path, "on-board config");
  app.add_option("--vehicle", o.vehicle_path, "vehicle file (mass, limits, T_body_camera)");
  app.add_option("--csv", o.csv_path,
                 "replay: per-frame estimates and setpoints; sim: the Fig. 6-8 signals");
  app.add_option("--world", o.world_path, "sim: world file (onboard/sim/worlds/*.yaml)");
  app.add_option("--script", o.script_path,
                 "sim: operator timeline (onboard/closed_loop/flights/*.yaml)");
  app.add_option("--sim-config", o.sim_config_path, "sim: simulator config");
  app.add_option("--resolution", o.resolution, "sim: camera WIDTHxHEIGHT (320x240, 640x480)");
  app.add_option("--seed", o.seed, "sim: noise and gust seed (default: the world's)")
      ->check(CLI::Range(0LL, 2147483647LL));
  app.add_flag("--link", o.link,
               "sim: fly commanded by a ground station over DDS, paced to real time");
  app.add_option("--duration-s", o.duration_s, "sim --link and cameras: run length")
      ->check(CLI::Range(0.1, 86400.0));
  app.add_option("--link-config", o.link_config_path, "sim --link: YAML with a link: section");
  hq::link::add_link_options(app, o.link_overrides);
  app.add_option("--command-timeout-ms", o.command_timeout_ms,
                 "sim --link: no fresh command this long -> hold zero velocity")
      ->check(CLI::Range(1.0, 10000.0));
  app.add_option("--heartbeat-timeout-ms", o.heartbeat_timeout_ms,
                 "sim --link: no ground heartbeat this long -> land")
      ->check(CLI::Range(1.0, 60000.0));
  app.add_option("--camera-rate-hz", o.camera_rate_hz,
                 "sim --link: JPEG frames to the ground (0: none)")
      ->check(CLI::Range(0.0, 60.0));
  app.add_option("--save-map", o.save_map_path,
                 "sim: the obstacle memory's map at the end of the flight (.pcd or .ply)")
      ->check([](const std::string& path) -> std::string {
        const auto ends = [&](const char* ext) {
          return path.size() > 4 && path.compare(path.size() - 4, 4, ext) == 0;
        };
        return ends(".pcd") || ends(".ply") ? "" : path + ": expected a .pcd or .ply file";
      });
  app.add_option("--link-log", o.link_log_path,
                 "sim --link: per-step CSV of mode, command and heartbeat ages, truth");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (o.source_kind == "sim" && o.link) return run_sim_link(o);
  if (o.source_kind == "sim") return run_sim(o);
  if (o.source_kind == "replay") return run_replay(o);
  // Anything else must be a camera this build has; parse_camera_spec says what is wrong.
  (void)hq::sources::parse_camera_spec(o.source_kind);
  return run_live(o);
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-onboard", argc, argv, run); }
