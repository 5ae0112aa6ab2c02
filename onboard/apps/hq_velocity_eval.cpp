// hq-velocity-eval: accuracy of the camera velocity of eq. 1 (raw odometry poses) and eq. 2
// (1€-filtered poses) of the core paper on a recorded sequence, and the lag the filter adds.
//   hq-velocity-eval <sequence-dir> --camera calib/tum_fr1.yaml [--config config/onboard.yaml]
//                    [--vehicle calib/vehicle_core_paper.yaml] [--max-lag-ms 200]
//                    [--accelerometer recorded|model]
// Truth: central difference of the ground-truth positions over +-1 frame interval (the median
// frame spacing), ground truth interpolated to the frame stamps, in the camera frame at the
// frame's time; the floor its own noise sets is printed beside. Sequences without
// gyro.txt/accelerometer.txt (TUM) get the IMU a named MEMS IMU on the camera would have given,
// from a B-spline fit of the ground truth, with the Kinect's recorded accelerometer where there
// is one (see hq/replay/replay_imu.hpp).
#include "hq/base/error.hpp"
#include "hq/base/log.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/config/camera_info.hpp"
#include "hq/evaluation/trajectory_error.hpp"
#include "hq/replay/velocity_evaluation.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <optional>
#include <string>

namespace {

int run(int argc, char** argv) {
  CLI::App app{"hq-velocity-eval: eq. 1 and eq. 2 camera velocity against ground truth"};
  std::string sequence_dir;
  std::string camera_path;
  std::string config_path = "config/onboard.yaml";
  std::string vehicle_path = "calib/vehicle_core_paper.yaml";
  double max_lag_ms = 200.0;
  std::string accelerometer = "recorded";
  app.add_option("sequence-dir", sequence_dir, "TUM-layout sequence with groundtruth.txt")
      ->required();
  app.add_option("--camera", camera_path, "camera file, e.g. calib/tum_fr1.yaml")->required();
  app.add_option("--config", config_path, "on-board config");
  app.add_option("--vehicle", vehicle_path, "vehicle file (used with recorded IMU files)");
  app.add_option("--max-lag-ms", max_lag_ms, "lag search range 0..this")
      ->check(CLI::Range(0.0, 2000.0));
  app.add_option("--accelerometer", accelerometer,
                 "where a TUM sequence has accelerometer.txt: replay it (recorded) or use the "
                 "IMU model's (model)")
      ->check(CLI::IsMember({"recorded", "model"}));
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  hq::replay::ImuSynthesis synthesis;
  synthesis.recorded_accelerometer = accelerometer == "recorded";
  const hq::replay::SequenceReplay replay =
      hq::replay::replay_velocity(sequence_dir, hq::config::load_camera_info(camera_path),
                                  hq::pipeline::load_onboard_config(config_path),
                                  hq::load_vehicle_config(vehicle_path), synthesis);
  hq::log::info("{}\n", replay.imu.description.c_str());
  hq::replay::LagSearch lag;
  lag.max_lag_s = 1e-3 * max_lag_ms;
  const hq::replay::VelocityErrors e = hq::replay::evaluate_velocity(
      replay.samples, replay.ground_truth, replay.frame_interval_ns, lag);

  hq::log::info(
      "{}: {} frames, {} estimates ok, {} compared; truth = central difference over "
      "+-{:.1f} ms (1 frame), camera frame C\n",
      sequence_dir.c_str(), replay.frames, replay.ok_estimates, e.samples,
      1e3 * e.frame_interval_s);
  hq::log::info("velocity from the odometry on {} of {} frames ({:.1f} %), inertial coast on {}\n",
                replay.ok_estimates, replay.frames, 100.0 * replay.availability(),
                replay.inertial_estimates);
  hq::log::info(
      "mean innovation chi^2 of the frames used: {:.2f} (3 when the covariances are right)\n",
      replay.mean_innovation_chi2);
  for (const auto& [reason, count] : replay.unavailable_reasons) {
    hq::log::info("  {:5} frames: {}\n", count, reason.c_str());
  }
  // The truth's own noise: a central difference of two poses 2h apart.
  const hq::evaluation::PoseNoise noise = hq::evaluation::ground_truth_noise(replay.ground_truth);
  hq::log::info(
      "truth |v| RMS {:.4f} m/s; its floor from the ground truth's own noise ({:.3f} mm per pose, "
      "{} third differences): {:.4f} m/s\n",
      e.truth_rms_mps, 1e3 * noise.trans_m, noise.differences,
      noise.pair_trans_m() / (2.0 * e.frame_interval_s));
  hq::log::info("{:<22} {:>9} {:>9} {:>9} {:>9}\n", "RMSE (m/s)", "x", "y", "z", "|xyz|");
  hq::log::info("{:<22} {:9.4f} {:9.4f} {:9.4f} {:9.4f}\n", "eq. 1 raw", e.rmse_raw_mps.x(),
                e.rmse_raw_mps.y(), e.rmse_raw_mps.z(), e.raw_norm_mps());
  hq::log::info("{:<22} {:9.4f} {:9.4f} {:9.4f} {:9.4f}\n", "eq. 2 one-euro",
                e.rmse_filtered_mps.x(), e.rmse_filtered_mps.y(), e.rmse_filtered_mps.z(),
                e.filtered_norm_mps());
  hq::log::info("{:<22} {:9.4f} {:9.4f} {:9.4f} {:9.4f}\n", "flown (fused with IMU)",
                e.rmse_flown_mps.x(), e.rmse_flown_mps.y(), e.rmse_flown_mps.z(),
                e.flown_norm_mps());
  hq::log::info("{:<22} {:9.4f} {:9.4f} {:9.4f} {:9.4f}\n", "eq. 2 shifted by lag",
                e.rmse_filtered_at_lag_mps.x(), e.rmse_filtered_at_lag_mps.y(),
                e.rmse_filtered_at_lag_mps.z(), e.rmse_filtered_at_lag_mps.norm());
  hq::log::info(
      "lag minimising RMSE over 0..{:.0f} ms: eq. 2 {:.0f} ms, eq. 1 {:.0f} ms, flown {:.0f} ms; "
      "the "
      "1-euro filter adds {:.0f} ms\n",
      max_lag_ms, e.filtered_lag_ms, e.raw_lag_ms, e.flown_lag_ms,
      e.filtered_lag_ms - e.raw_lag_ms);
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-velocity-eval", argc, argv, run); }
