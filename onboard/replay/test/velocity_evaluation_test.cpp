// Ground-truth velocity, the RMSE/lag evaluation and the synthesised IMU on trajectories whose
// answers are known in closed form.
#include "hq/replay/velocity_evaluation.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/replay/replay_imu.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace hq::replay {
namespace {

using recording::StampedPose;
using ::testing::HasSubstr;

constexpr std::int64_t kGroundTruthPeriodNs = 10'000'000;  // 100 Hz, as TUM's mocap

Eigen::Matrix3d Rz(double angle_rad) {
  return Eigen::AngleAxisd(angle_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

/// A level camera-as-body (R_GQ = Rz(yaw) Rx(pi), NED body in a z-up world) yawing at
/// yaw_rate_radps while its position follows p(t).
template <typename Position>
std::vector<StampedPose> trajectory(double duration_s, double yaw_rate_radps, Position p) {
  const Eigen::Matrix3d R_QC = R_B_C_for_camera_as_body();
  const Eigen::Matrix3d Rx_pi =
      Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  std::vector<StampedPose> out;
  for (std::int64_t t = 0; t <= static_cast<std::int64_t>(duration_s * 1e9);
       t += kGroundTruthPeriodNs) {
    const double t_s = hq::to_seconds(t);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Rz(yaw_rate_radps * t_s) * Rx_pi * R_QC;
    T.translation() = p(t_s);
    out.push_back({t, T});
  }
  return out;
}

TEST(TrueCameraVelocity, IsTheWorldVelocityInTheCameraFrame) {
  const Eigen::Vector3d v_G(0.4, -0.2, 0.1);
  const auto gt = trajectory(2.0, 0.5, [&](double t) { return Eigen::Vector3d(v_G * t); });
  const std::int64_t t_ns = 1'005'000'000;  // between ground-truth samples
  const auto v = true_camera_velocity(gt, t_ns, 33'000'000);
  ASSERT_TRUE(v.has_value());
  const Eigen::Matrix3d R_GC = interpolate_pose(gt, t_ns)->linear();
  EXPECT_LT((*v - R_GC.transpose() * v_G).norm(), 1e-9);
  EXPECT_FALSE(true_camera_velocity(gt, 10'000'000, 33'000'000).has_value())
      << "t - h before the ground truth";
}

TEST(EvaluateVelocity, FindsRmseAndTheLagOfADelayedEstimate) {
  // GIVEN a sinusoidal motion, a raw estimate equal to the truth and a filtered estimate that is
  // the truth 50 ms late, THEN raw RMSE is 0 with lag 0, the filtered lag is 50 ms and its
  // RMSE at that lag is 0.
  const auto gt = trajectory(4.0, 0.0, [](double t) {
    return Eigen::Vector3d(0.5 * std::sin(2.0 * t), 0.3 * std::cos(3.0 * t), 0.0);
  });
  const std::int64_t h_ns = 33'000'000;
  std::vector<VelocitySample> samples;
  for (std::int64_t t = 500'000'000; t <= 3'500'000'000; t += h_ns) {
    samples.push_back(
        {t, *true_camera_velocity(gt, t, h_ns), *true_camera_velocity(gt, t - 50'000'000, h_ns)});
  }
  const VelocityErrors e = evaluate_velocity(samples, gt, h_ns);
  EXPECT_EQ(e.samples, static_cast<int>(samples.size()));
  EXPECT_LT(e.raw_norm_mps(), 1e-9);
  EXPECT_DOUBLE_EQ(e.raw_lag_ms, 0.0);
  EXPECT_GT(e.filtered_norm_mps(), 0.05);
  EXPECT_NEAR(e.filtered_lag_ms, 50.0, 1e-6);
  EXPECT_LT(e.rmse_filtered_at_lag_mps.norm(), 1e-9);
  EXPECT_GT(e.truth_rms_mps, 0.3);
}

TEST(EvaluateVelocity, EstimatesOutsideTheGroundTruthAreAnError) {
  const auto gt = trajectory(1.0, 0.0, [](double t) { return Eigen::Vector3d(t, 0.0, 0.0); });
  VelocitySample late;
  late.t_ns = 5'000'000'000;
  const std::vector<VelocitySample> samples = {late};
  try {
    evaluate_velocity(samples, gt, 33'000'000);
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("none of 1 estimates"));
  }
  EXPECT_THROW(evaluate_velocity(samples, gt, 0), InputError);
}

MemsImuModel noiseless() {
  MemsImuModel model = bmi088();
  model.gyro_noise_density_radps = 0.0;
  model.accel_noise_density_mps2 = 0.0;
  model.gyro_bias_random_walk = 0.0;
  model.accel_bias_random_walk = 0.0;
  model.gyro_turn_on_bias_radps = 0.0;
  model.accel_turn_on_bias_mps2 = 0.0;
  return model;
}

const Eigen::Vector3d kGravityDownW(0.0, 0.0, -9.80665);

TEST(SynthesiseImu, GivesBodyRateAndGravityOfALevelYawingCamera) {
  // A level camera-as-body yawing left (+z up in the world) at 0.5 rad/s is a rate of -0.5
  // about the body's down axis; at constant velocity the specific force is -g along body z.
  const auto gt = trajectory(2.0, 0.5, [](double t) { return Eigen::Vector3d(0.2 * t, 0.0, 1.0); });
  ImuSynthesis synthesis;
  synthesis.imu = noiseless();
  const auto imu = synthesise_imu(evaluation::TrajectorySpline::fit(gt), R_B_C_for_camera_as_body(),
                                  kGravityDownW, synthesis);
  ASSERT_GT(imu.size(), 300u);
  EXPECT_NEAR(hq::to_seconds(imu[1].t_ns - imu[0].t_ns), 1.0 / 200.0, 1e-9);
  for (const ImuMeasurement& m : imu) {
    EXPECT_LT((m.gyro_radps - Eigen::Vector3d(0.0, 0.0, -0.5)).norm(), 1e-3);
    EXPECT_LT((m.accel_mps2 - Eigen::Vector3d(0.0, 0.0, -9.80665)).norm(), 1e-3);
  }
}

TEST(SynthesiseImu, AddsTheNamedImusNoiseAtItsDatasheetDensity) {
  const auto gt = trajectory(4.0, 0.0, [](double t) { return Eigen::Vector3d(0.2 * t, 0.0, 1.0); });
  const evaluation::TrajectorySpline spline = evaluation::TrajectorySpline::fit(gt);
  ImuSynthesis synthesis;
  synthesis.imu.gyro_turn_on_bias_radps = 0.0;
  synthesis.imu.accel_turn_on_bias_mps2 = 0.0;
  synthesis.imu.gyro_bias_random_walk = 0.0;
  synthesis.imu.accel_bias_random_walk = 0.0;
  const auto noisy = synthesise_imu(spline, R_B_C_for_camera_as_body(), kGravityDownW, synthesis);
  synthesis.imu = noiseless();
  const auto clean = synthesise_imu(spline, R_B_C_for_camera_as_body(), kGravityDownW, synthesis);
  ASSERT_EQ(noisy.size(), clean.size());
  double sq_gyro = 0.0;
  double sq_accel = 0.0;
  for (std::size_t i = 0; i < noisy.size(); ++i) {
    sq_gyro += (noisy[i].gyro_radps - clean[i].gyro_radps).squaredNorm();
    sq_accel += (noisy[i].accel_mps2 - clean[i].accel_mps2).squaredNorm();
  }
  const auto n = static_cast<double>(3 * noisy.size());
  const MemsImuModel model = bmi088();
  // sigma = density sqrt(rate), within the spread of 2400 draws.
  EXPECT_NEAR(std::sqrt(sq_gyro / n), model.gyro_noise_density_radps * std::sqrt(200.0),
              0.05 * model.gyro_noise_density_radps * std::sqrt(200.0));
  EXPECT_NEAR(std::sqrt(sq_accel / n), model.accel_noise_density_mps2 * std::sqrt(200.0),
              0.05 * model.accel_noise_density_mps2 * std::sqrt(200.0));
  EXPECT_THAT(describe(model), HasSubstr("Bosch BMI088"));
  EXPECT_THAT(describe(model), HasSubstr("0.014 deg/s/sqrt(Hz)"));
}

// A Kinect's accelerometer record of a camera moving under gravity tilted 3 deg from the
// world's -z (a motion-capture frame not quite level).
std::vector<recording::AccelSample> kinect_record(const evaluation::TrajectorySpline& spline,
                                                  const Eigen::Vector3d& g_G) {
  std::vector<recording::AccelSample> out;
  const Eigen::Matrix3d R_A_C = R_camera_kinect_accel().transpose();
  for (std::int64_t t = spline.t_begin_ns(); t <= spline.t_end_ns(); t += 1'000'000) {
    const Eigen::Matrix3d R_GC = spline.pose(t).linear();
    out.push_back({t, R_A_C * R_GC.transpose() * (spline.acceleration_G_mps2(t) - g_G)});
  }
  return out;
}

TEST(GravityFromAccelerometer, FindsATiltedWorldsGravityAndReplaysTheRecording) {
  const auto gt = trajectory(3.0, 0.4, [](double t) {
    return Eigen::Vector3d(0.3 * std::sin(2.0 * t), 0.1 * t, 1.0 + 0.1 * std::cos(3.0 * t));
  });
  const evaluation::TrajectorySpline spline = evaluation::TrajectorySpline::fit(gt);
  const Eigen::Vector3d g_G =
      Eigen::AngleAxisd(3.0 * M_PI / 180.0, Eigen::Vector3d::UnitX()) * kGravityDownW;
  const auto record = kinect_record(spline, g_G);
  const GravityEstimate g = gravity_from_accelerometer(spline, record, R_camera_kinect_accel());
  EXPECT_LT((g.g_G_mps2 - g_G).norm(), 1e-3);
  EXPECT_NEAR(g.tilt_from_G_down_deg, 3.0, 1e-3);
  EXPECT_EQ(g.samples, static_cast<int>(record.size()));

  // The replayed accelerometer is the record, in the body frame, averaged per 5 ms sample:
  // what the model would give with the same gravity and no noise.
  ImuSynthesis synthesis;
  synthesis.imu = noiseless();
  const Eigen::Matrix3d R_QC = R_B_C_for_camera_as_body();
  const auto replayed =
      synthesise_imu(spline, R_QC, g.g_G_mps2, synthesis, &record, R_camera_kinect_accel());
  const auto modelled = synthesise_imu(spline, R_QC, g.g_G_mps2, synthesis);
  ASSERT_EQ(replayed.size(), modelled.size());
  double worst = 0.0;
  for (std::size_t i = 0; i < replayed.size(); ++i) {
    worst = std::max(worst, (replayed[i].accel_mps2 - modelled[i].accel_mps2).norm());
  }
  EXPECT_LT(worst, 0.05) << "5 ms averages of a moving camera's 1 kHz record";

  // Read in the camera's own axes, the same record puts gravity upside down: refused.
  EXPECT_THAT(hq::testing::input_error_message(
                  [&] { gravity_from_accelerometer(spline, record, Eigen::Matrix3d::Identity()); }),
              HasSubstr("the accelerometer's axes are not the ones assumed"));
}

TEST(ChooseAccelerometer, ReplaysARecordInKinectAxesAndSaysWhyNotOtherwise) {
  const auto gt = trajectory(3.0, 0.4, [](double t) {
    return Eigen::Vector3d(0.3 * std::sin(2.0 * t), 0.1 * t, 1.0 + 0.1 * std::cos(3.0 * t));
  });
  const evaluation::TrajectorySpline spline = evaluation::TrajectorySpline::fit(gt);
  const auto record = kinect_record(spline, kGravityDownW);
  // GIVEN a Kinect record: its gravity, and the record itself when asked for
  const AccelerometerChoice kinect = choose_accelerometer(spline, &record, true);
  EXPECT_EQ(kinect.recorded, &record);
  EXPECT_LT((kinect.g_G_mps2 - kGravityDownW).norm(), 1e-3);
  EXPECT_THAT(kinect.description, HasSubstr("gravity from accelerometer.txt"));
  EXPECT_EQ(choose_accelerometer(spline, &record, false).recorded, nullptr);
  // GIVEN a record in other axes (gravity upside down in Kinect axes): not used, and why
  std::vector<recording::AccelSample> flipped = record;
  for (recording::AccelSample& a : flipped) a.accel_mps2 = -a.accel_mps2;
  const AccelerometerChoice other = choose_accelerometer(spline, &flipped, true);
  EXPECT_EQ(other.recorded, nullptr);
  EXPECT_EQ(other.g_G_mps2, kGravityDownW);
  EXPECT_THAT(other.description, HasSubstr("accelerometer.txt NOT USED"));
  EXPECT_THAT(other.description, HasSubstr("not the ones assumed"));
  // GIVEN none: gravity assumed, and said to be
  const AccelerometerChoice none = choose_accelerometer(spline, nullptr, true);
  EXPECT_EQ(none.recorded, nullptr);
  EXPECT_THAT(none.description, HasSubstr("ASSUMED"));
}

TEST(SynthesiseImu, TooShortGroundTruthIsAnError) {
  const std::vector<StampedPose> one = {{0, Eigen::Isometry3d::Identity()}};
  EXPECT_THAT(hq::testing::input_error_message([&] { evaluation::TrajectorySpline::fit(one); }),
              HasSubstr("1 poses, expected at least 4"));
}

}  // namespace
}  // namespace hq::replay
