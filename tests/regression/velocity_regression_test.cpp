// Camera velocity of eq. 1 (raw) and eq. 2 (1€-filtered) of the core paper against ground
// truth, through the whole OnboardChain with config/onboard.yaml:
//  - on the bundled real frames (TUM fr1_360: 5 frames 68 ms apart, IMU synthesised from the
//    ground truth). The estimator's 0.2 s warm-up leaves ONE frame to compare, so these bounds
//    only guard against gross regressions;
//  - on two 10 s simulated flights recorded at 320x240 with hq::sim's TumWriter (recorded
//    IMU): a hover, where noise dominates and the core paper's reason for the filter shows
//    (filtered RMSE < raw RMSE), and sinusoidal manoeuvres, where the filter's lag dominates.
// Each bound sits beside the figure measured when it was set (this test, same code and seed),
// with a margin of at most 25 %.
#include "hq/config/camera_info.hpp"
#include "hq/recording/data_dir.hpp"
#include "hq/replay/velocity_evaluation.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/tum_writer.hpp"
#include "hq/sim/world.hpp"
#include "hq/testing/input_error.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fmt/format.h>
#include <optional>
#include <string>
#include <unistd.h>

namespace {

using hq::replay::VelocityErrors;

void print(const char* name, const hq::replay::SequenceReplay& replay, const VelocityErrors& e) {
  fmt::print("{}: {} frames, {} ok, {} compared, h {:.1f} ms, truth RMS {:.4f} m/s\n", name,
             replay.frames, replay.ok_estimates, e.samples, 1e3 * e.frame_interval_s,
             e.truth_rms_mps);
  fmt::print("  RMSE eq. 1 raw      [{:.4f} {:.4f} {:.4f}] |{:.4f}| m/s\n", e.rmse_raw_mps.x(),
             e.rmse_raw_mps.y(), e.rmse_raw_mps.z(), e.raw_norm_mps());
  fmt::print("  RMSE eq. 2 filtered [{:.4f} {:.4f} {:.4f}] |{:.4f}| m/s\n", e.rmse_filtered_mps.x(),
             e.rmse_filtered_mps.y(), e.rmse_filtered_mps.z(), e.filtered_norm_mps());
  fmt::print("  RMSE flown (fused)  [{:.4f} {:.4f} {:.4f}] |{:.4f}| m/s\n", e.rmse_flown_mps.x(),
             e.rmse_flown_mps.y(), e.rmse_flown_mps.z(), e.flown_norm_mps());
  fmt::print("  lag eq. 2 {:.0f} ms, eq. 1 {:.0f} ms, flown {:.0f} ms\n", e.filtered_lag_ms,
             e.raw_lag_ms, e.flown_lag_ms);
}

// The first 150 frames of fr1/xyz (5 s, hand-held, motion capture), replayed with the
// Kinect's own accelerometer and a BMI088 gyro made from the ground truth (replay_imu.hpp), or
// with the BMI088's accelerometer too. Measured with the shipped config:
//   recorded accelerometer: 142 of 144 frames, flown |v| RMSE 0.0416 m/s, lag 0 ms, NIS 2.19;
//     eq. 2 (1-euro) 0.0930 m/s, lag 85 ms
//   BMI088 accelerometer:   142 of 144 frames, flown 0.0330 m/s (0.0271 on the whole 792)
// The two frames without a velocity are the first and the one a start waits for
// (estimator.reacquire_frames).
struct SliceFigures {
  hq::replay::SequenceReplay replay;
  VelocityErrors errors;
};

std::optional<SliceFigures> replay_fr1_xyz(bool recorded_accelerometer) {
  const auto data = hq::recording::find_data_dir();
  if (!data) return std::nullopt;
  const std::string dir = *data + "/tum/rgbd_dataset_freiburg1_xyz";
  if (!std::filesystem::exists(dir)) return std::nullopt;
  hq::replay::ImuSynthesis synthesis;
  synthesis.recorded_accelerometer = recorded_accelerometer;
  SliceFigures out;
  out.replay = hq::replay::replay_velocity(dir, hq::config::load_camera_info("calib/tum_fr1.yaml"),
                                           hq::pipeline::load_onboard_config("config/onboard.yaml"),
                                           hq::load_vehicle_config("calib/vehicle_core_paper.yaml"),
                                           synthesis);
  out.errors = hq::replay::evaluate_velocity(out.replay.samples, out.replay.ground_truth,
                                             out.replay.frame_interval_ns);
  print(recorded_accelerometer ? "fr1_xyz, Kinect accelerometer" : "fr1_xyz, BMI088", out.replay,
        out.errors);
  return out;
}

TEST(VelocityOnRecordedDepth, EveryGoodFrameGivesAPromptVelocityAheadOfTheOneEuro) {
  for (const bool recorded : {true, false}) {
    const auto run = replay_fr1_xyz(recorded);
    if (!run) GTEST_SKIP() << "no fr1_xyz: " << hq::recording::data_dir_search_description();
    const VelocityErrors& e = run->errors;
    EXPECT_TRUE(run->replay.imu.synthesised);
    // Available on every frame but the two a start needs.
    EXPECT_GE(run->replay.availability(), 0.98);
    // Prompt: no lag to speak of, where eq. 2's 1-euro filter lags tens of ms.
    EXPECT_LE(e.flown_lag_ms, 20.0);
    EXPECT_GT(e.filtered_lag_ms, 40.0);
    // And more accurate than eq. 2 and eq. 1, within the measured figure's margin.
    EXPECT_LT(e.flown_norm_mps(), recorded ? 0.050 : 0.040);
    EXPECT_LT(e.flown_norm_mps(), e.filtered_norm_mps());
    EXPECT_LT(e.flown_norm_mps(), e.raw_norm_mps());
    // The filter's covariances are honest: the mean NIS of 3 degrees of freedom is near 3.
    EXPECT_GT(run->replay.mean_innovation_chi2, 1.0);
    EXPECT_LT(run->replay.mean_innovation_chi2, 5.0);
  }
}

TEST(VelocityOnRecordedDepth, ASequenceTooShortForTheEstimatorSaysWhichValuesToLower) {
  const auto data = hq::recording::find_data_dir();
  if (!data) GTEST_SKIP() << "no real data: " << hq::recording::data_dir_search_description();
  const std::string dir = *data + "/tum/rgbd_dataset_freiburg1_360";
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << dir << " absent";
  // GIVEN fr1_360's 5 frames and a config that wants 5 agreeing frames after a start
  auto config = hq::pipeline::load_onboard_config("config/onboard.yaml");
  config.estimator.reacquire_frames = 5;
  const std::string message = hq::testing::input_error_message([&] {
    hq::replay::replay_velocity(dir, hq::config::load_camera_info("calib/tum_fr1.yaml"), config,
                                hq::load_vehicle_config("calib/vehicle_core_paper.yaml"));
  });
  // THEN the error names the sequence and the value, not an empty evaluation
  EXPECT_THAT(message, ::testing::HasSubstr("rgbd_dataset_freiburg1_360: none of its 5 frames"));
  EXPECT_THAT(message, ::testing::HasSubstr("estimator.reacquire_frames (5)"));
  // AND with the 1-euro output the warm-up is named too
  config.estimator.reacquire_frames = 2;
  config.estimator.velocity_output =
      hq::estimator::VelocityEstimatorConfig::VelocityOutput::kOneEuro;
  const std::string one_euro = hq::testing::input_error_message([&] {
    hq::replay::replay_velocity(dir, hq::config::load_camera_info("calib/tum_fr1.yaml"), config,
                                hq::load_vehicle_config("calib/vehicle_core_paper.yaml"));
  });
  EXPECT_THAT(one_euro, ::testing::HasSubstr("estimator.warmup_s (0.2 s)"));
}

/// Position hold plus a feed-forward velocity profile flown on truth, converted to the
/// attitude-thrust command with gravity compensation in H (core paper §3; NED body, NWU world).
class ScriptedFlight {
 public:
  /// @param manoeuvre  scales the velocity and yaw-rate profile: 0 hovers, 1 manoeuvres.
  ScriptedFlight(const Eigen::Vector3d& start_N_m, double manoeuvre)
      : start_m_(start_N_m), manoeuvre_(manoeuvre) {}

  hq::sim::AttitudeCommand command(const hq::sim::Simulator& sim, double t_s) const {
    constexpr double kG = 9.80665;
    if (t_s < kTakeoffS) return {};
    // After climbing, sinusoidal velocities of different periods on x and y: the camera sees
    // speeds up to 0.4 m/s changing direction, so both noise (eq. 1) and lag (eq. 2) show.
    const double tau = std::max(0.0, t_s - kManoeuvreS);
    const double k = manoeuvre_;
    const double wx = 2.0 * M_PI / 4.0;
    const double wy = 2.0 * M_PI / 3.0;
    const Eigen::Vector2d v_d(k * 0.4 * std::sin(wx * tau), k * 0.3 * std::sin(wy * tau));
    const Eigen::Vector2d a_ff(k * 0.4 * wx * std::cos(wx * tau),
                               k * 0.3 * wy * std::cos(wy * tau));
    const Eigen::Vector2d p_d =
        start_m_.head<2>() + k * Eigen::Vector2d(0.4 / wx * (1.0 - std::cos(wx * tau)),
                                                 0.3 / wy * (1.0 - std::cos(wy * tau)));
    const hq::sim::TruthState& truth = sim.truth();
    const Eigen::Vector3d p = truth.T_N_B.translation();
    const Eigen::Vector2d a_xy = (t_s >= kManoeuvreS ? a_ff : Eigen::Vector2d::Zero()) +
                                 1.0 * (p_d - p.head<2>()) + 2.0 * (v_d - truth.v_N_mps.head<2>());
    const double a_up = 3.0 * (kAltitudeM - p.z()) - 2.5 * truth.v_N_mps.z();
    // Body forward in NWU is (cos psi, -sin psi), right is (-sin psi, -cos psi).
    const double yaw = truth.euler_rad.z();
    const double a_forward = std::cos(yaw) * a_xy.x() - std::sin(yaw) * a_xy.y();
    const double a_right = -std::sin(yaw) * a_xy.x() - std::cos(yaw) * a_xy.y();
    const double pitch = std::clamp(-std::atan2(a_forward, kG + a_up), -0.3, 0.3);
    const double roll = std::clamp(std::atan2(a_right * std::cos(pitch), kG + a_up), -0.3, 0.3);
    const double yaw_rate = t_s >= kManoeuvreS ? k * 0.25 * std::sin(2.0 * M_PI / 5.0 * tau) : 0.0;
    return {sim.config().vehicle.mass_kg * (kG + a_up) / (std::cos(roll) * std::cos(pitch)), roll,
            pitch, yaw_rate};
  }

  static constexpr double kTakeoffS = 0.5;
  static constexpr double kManoeuvreS = 3.0;  // climbed and settled
  static constexpr double kAltitudeM = 1.0;

 private:
  Eigen::Vector3d start_m_;
  double manoeuvre_;
};

/// Records [kManoeuvreS, kManoeuvreS + duration_s] of the scripted flight in worlds/room.yaml.
void record_flight(const std::string& dir, double duration_s, double manoeuvre) {
  const hq::sim::World world = hq::sim::load_world("onboard/sim/worlds/room.yaml");
  hq::sim::SimConfig config = hq::sim::load_sim_config("onboard/sim/config/sim.yaml");
  const double hfov_rad =
      2.0 * std::atan(0.5 * config.camera.pinhole.width / config.camera.pinhole.fx);
  config.camera.pinhole = hq::sim::pinhole_from_fov(320, 240, hfov_rad);
  config.seed = 5;
  hq::sim::Simulator sim(config, world);
  hq::sim::TumWriter writer(dir, config.camera.pinhole, config.camera.T_B_C);
  const ScriptedFlight script(world.start_N_m, manoeuvre);
  constexpr std::int64_t kControlPeriodNs = 5'000'000;
  const auto start_ns = static_cast<std::int64_t>(ScriptedFlight::kManoeuvreS * 1e9);
  const auto end_ns = start_ns + static_cast<std::int64_t>(duration_s * 1e9);
  hq::sim::ImuSample imu[64];
  cv::Mat image, depth_m;
  for (std::int64_t t = 0; t <= end_ns; t += kControlPeriodNs) {
    sim.set_command(script.command(sim, 1e-9 * static_cast<double>(t)));
    sim.step_to(t);
    const std::size_t n = sim.take_imu(imu, 64);
    for (std::size_t i = 0; i < n && t >= start_ns; ++i) writer.write_imu(imu[i]);
    if (sim.camera_due()) {
      const std::int64_t t_frame_ns = sim.camera_t_ns();
      const Eigen::Isometry3d T_N_C = sim.camera_T_N_C();
      sim.render_camera(image, depth_m);
      if (t_frame_ns >= start_ns) writer.write_frame(t_frame_ns, image, depth_m, T_N_C);
    }
  }
  writer.close();
  ASSERT_FALSE(sim.collided());
}

struct SimulatedEvaluation {
  hq::replay::SequenceReplay replay;
  VelocityErrors errors;
};

/// Records 10 s of the scripted flight to a temporary folder and replays it through the chain.
SimulatedEvaluation fly_and_evaluate(const char* name, double manoeuvre) {
  const std::string dir = (std::filesystem::temp_directory_path() /
                           ("hq_velocity_regression_" + std::to_string(::getpid()) + "_" + name))
                              .string();
  std::filesystem::remove_all(dir);
  record_flight(dir, 10.0, manoeuvre);
  SimulatedEvaluation out;
  out.replay =
      hq::replay::replay_velocity(dir, hq::config::load_camera_info(dir + "/camera.yaml"),
                                  hq::pipeline::load_onboard_config("config/onboard.yaml"),
                                  hq::load_vehicle_config("calib/vehicle_core_paper.yaml"));
  std::filesystem::remove_all(dir);
  out.errors = hq::replay::evaluate_velocity(out.replay.samples, out.replay.ground_truth,
                                             out.replay.frame_interval_ns);
  print(name, out.replay, out.errors);
  return out;
}

TEST(VelocityOnSimulatedFlight, InHoverFilteredBeatsRaw) {
  // GIVEN a 10 s hover (velocity noise-dominated), THEN eq. 2 has a lower RMSE than eq. 1: the
  // core paper's reason for the filter.
  const SimulatedEvaluation run = fly_and_evaluate("hover", 0.0);
  const VelocityErrors& e = run.errors;
  EXPECT_FALSE(run.replay.imu.synthesised) << "the simulator records gyro.txt, accelerometer.txt";
  EXPECT_GE(e.samples, 290);  // measured 293 of 301 frames
  EXPECT_LT(e.filtered_norm_mps(), e.raw_norm_mps());
  // Measured 0.0067 / 0.0038 with frame to keyframe and the gyro (0.0100 / 0.0092 frame to
  // frame without it, the default before).
  EXPECT_LT(e.raw_norm_mps(), 0.0084);
  EXPECT_LT(e.filtered_norm_mps(), 0.0048);
}

TEST(VelocityOnSimulatedFlight, InManoeuvresTheFilterAddsLag) {
  // GIVEN 10 s of sinusoidal manoeuvres (|v| RMS 0.36 m/s), THEN both stay within their
  // measured RMSE and the filter delays eq. 2. Measured with config/onboard.yaml (1€ position
  // min_cutoff 1 Hz, beta 2): here the lag dominates and eq. 2 is WORSE than eq. 1 at zero
  // shift (0.0546 vs 0.0207 m/s; frame to frame without the gyro, the default before: 0.0577
  // vs 0.0335). Not asserted either way: it is a tuning finding, reported with
  // B-onboard-chain.
  const SimulatedEvaluation run = fly_and_evaluate("manoeuvre", 1.0);
  const VelocityErrors& e = run.errors;
  EXPECT_GE(e.samples, 290);                          // measured 293 of 301 frames
  EXPECT_GT(e.truth_rms_mps, 0.3);                    // measured 0.363
  EXPECT_LT(e.raw_norm_mps(), 0.026);                 // measured 0.0207
  EXPECT_LT(e.filtered_norm_mps(), 0.069);            // measured 0.0546
  EXPECT_GT(e.filtered_lag_ms, e.raw_lag_ms + 20.0);  // measured 80 vs 17 ms
  EXPECT_LE(e.filtered_lag_ms, 95.0);                 // measured 80 ms
  // A backward difference lags h/2 = 16.5 ms: at most 17 on the search's 1 ms grid (measured
  // 17; 13 frame to frame without the gyro, whose errors partly led the motion).
  EXPECT_LE(e.raw_lag_ms, 17.0);
  // The velocity flown (eq. 1 fused with the IMU) has neither the lag nor eq. 1's noise:
  // measured 0.0089 m/s, lag 9 ms (eq. 1 0.0207; 0.0151 since the odometry leaves keyframe
  // points seen moving out, the flown 0.0088: the IMU, not eq. 1, bounds it).
  EXPECT_LT(e.flown_norm_mps(), 0.011);
  EXPECT_LT(e.flown_norm_mps(), 0.7 * e.raw_norm_mps());
  EXPECT_LE(e.flown_lag_ms, 20.0);
}

}  // namespace
