#include "hq/evaluation/trajectory_spline.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fmt/format.h>
#include <random>
#include <vector>

namespace hq::evaluation {
namespace {

using hq::testing::input_error_message;
using recording::StampedPose;
using ::testing::HasSubstr;

constexpr std::int64_t kT0Ns = 1'305'031'790'000'000'000;

// A hand-held-like motion with a known derivative: position a sum of sines (up to 1 Hz), the
// sensor yawing a whole turn and more (past the quaternion's sign flip) while it rocks in roll.
struct Motion {
  static Eigen::Vector3d p(double t) {
    return {0.3 * std::sin(2.0 * t), 0.2 * std::cos(3.0 * t), 0.05 * std::sin(6.0 * t)};
  }
  static Eigen::Vector3d a(double t) {
    return {-1.2 * std::sin(2.0 * t), -1.8 * std::cos(3.0 * t), -1.8 * std::sin(6.0 * t)};
  }
  static double yaw(double t) { return 1.5 * t; }
  static double roll(double t) { return 0.2 * std::sin(4.0 * t); }
  static Eigen::Matrix3d R(double t) {
    return (Eigen::AngleAxisd(yaw(t), Eigen::Vector3d::UnitZ()) *
            Eigen::AngleAxisd(roll(t), Eigen::Vector3d::UnitX()))
        .toRotationMatrix();
  }
  // omega_S = R^T dR/dt: the roll rate about x plus the yaw rate about z seen in S.
  static Eigen::Vector3d omega_S(double t) {
    const Eigen::Vector3d z_S =
        Eigen::AngleAxisd(roll(t), Eigen::Vector3d::UnitX()).toRotationMatrix().transpose() *
        Eigen::Vector3d::UnitZ();
    return 0.8 * std::cos(4.0 * t) * Eigen::Vector3d::UnitX() + 1.5 * z_S;
  }
};

std::int64_t stamp(double t_s) { return kT0Ns + std::llround(t_s * 1e9); }

// 100 Hz motion capture over 6 s with white noise of the size measured on fr1 (0.15 mm, 0.07
// deg per pose), and a 0.2 s gap as motion capture loses markers.
std::vector<StampedPose> motion_capture(double noise_m, double noise_rad) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<StampedPose> poses;
  for (int k = 0; k <= 600; ++k) {
    const double t = 0.01 * k;
    if (t > 3.0 && t < 3.2) continue;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    const Eigen::Vector3d rot_noise(normal(rng), normal(rng), normal(rng));
    T.linear() =
        Motion::R(t) *
        Eigen::AngleAxisd(noise_rad * rot_noise.norm(), rot_noise.normalized()).toRotationMatrix();
    T.translation() =
        Motion::p(t) + noise_m * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    poses.push_back({stamp(t), T});
  }
  return poses;
}

TEST(TrajectorySpline, RecoversPoseRateAndAccelerationOfNoisyMotionCapture) {
  const std::vector<StampedPose> poses = motion_capture(1.5e-4, 1.2e-3);
  const TrajectorySpline spline = TrajectorySpline::fit(poses);
  EXPECT_EQ(spline.t_begin_ns(), stamp(0.0));
  EXPECT_EQ(spline.t_end_ns(), stamp(6.0));
  // The residual is the noise it averaged out: close to its 0.26 mm (3 axes), not far below.
  EXPECT_GT(spline.residual_rms_m(), 1.5e-4);
  EXPECT_LT(spline.residual_rms_m(), 4e-4);
  double sq_accel = 0;
  double sq_omega = 0;
  double max_p = 0;
  int count = 0;
  // Away from the ends, where a regression spline has one side only, and apart from the gap,
  // which the fit bridges on the second differences alone (checked after).
  for (double t = 0.2; t < 5.8; t += 0.005) {
    const double angle =
        Eigen::AngleAxisd(spline.pose(stamp(t)).linear().transpose() * Motion::R(t)).angle();
    if (t > 2.95 && t < 3.25) {
      EXPECT_LT((spline.pose(stamp(t)).translation() - Motion::p(t)).norm(), 0.01);
      EXPECT_LT(angle, 0.03) << "at t = " << t;
      continue;
    }
    max_p = std::max(max_p, (spline.pose(stamp(t)).translation() - Motion::p(t)).norm());
    EXPECT_LT(angle, 0.01) << "at t = " << t;
    sq_accel += (spline.acceleration_G_mps2(stamp(t)) - Motion::a(t)).squaredNorm();
    sq_omega += (spline.omega_S_radps(stamp(t)) - Motion::omega_S(t)).squaredNorm();
    ++count;
  }
  EXPECT_LT(max_p, 1.5e-3);
  // The peer: second differences of the same poses, 10 ms apart, away from the gap.
  double sq_difference = 0;
  int differences = 0;
  for (std::size_t k = 20; k + 21 < poses.size(); ++k) {
    const double t = hq::to_seconds(poses[k].t_ns - kT0Ns);
    if (poses[k + 1].t_ns - poses[k - 1].t_ns != 20'000'000) continue;  // the gap's edges
    const Eigen::Vector3d a =
        (poses[k + 1].T_G_S.translation() - 2.0 * poses[k].T_G_S.translation() +
         poses[k - 1].T_G_S.translation()) /
        1e-4;
    sq_difference += (a - Motion::a(t)).squaredNorm();
    ++differences;
  }
  const double spline_accel_rmse = std::sqrt(sq_accel / count);
  const double difference_accel_rmse = std::sqrt(sq_difference / differences);
  fmt::print(
      "acceleration RMSE {:.3f} m/s^2 (second differences: {:.3f}), rate RMSE {:.4f} rad/s\n",
      spline_accel_rmse, difference_accel_rmse, std::sqrt(sq_omega / count));
  // A tenth of the 2 m/s^2 RMS acceleration (measured 0.21), where the second differences are
  // buried under the noise (0.15 mm x sqrt(6 x 3) / (10 ms)^2, about 6 m/s^2).
  EXPECT_LT(spline_accel_rmse, 0.3);
  EXPECT_LT(spline_accel_rmse, 0.1 * difference_accel_rmse);
  EXPECT_LT(std::sqrt(sq_omega / count), 0.05);
}

TEST(TrajectorySpline, VelocityIsThePositionsDerivative) {
  const TrajectorySpline spline = TrajectorySpline::fit(motion_capture(0.0, 0.0));
  const double h = 1e-4;
  for (double t = 0.5; t < 5.5; t += 0.37) {
    const Eigen::Vector3d numeric =
        (spline.pose(stamp(t + h)).translation() - spline.pose(stamp(t - h)).translation()) /
        (2 * h);
    EXPECT_LT((spline.velocity_G_mps(stamp(t)) - numeric).norm(), 1e-4) << "at t = " << t;
  }
}

TEST(TrajectorySpline, RefusesWhatItCannotFit) {
  std::vector<StampedPose> few(3, StampedPose{kT0Ns, Eigen::Isometry3d::Identity()});
  for (int k = 0; k < 3; ++k) few[static_cast<std::size_t>(k)].t_ns = stamp(0.01 * k);
  EXPECT_THAT(input_error_message([&] { TrajectorySpline::fit(few); }),
              HasSubstr("3 poses, expected at least 4"));

  std::vector<StampedPose> poses = motion_capture(0.0, 0.0);
  std::vector<StampedPose> unordered = poses;
  unordered[5].t_ns = unordered[4].t_ns;
  EXPECT_THAT(input_error_message([&] { TrajectorySpline::fit(unordered); }),
              HasSubstr("pose 6 stamped"));
  std::vector<StampedPose> not_finite = poses;
  not_finite[9].T_G_S.translation().x() = std::nan("");
  EXPECT_THAT(input_error_message([&] { TrajectorySpline::fit(not_finite); }),
              HasSubstr("pose 10 is not finite"));
  EXPECT_THAT(input_error_message([&] {
                TrajectorySpline::fit(poses, {0.0, 1e-6});
              }),
              HasSubstr("knot spacing 0 s"));
}

}  // namespace
}  // namespace hq::evaluation
