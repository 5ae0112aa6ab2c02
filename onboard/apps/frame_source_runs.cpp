// hq-onboard on frame sources: a recorded sequence (--source replay) or a live camera
// (--source openni2|freenect), printing a live status line, a per-frame CSV and stage timings.
//
// Replay IMU: a sequence with accelerometer.txt and gyro.txt (the simulator writes both, body
// NED frame) is replayed as recorded, with --vehicle's extrinsics. TUM RGB-D has no gyro and the
// bundled fr1_360 has no accelerometer.txt, so there the IMU is SYNTHESISED from the ground
// truth at 200 Hz (gyro = body rate between consecutive ground-truth orientations + white noise;
// accelerometer = gravity and the finite-difference acceleration in the body frame). The camera
// is then the tracked sensor, so the body frame Q is the camera's NED-equivalent (Q x = optical
// z, Q y = optical x, Q z = optical y; Q_p_C = 0) and --vehicle contributes only mass and limits.

#include "onboard_runs.hpp"

#include "hq/base/error.hpp"
#include "hq/config/camera_info.hpp"
#include "hq/control/vehicle_config.hpp"
#include "hq/estimator/complementary_filter.hpp"
#include "hq/pipeline/replay_imu.hpp"
#include "hq/pipeline/stage_timing.hpp"
#include "hq/sources/camera_sources.hpp"
#include "hq/sources/tum_frame_source.hpp"

#include <csignal>
#include <cstdio>
#include <memory>
#include <string>
#include <unistd.h>

namespace hq::onboard_app {

namespace {

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

}  // namespace

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
  hq::pipeline::OnboardConfig config = hq::pipeline::load_onboard_config(o.config_path);
  config.modes.start_landed = false;  // a camera carried by hand, not a vehicle on the floor
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
  hq::pipeline::OnboardConfig config = hq::pipeline::load_onboard_config(config_path);
  config.modes.start_landed = false;  // a recording starts in motion, not resting on the floor
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

}  // namespace hq::onboard_app
