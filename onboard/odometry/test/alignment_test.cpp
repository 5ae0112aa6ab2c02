// The Gauss-Newton alignment alone, against a prepared reference of the rendered plane.
#include "alignment.hpp"

#include "hq/geometry/lie.hpp"

#include "prepared_plane.hpp"
#include <gtest/gtest.h>

namespace hq::odometry::detail {
namespace {

using test::pose;
using test::PreparedPlane;

double rotation_between_rad(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return geometry::log_so3(a.transpose() * b).norm();
}

class AlignmentTest : public ::testing::TestWithParam<bool> {};

TEST_P(AlignmentTest, KnownMotionIsRecoveredFromIdentity) {
  OdometryConfig config;
  config.use_depth_term = GetParam();
  PreparedPlane plane(config);
  // GIVEN a reference and a current frame 1.4 cm and 0.5 deg apart over the plane 2 m away
  const Eigen::Isometry3d T_G_ref = pose(0.02, 0.01, 0.0, 0.01, 0.0, 0.0);
  const Eigen::Isometry3d T_G_cur = T_G_ref * pose(0.01, -0.006, 0.008, 0.004, -0.005, 0.007);
  plane.prepare_reference(T_G_ref);
  plane.build_current(T_G_cur);
  Aligner aligner(config, plane.cameras);
  // WHEN aligned from the identity without priors
  const Alignment a =
      aligner.align(plane.reference, plane.current, Eigen::Isometry3d::Identity(), Prediction{});
  // THEN the pose is the true one to a millimetre and a twentieth of a degree
  const Eigen::Isometry3d T_cur_ref = T_G_cur.inverse() * T_G_ref;
  EXPECT_LT((a.T_cur_ref.translation() - T_cur_ref.translation()).norm(), 1e-3);
  EXPECT_LT(rotation_between_rad(a.T_cur_ref.linear(), T_cur_ref.linear()), 1e-3);
  EXPECT_GT(a.valid, 1000);
  EXPECT_GT(a.iterations, 1);
  EXPECT_TRUE(a.normal.H.allFinite());
  EXPECT_GT(a.normal.H.determinant(), 0.0);
  EXPECT_EQ(a.normal.H_depth_translation.isZero(), !config.use_depth_term);
}

INSTANTIATE_TEST_SUITE_P(IntensityAloneAndWithDepth, AlignmentTest, ::testing::Bool());

TEST(Aligner, IdenticalFramesStayAtTheIdentityWithSmallResiduals) {
  const OdometryConfig config;
  PreparedPlane plane(config);
  plane.prepare_reference(pose(0.0, 0.0, 0.0, 0.0, 0.0, 0.0));
  plane.build_current(pose(0.0, 0.0, 0.0, 0.0, 0.0, 0.0));
  Aligner aligner(config, plane.cameras);
  const Alignment a =
      aligner.align(plane.reference, plane.current, Eigen::Isometry3d::Identity(), Prediction{});
  EXPECT_LT(a.T_cur_ref.translation().norm(), 1e-4);
  EXPECT_LT(geometry::log_so3(a.T_cur_ref.linear()).norm(), 1e-4);
  EXPECT_LT(a.weighted_error, 1.0);  // grey levels^2: only the renderer's rounding remains
}

TEST(Aligner, StrongGyroPriorHoldsTheRotation) {
  const OdometryConfig config;
  PreparedPlane plane(config);
  const Eigen::Isometry3d T_G_cur = pose(0.005, 0.0, 0.0, 0.0, 0.0, 0.01);
  plane.prepare_reference(Eigen::Isometry3d::Identity());
  plane.build_current(T_G_cur);
  Aligner aligner(config, plane.cameras);
  // A prior 1 degree away from the truth, about 10^6 times the data term's information.
  Prediction p;
  p.use_prior = true;
  p.R_ref_prior = T_G_cur.linear() * geometry::exp_so3(Eigen::Vector3d(0.0, 0.0, 0.0175));
  p.prior_information = Eigen::Matrix3d::Identity() * 1e14;
  p.T_ref_predicted.linear() = p.R_ref_prior;
  const Alignment held =
      aligner.align(plane.reference, plane.current, p.T_ref_predicted.inverse(), p);
  EXPECT_LT(rotation_between_rad(held.T_cur_ref.linear().transpose(), p.R_ref_prior), 1e-4);
  // The vision alone, from there, finds its own rotation back.
  const Alignment vision = aligner.vision_only(plane.reference, plane.current, held);
  EXPECT_LT(rotation_between_rad(vision.T_cur_ref.linear().transpose(), T_G_cur.linear()),
            rotation_between_rad(held.T_cur_ref.linear().transpose(), T_G_cur.linear()));
}

TEST(Aligner, FinestResidualsMarkEveryVisiblePoint) {
  const OdometryConfig config;
  PreparedPlane plane(config);
  plane.prepare_reference(Eigen::Isometry3d::Identity());
  plane.build_current(Eigen::Isometry3d::Identity());
  Aligner aligner(config, plane.cameras);
  Alignment at_truth;
  aligner.finest_residuals(plane.reference, plane.current, at_truth);
  const ReferenceLevel& finest = at_level(plane.reference, config.finest_level);
  int with_residual = 0;
  for (int i = 0; i < finest.count; ++i) {
    const auto k = static_cast<std::size_t>(i);
    with_residual += aligner.masks()[k] > 0.0f ? 1 : 0;
    EXPECT_LT(std::abs(aligner.residuals()[k]), 2.0f);
  }
  // Every textured point lands in the image but those within a pixel of its last row/column.
  EXPECT_GT(with_residual, finest.count * 95 / 100);
}

}  // namespace
}  // namespace hq::odometry::detail
