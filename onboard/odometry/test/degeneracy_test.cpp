// What the scene leaves unmeasured: steps that keep the prediction along unobserved
// translations, and frames lost because their translation is not constrained.
#include "degeneracy.hpp"

#include <gtest/gtest.h>

namespace hq::odometry::detail {
namespace {

// Normal equations whose translation information is `translation` per axis (x, y, z) and whose
// rotation is well measured, decoupled, with a brightness offset of its own.
Matrix7d decoupled_system(const Eigen::Vector3d& translation) {
  Matrix7d A = Matrix7d::Identity() * 1e4;
  A.diagonal().head<3>() = translation;
  return A;
}

TEST(SolveRemapped, WithoutARatioIsThePlainSolve) {
  Matrix7d A = decoupled_system(Eigen::Vector3d(1e4, 2e4, 1e-3));
  A(0, 3) = A(3, 0) = 10.0;
  Vector7d b;
  b << 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0;
  const Vector7d expected = A.ldlt().solve(b);
  EXPECT_TRUE(solve_remapped(A, b, 0.0).isApprox(expected, 1e-12));
}

TEST(SolveRemapped, UnobservedTranslationKeepsThePrediction) {
  // z carries a millionth of x's information: the plain step along it is b_z / 1e-2 = 300.
  const Matrix7d A = decoupled_system(Eigen::Vector3d(1e4, 2e4, 1e-2));
  Vector7d b;
  b << 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0;
  const Vector7d plain = A.ldlt().solve(b);
  ASSERT_NEAR(plain(2), 300.0, 1e-9);
  const Vector7d remapped = solve_remapped(A, b, 1e-3);
  EXPECT_DOUBLE_EQ(remapped(2), 0.0);
  // The observed directions step as before.
  EXPECT_NEAR(remapped(0), plain(0), 1e-12);
  EXPECT_NEAR(remapped(1), plain(1), 1e-12);
  EXPECT_TRUE(remapped.tail<4>().isApprox(plain.tail<4>(), 1e-12));
}

TEST(SolveRemapped, TheBestTranslationDirectionAlwaysSteps) {
  // With the ratio at 1 every direction is "unobserved" against the best one, which still steps.
  const Matrix7d A = decoupled_system(Eigen::Vector3d(1e-6, 2e-6, 4e-6));
  const Vector7d b = Vector7d::Ones();
  const Vector7d remapped = solve_remapped(A, b, 1.0);
  EXPECT_DOUBLE_EQ(remapped(0), 0.0);
  EXPECT_DOUBLE_EQ(remapped(1), 0.0);
  EXPECT_NEAR(remapped(2), 1.0 / 4e-6, 1e-3);
}

NormalEquations with_translation_information(const Eigen::Vector3d& translation) {
  NormalEquations normal;
  normal.H = Matrix6d::Identity() * 1e8;
  normal.H.diagonal().head<3>() = translation;
  return normal;
}

TEST(TranslationUnconstrained, WellMeasuredTranslationIsKept) {
  OdometryConfig config;
  // sigma = 1 / sqrt(scale x information): 1 cm under the 2 cm bound.
  const double information = 1.0 / (config.vision_information_scale * 0.01 * 0.01);
  EXPECT_FALSE(translation_unconstrained(
      with_translation_information(Eigen::Vector3d::Constant(information)), config));
}

TEST(TranslationUnconstrained, DirectionBeyondTheSigmaBoundIsLost) {
  OdometryConfig config;
  const double good = 1.0 / (config.vision_information_scale * 0.01 * 0.01);
  const double loose = 1.0 / (config.vision_information_scale * 0.03 * 0.03);  // 3 cm
  EXPECT_TRUE(translation_unconstrained(
      with_translation_information(Eigen::Vector3d(good, loose, good)), config));
}

TEST(TranslationUnconstrained, SingularInformationIsLost) {
  EXPECT_TRUE(translation_unconstrained(
      with_translation_information(Eigen::Vector3d(1e8, 1e8, 0.0)), OdometryConfig{}));
}

TEST(TranslationUnconstrained, TheBrightnessOffsetIsMarginalisedOut) {
  // The offset's column duplicates the x translation's: alone, x is measured; with the offset
  // estimated, nothing tells them apart.
  OdometryConfig config;
  NormalEquations normal = with_translation_information(Eigen::Vector3d::Constant(1e8));
  normal.H_pose_offset = Vector6d::Zero();
  normal.H_pose_offset(0) = 1e8;
  normal.H_offset = 1e8;
  config.estimate_brightness_offset = false;
  EXPECT_FALSE(translation_unconstrained(normal, config));
  config.estimate_brightness_offset = true;
  EXPECT_TRUE(translation_unconstrained(normal, config));
}

TEST(TranslationInformationTooWeak, ComparesWithTheDepthRowsBestDirection) {
  NormalEquations normal = with_translation_information(Eigen::Vector3d(100.0, 100.0, 0.5));
  normal.H_depth_translation = Eigen::Matrix3d::Identity() * 100.0;
  EXPECT_TRUE(translation_information_too_weak(normal, 0.01));    // 0.5 < 1
  EXPECT_FALSE(translation_information_too_weak(normal, 0.001));  // 0.5 > 0.1
  EXPECT_FALSE(translation_information_too_weak(normal, 0.0));    // off
}

}  // namespace
}  // namespace hq::odometry::detail
