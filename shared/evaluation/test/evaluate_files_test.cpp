// End to end on files, as hq-evaluate runs: write a ground truth and an estimate in TUM format,
// read them back, compute RPE and ATE.
#include "hq/evaluation/trajectory_error.hpp"
#include "hq/recording/tum_io.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <unistd.h>

namespace hq::evaluation {
namespace {

using recording::StampedPose;

TEST(EvaluateFiles, SyntheticGroundTruthAndEstimateGiveKnownFigures) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("hq_evaluation_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);

  // GIVEN ground truth at 100 Hz for 3 s, moving along x at 0.5 m/s and yawing at 0.2 rad/s,
  // and an estimate every 30 ms (stamps 4 ms after the ground truth's) in a world frame shifted by
  // (1, 2, 3) m that overestimates the speed by 2 %: 0.01 m/s of drift along x.
  std::vector<StampedPose> gt;
  for (std::int64_t k = 0; k <= 300; ++k) {
    const double t_s = static_cast<double>(k) * 0.01;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(0.2 * t_s, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(0.5 * t_s, 0.0, 1.0);
    gt.push_back({1'000'000'000'000 + k * 10'000'000, T});
  }
  std::vector<StampedPose> est;
  for (std::int64_t k = 0; k < 90; ++k) {
    const std::int64_t t_ns = 1'000'000'000'000 + 4'000'000 + k * 30'000'000;
    const double t_s = static_cast<double>(t_ns - 1'000'000'000'000) * 1e-9;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(0.2 * t_s, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = Eigen::Vector3d(0.51 * t_s + 1.0, 2.0, 4.0);
    est.push_back({t_ns, T});
  }
  const std::string gt_path = (dir / "groundtruth.txt").string();
  const std::string est_path = (dir / "traj.txt").string();
  recording::write_tum_trajectory(gt_path, gt);
  recording::write_tum_trajectory(est_path, est);

  // WHEN read back and evaluated as hq-evaluate does
  const std::vector<StampedPose> gt_read = recording::read_tum_trajectory(gt_path);
  const std::vector<StampedPose> est_read = recording::read_tum_trajectory(est_path);
  const RpeResult rpe = relative_pose_error(gt_read, est_read, 1.0, 0.02);
  const AteResult ate = absolute_trajectory_error(gt_read, est_read, 0.02);
  std::filesystem::remove_all(dir);

  // THEN every estimate pairs with the ground truth 4 ms before it; the estimate's relative
  // motion over a window dt is the ground truth's plus 0.01 dt along world x, which is
  // 0.01 m/s whatever the yaw. The 4 ms stamp offset adds the motion made in 4 ms at both ends
  // of a window, which cancels in the relative motion up to the 0.8 mrad yaw it makes:
  // |(0.01, 0.5 * 0.0008)| = 0.010008 m/s.
  for (const auto& [g, e] : associate_poses(gt_read, est_read, 0.02)) {
    EXPECT_EQ(est_read[e].t_ns - gt_read[g].t_ns, 4'000'000) << "estimate " << e;
  }
  EXPECT_EQ(ate.trans_m.count, 90);
  EXPECT_FALSE(rpe.delta_clipped);
  EXPECT_GT(rpe.trans_mps.count, 50);
  EXPECT_NEAR(rpe.trans_mps.median, 0.010008, 1e-6);
  EXPECT_NEAR(rpe.trans_mps.max, 0.010008, 1e-6);
  EXPECT_NEAR(rpe.rot_degps.max, 0.0, 1e-5);
  // ATE: a straight line with a 2 % speed error leaves along-track errors 0.01 m/s (t - t_mean)
  // once the constant part is aligned away: RMSE 0.01 * std(t) over 90 stamps 33.33 ms apart,
  // and at most 0.01 * (89 * 30 ms) / 2.
  const double std_t_s = 0.03 * std::sqrt((90.0 * 90.0 - 1.0) / 12.0);
  EXPECT_NEAR(ate.trans_m.rmse, 0.01 * std_t_s, 1e-6);
  EXPECT_NEAR(ate.trans_m.max, 0.01 * 89 * 0.03 / 2, 1e-6);
}

}  // namespace
}  // namespace hq::evaluation
