#include "hq/evaluation/trajectory_error.hpp"

#include "hq/base/error.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace hq::evaluation {
namespace {

using recording::StampedPose;
using ::testing::HasSubstr;

constexpr double kPi = 3.14159265358979323846;
constexpr std::int64_t kT0Ns = 1'305'031'790'000'000'000;

using hq::testing::input_error_message;

Eigen::Isometry3d make_pose(const Eigen::Vector3d& axis_angle_rad, const Eigen::Vector3d& p_m) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const double angle = axis_angle_rad.norm();
  if (angle > 0) T.linear() = Eigen::AngleAxisd(angle, axis_angle_rad / angle).toRotationMatrix();
  T.translation() = p_m;
  return T;
}

// A helix with a turning, pitching sensor: every pose differs in all six degrees of freedom.
std::vector<StampedPose> helix(int count, double rate_hz) {
  std::vector<StampedPose> poses;
  for (int k = 0; k < count; ++k) {
    const double t_s = k / rate_hz;
    poses.push_back({kT0Ns + static_cast<std::int64_t>(std::llround(t_s * 1e9)),
                     make_pose(Eigen::Vector3d(0.1 * std::sin(t_s), 0.05, 0.4 * t_s + 0.2),
                               Eigen::Vector3d(std::cos(t_s), std::sin(t_s), 0.3 * t_s))});
  }
  return poses;
}

TEST(ErrorStats, OddCountGivesMiddleValue) {
  const ErrorStats stats = error_stats({3.0, 1.0, 2.0});
  EXPECT_EQ(stats.count, 3);
  EXPECT_DOUBLE_EQ(stats.mean, 2.0);
  EXPECT_DOUBLE_EQ(stats.median, 2.0);
  EXPECT_DOUBLE_EQ(stats.rmse, std::sqrt(14.0 / 3.0));
  EXPECT_DOUBLE_EQ(stats.max, 3.0);
}

TEST(ErrorStats, EvenCountAveragesTheTwoMiddleValues) {
  const ErrorStats stats = error_stats({4.0, 1.0, 10.0, 2.0});
  EXPECT_EQ(stats.count, 4);
  EXPECT_DOUBLE_EQ(stats.mean, 4.25);
  EXPECT_DOUBLE_EQ(stats.median, 3.0);
  EXPECT_DOUBLE_EQ(stats.rmse, std::sqrt(121.0 / 4.0));
  EXPECT_DOUBLE_EQ(stats.max, 10.0);
}

TEST(ErrorStats, EmptyListHasZeroCount) {
  const ErrorStats stats = error_stats({});
  EXPECT_EQ(stats.count, 0);
  EXPECT_EQ(stats.rmse, 0.0);
  EXPECT_EQ(stats.median, 0.0);
}

TEST(TrajectoryError, IdenticalTrajectoriesGiveZero) {
  const std::vector<StampedPose> gt = helix(61, 30.0);
  const RpeResult rpe = relative_pose_error(gt, gt, 1.0);
  EXPECT_FALSE(rpe.delta_clipped);
  EXPECT_EQ(rpe.delta_s, 1.0);
  // Windows start at frames 0..45: the last start still finds a stamp >= 0.5 s later.
  EXPECT_EQ(rpe.trans_mps.count, 46);
  EXPECT_NEAR(rpe.trans_mps.max, 0.0, 1e-12);
  EXPECT_NEAR(rpe.rot_degps.max, 0.0, 1e-6);
  const AteResult ate = absolute_trajectory_error(gt, gt);
  EXPECT_EQ(ate.trans_m.count, 61);
  EXPECT_NEAR(ate.trans_m.max, 0.0, 1e-9);
  EXPECT_TRUE(ate.T_gt_est.matrix().isIdentity(1e-9));
}

TEST(TrajectoryError, ConstantRigidOffsetIsAlignedAwayAndInvisibleToRpe) {
  // GIVEN the estimate expressed in another world frame: P_k = T_est_gt * Q_k.
  const std::vector<StampedPose> gt = helix(61, 30.0);
  const Eigen::Isometry3d T_est_gt =
      make_pose(Eigen::Vector3d(0.3, -1.2, 0.7), Eigen::Vector3d(5.0, -2.0, 1.5));
  std::vector<StampedPose> est = gt;
  for (StampedPose& pose : est) pose.T_G_S = T_est_gt * pose.T_G_S;

  // THEN the alignment recovers its inverse and both errors vanish.
  const AteResult ate = absolute_trajectory_error(gt, est);
  EXPECT_NEAR(ate.trans_m.rmse, 0.0, 1e-9);
  EXPECT_TRUE(ate.T_gt_est.matrix().isApprox(T_est_gt.inverse().matrix(), 1e-9));
  const RpeResult rpe = relative_pose_error(gt, est, 0.5);
  EXPECT_NEAR(rpe.trans_mps.max, 0.0, 1e-9);
  EXPECT_NEAR(rpe.rot_degps.max, 0.0, 1e-5);
}

TEST(TrajectoryError, ExtraTranslationPerStepGivesExactRpe) {
  // GIVEN ground truth translating without rotation at 20 Hz, and an estimate that adds
  // (3, 4, 0) mm per step: 5 mm per 50 ms = 0.1 m/s of drift.
  std::vector<StampedPose> gt;
  std::vector<StampedPose> est;
  for (std::int64_t k = 0; k <= 40; ++k) {
    const std::int64_t t_ns = kT0Ns + k * 50'000'000;
    const Eigen::Vector3d p_m(0.2 * static_cast<double>(k), -0.1 * static_cast<double>(k), 1.0);
    gt.push_back({t_ns, make_pose(Eigen::Vector3d::Zero(), p_m)});
    est.push_back(
        {t_ns, make_pose(Eigen::Vector3d::Zero(),
                         p_m + static_cast<double>(k) * Eigen::Vector3d(0.003, 0.004, 0))});
  }
  for (const double delta_s : {1.0, 0.5}) {
    const RpeResult rpe = relative_pose_error(gt, est, delta_s);
    EXPECT_NEAR(rpe.trans_mps.rmse, 0.1, 1e-9) << delta_s;
    EXPECT_NEAR(rpe.trans_mps.mean, 0.1, 1e-9) << delta_s;
    EXPECT_NEAR(rpe.trans_mps.median, 0.1, 1e-9) << delta_s;
    EXPECT_NEAR(rpe.trans_mps.max, 0.1, 1e-9) << delta_s;
    EXPECT_NEAR(rpe.rot_degps.max, 0.0, 1e-9) << delta_s;
  }
  // Windows of 1 s start at frames 0..30 (the last ones end at frame 40, >= 0.5 s later).
  EXPECT_EQ(relative_pose_error(gt, est, 1.0).trans_mps.count, 31);
}

TEST(TrajectoryError, RotationRateErrorGivesDegreesPerSecond) {
  // GIVEN ground truth yawing at 0.2 rad/s and an estimate yawing at 0.3 rad/s at 30 Hz:
  // E = Rz(-0.2 dt) Rz(0.3 dt) = Rz(0.1 dt), so 0.1 rad/s = 5.7295779513 deg/s.
  std::vector<StampedPose> gt;
  std::vector<StampedPose> est;
  for (std::int64_t k = 0; k < 90; ++k) {
    const std::int64_t t_ns = kT0Ns + k * 33'333'333;
    const double t_s = static_cast<double>(k) * 0.033333333;
    gt.push_back({t_ns, make_pose(Eigen::Vector3d(0, 0, 0.2 * t_s), Eigen::Vector3d::Zero())});
    est.push_back({t_ns, make_pose(Eigen::Vector3d(0, 0, 0.3 * t_s), Eigen::Vector3d::Zero())});
  }
  const RpeResult rpe = relative_pose_error(gt, est, 1.0);
  const double expected_degps = 0.1 * 180.0 / kPi;
  EXPECT_NEAR(rpe.rot_degps.rmse, expected_degps, 1e-6);
  EXPECT_NEAR(rpe.rot_degps.median, expected_degps, 1e-6);
  EXPECT_NEAR(rpe.rot_degps.max, expected_degps, 1e-6);
  EXPECT_NEAR(rpe.trans_mps.max, 0.0, 1e-12);
}

TEST(TrajectoryError, SaddleShapedOffsetLeavesKnownAte) {
  // GIVEN four ground-truth corners of a square and an estimate lifted by +-5 cm in a saddle
  // pattern (z = 0.05 x y): no rigid motion fits it better than identity (the cross-covariance
  // is diag(1, 1, 0)), so every point keeps its 5 cm error.
  const Eigen::Vector3d corners[] = {{1, 1, 0}, {-1, 1, 0}, {-1, -1, 0}, {1, -1, 0}};
  std::vector<StampedPose> gt;
  std::vector<StampedPose> est;
  for (std::int64_t k = 0; k < 4; ++k) {
    const Eigen::Vector3d& c = corners[k];
    const std::int64_t t_ns = kT0Ns + k * 100'000'000;
    gt.push_back({t_ns, make_pose(Eigen::Vector3d::Zero(), c)});
    est.push_back({t_ns, make_pose(Eigen::Vector3d::Zero(),
                                   c + Eigen::Vector3d(0, 0, 0.05 * c.x() * c.y()))});
  }
  const AteResult ate = absolute_trajectory_error(gt, est);
  EXPECT_EQ(ate.trans_m.count, 4);
  EXPECT_NEAR(ate.trans_m.rmse, 0.05, 1e-12);
  EXPECT_NEAR(ate.trans_m.median, 0.05, 1e-12);
  EXPECT_NEAR(ate.trans_m.max, 0.05, 1e-12);
  EXPECT_TRUE(ate.T_gt_est.matrix().isIdentity(1e-12));
}

TEST(AssociatePoses, GapsAndStampsBeyondMaxDtAreNotAssociated) {
  // Ground truth at 100 Hz over [0, 1] s with a gap (0.40, 0.60) s; estimate every 0.1 s, each
  // 3 ms late, over [0, 1.2] s. Estimates at 0.5 s (gap) and 1.1, 1.2 s (after the end) stay
  // unpaired; 1.0 s pairs with the last ground truth.
  std::vector<StampedPose> gt;
  for (std::int64_t k = 0; k <= 100; ++k) {
    if (k > 40 && k < 60) continue;
    gt.push_back({kT0Ns + k * 10'000'000, Eigen::Isometry3d::Identity()});
  }
  std::vector<StampedPose> est;
  for (std::int64_t k = 0; k <= 12; ++k) {
    est.push_back({kT0Ns + k * 100'000'000 + 3'000'000, Eigen::Isometry3d::Identity()});
  }
  const auto pairs = associate_poses(gt, est, 0.02);
  std::vector<std::size_t> est_indices;
  for (const auto& [g, e] : pairs) {
    est_indices.push_back(e);
    EXPECT_EQ(gt[g].t_ns + 3'000'000, est[e].t_ns) << "est " << e;
  }
  EXPECT_EQ(est_indices, (std::vector<std::size_t>{0, 1, 2, 3, 4, 6, 7, 8, 9, 10}));

  // With a 2 ms tolerance the 3 ms offset associates nothing.
  EXPECT_TRUE(associate_poses(gt, est, 0.002).empty());
}

TEST(AssociatePoses, EachGroundTruthPoseUsedOnce) {
  // Two estimates 4 ms apart share the same nearest ground truth pose; the closer one wins it,
  // the other takes the next nearest within tolerance.
  const std::vector<StampedPose> gt = {{kT0Ns, Eigen::Isometry3d::Identity()},
                                       {kT0Ns + 10'000'000, Eigen::Isometry3d::Identity()}};
  const std::vector<StampedPose> est = {{kT0Ns + 1'000'000, Eigen::Isometry3d::Identity()},
                                        {kT0Ns + 3'000'000, Eigen::Isometry3d::Identity()}};
  const auto pairs = associate_poses(gt, est, 0.008);
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_EQ(pairs[0], std::make_pair(std::size_t{0}, std::size_t{0}));
  EXPECT_EQ(pairs[1], std::make_pair(std::size_t{1}, std::size_t{1}));
}

TEST(TrajectoryError, ShortSequenceClipsDelta) {
  // 9 frames at 30 Hz span 0.2667 s, less than the requested 1 s.
  const std::vector<StampedPose> gt = helix(9, 30.0);
  const RpeResult rpe = relative_pose_error(gt, gt, 1.0);
  EXPECT_TRUE(rpe.delta_clipped);
  EXPECT_NEAR(rpe.delta_s, 8.0 / 30.0, 1e-9);
  // Windows of >= half the span: starts at frames 0..4, all ending at frame 8.
  EXPECT_EQ(rpe.trans_mps.count, 5);
}

TEST(TrajectoryError, TooFewAssociatedPosesIsAnInputError) {
  const std::vector<StampedPose> gt = helix(10, 100.0);
  std::vector<StampedPose> est = {gt[3]};
  EXPECT_THAT(input_error_message([&] { relative_pose_error(gt, est); }),
              HasSubstr("RPE needs at least 2 associated poses, got 1 (ground truth 10 poses, "
                        "estimate 1 poses"));
  est.push_back(gt[7]);
  EXPECT_THAT(input_error_message([&] { absolute_trajectory_error(gt, est); }),
              HasSubstr("ATE needs at least 3 associated poses, got 2"));
  // Estimates 1 s after the ground truth associate nothing.
  for (StampedPose& pose : est) pose.t_ns += 1'000'000'000;
  EXPECT_THAT(input_error_message([&] { absolute_trajectory_error(gt, est); }), HasSubstr("got 0"));
}

TEST(TrajectoryError, NonFiniteOrUnorderedPosesAreInputErrors) {
  const std::vector<StampedPose> gt = helix(10, 100.0);
  std::vector<StampedPose> est = gt;
  est[4].T_G_S.translation().y() = std::nan("");
  EXPECT_THAT(input_error_message([&] { absolute_trajectory_error(gt, est); }),
              HasSubstr("estimate pose 4"));
  est = gt;
  std::swap(est[2], est[3]);
  EXPECT_THAT(input_error_message([&] { relative_pose_error(gt, est); }),
              HasSubstr("estimate pose 3"));
  EXPECT_THAT(input_error_message([&] { relative_pose_error(gt, gt, 0.0); }),
              HasSubstr("delta_s = 0.000000, expected finite and > 0"));
  EXPECT_THAT(input_error_message([&] { associate_poses(gt, gt, -1.0); }),
              HasSubstr("max_dt_s = -1.000000"));
}

// The helix with white noise of sigma per axis on every pose's position and rotation vector.
std::vector<StampedPose> noisy_helix(int count, double rate_hz, double sigma_m, double sigma_rad,
                                     std::uint64_t seed) {
  std::vector<StampedPose> poses = helix(count, rate_hz);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (StampedPose& pose : poses) {
    const Eigen::Vector3d dp(normal(rng), normal(rng), normal(rng));
    const Eigen::Vector3d dr(normal(rng), normal(rng), normal(rng));
    pose.T_G_S.translation() += sigma_m * dp;
    pose.T_G_S.linear() =
        pose.T_G_S.linear() * make_pose(sigma_rad * dr, Eigen::Vector3d::Zero()).linear();
  }
  return poses;
}

TEST(GroundTruthNoise, WhiteNoiseOnEachPoseIsRecovered) {
  // GIVEN 2000 poses at 100 Hz with 0.5 mm and 0.05 deg of noise per axis
  constexpr double kSigmaM = 0.5e-3;
  constexpr double kSigmaDeg = 0.05;
  const auto poses = noisy_helix(2000, 100.0, kSigmaM, kSigmaDeg * kPi / 180.0, 7);
  // WHEN its own noise is estimated
  const PoseNoise noise = ground_truth_noise(poses);
  // THEN the RMS lengths are sqrt(3) sigma, to the sampling error of 1997 differences
  EXPECT_EQ(noise.differences, 1997);
  EXPECT_NEAR(noise.trans_m, std::sqrt(3.0) * kSigmaM, 0.08 * std::sqrt(3.0) * kSigmaM);
  EXPECT_NEAR(noise.rot_deg, std::sqrt(3.0) * kSigmaDeg, 0.08 * std::sqrt(3.0) * kSigmaDeg);
}

TEST(GroundTruthNoise, SmoothMotionWithJitteredStampsHasNone) {
  // GIVEN the noise-free helix sampled at 100 Hz +- 1 ms (poses at their true stamps), with a
  // 50 ms gap in the record
  std::vector<StampedPose> poses;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> jitter(-1e-3, 1e-3);
  for (int k = 0; k < 500; ++k) {
    if (k >= 200 && k < 205) continue;
    const double t_s = k / 100.0 + jitter(rng);
    poses.push_back({kT0Ns + static_cast<std::int64_t>(std::llround(t_s * 1e9)),
                     make_pose(Eigen::Vector3d(0.1 * std::sin(t_s), 0.05, 0.4 * t_s + 0.2),
                               Eigen::Vector3d(std::cos(t_s), std::sin(t_s), 0.3 * t_s))});
  }
  // WHEN its noise is estimated
  const PoseNoise noise = ground_truth_noise(poses);
  // THEN the jitter and the gap, which would each show as a millimetre, leave a floor far
  // below the noise of any motion capture
  EXPECT_GT(noise.differences, 480);
  EXPECT_LT(noise.differences, 495);
  EXPECT_LT(noise.trans_m, 2e-5);
  EXPECT_LT(noise.rot_deg, 2e-3);
}

TEST(GroundTruthNoise, TooFewPosesGiveNoFigureAndBadPosesAnInputError) {
  EXPECT_EQ(ground_truth_noise(helix(3, 100.0)).differences, 0);
  EXPECT_EQ(ground_truth_noise(helix(4, 100.0)).differences, 1);
  std::vector<StampedPose> poses = helix(10, 100.0);
  poses[6].T_G_S.translation().x() = std::nan("");
  EXPECT_THAT(input_error_message([&] { ground_truth_noise(poses); }),
              HasSubstr("ground truth pose 6"));
}

}  // namespace
}  // namespace hq::evaluation
