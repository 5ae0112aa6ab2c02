// The gyro fusion alone: the bias filter, the chain of gyro steps since the reference, the
// prior's weight against the vision, and what a vision rotation says about the bias.
#include "gyro_fusion.hpp"

#include "hq/geometry/lie.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace hq::odometry::detail {
namespace {

RotationPrior gyro_step(const Eigen::Vector3d& rotation_rad, double information) {
  RotationPrior prior;
  prior.R_prev_cur = geometry::exp_so3(rotation_rad);
  prior.information = Eigen::Matrix3d::Identity() * information;
  return prior;
}

TEST(GyroBiasFilter, ConstantBiasIsLearntFromRepeatedObservations) {
  GyroBiasFilter filter;
  filter.reset(0.005);
  const Eigen::Vector3d bias(0.004, -0.002, 0.003);
  const Eigen::Matrix3d noise = Eigen::Matrix3d::Identity() * 1e-6;
  for (int k = 0; k < 50; ++k) {
    ASSERT_TRUE(filter.update(bias - filter.bias(), noise, 16.27));
  }
  EXPECT_LT((filter.bias() - bias).norm(), 1e-4);
  // Each observation shrinks the uncertainty below the initial 0.005^2 per axis.
  EXPECT_LT(filter.covariance().trace(), 3.0 * 0.005 * 0.005 / 10.0);
}

TEST(GyroBiasFilter, ObservationBeyondTheGateTeachesNothing) {
  GyroBiasFilter filter;
  filter.reset(0.005);
  const Eigen::Matrix3d noise = Eigen::Matrix3d::Identity() * 1e-6;
  EXPECT_FALSE(filter.update(Eigen::Vector3d(1.0, 0.0, 0.0), noise, 16.27));
  EXPECT_FALSE(filter.update(Eigen::Vector3d::Constant(std::nan("")), noise, 16.27));
  EXPECT_EQ(filter.bias(), Eigen::Vector3d::Zero());
}

TEST(GyroBiasFilter, RandomWalkGrowsTheUncertaintyWithTime) {
  GyroBiasFilter filter;
  filter.reset(0.005);
  filter.propagate(0, 0.01);
  const double before = filter.covariance()(0, 0);
  filter.propagate(4'000'000'000, 0.01);  // 4 s: variance grows by 0.01^2 x 4
  EXPECT_NEAR(filter.covariance()(0, 0) - before, 4e-4, 1e-12);
  filter.propagate(1'000'000'000, 0.01);  // back in time: nothing
  EXPECT_NEAR(filter.covariance()(0, 0) - before, 4e-4, 1e-12);
}

TEST(GyroFusion, StepsChainSinceTheReference) {
  OdometryConfig config;
  GyroFusion fusion(config);
  const RotationPrior first = gyro_step(Eigen::Vector3d(0.0, 0.0, 0.02), 1e6);
  const RotationPrior second = gyro_step(Eigen::Vector3d(0.01, 0.0, 0.0), 1e6);
  GyroSteps a;
  ASSERT_TRUE(fusion.steps(first, 0.033, a));
  fusion.keep_chain(&a);
  GyroSteps b;
  ASSERT_TRUE(fusion.steps(second, 0.033, b));
  // No bias estimate yet: the steps are the gyro's, the chain their product.
  EXPECT_TRUE(b.R_prev_cur.isApprox(second.R_prev_cur, 1e-12));
  EXPECT_TRUE(b.chain.R_ref_cur.isApprox(first.R_prev_cur * second.R_prev_cur, 1e-12));
  EXPECT_NEAR(b.chain.span_s, 0.066, 1e-12);
  // The bias still unknown is the same in every step: the chain's share grows with span^2.
  const double bias_variance = config.gyro_bias_sigma_radps * config.gyro_bias_sigma_radps;
  EXPECT_NEAR(b.chain_covariance.trace(), 3.0 * (2e-6 + bias_variance * 0.066 * 0.066), 1e-12);
  EXPECT_NEAR(b.step_covariance.trace(), 3.0 * (1e-6 + bias_variance * 0.033 * 0.033), 1e-12);

  fusion.restart_chain();
  GyroSteps c;
  ASSERT_TRUE(fusion.steps(second, 0.033, c));
  EXPECT_NEAR(c.chain.span_s, 0.033, 1e-12);
}

TEST(GyroFusion, FrameWithoutGyroBreaksTheChainUntilTheNextReference) {
  GyroFusion fusion(OdometryConfig{});
  fusion.keep_chain(nullptr);
  GyroSteps steps;
  EXPECT_FALSE(fusion.steps(gyro_step(Eigen::Vector3d(0.0, 0.0, 0.01), 1e6), 0.033, steps));
  fusion.restart_chain();
  EXPECT_TRUE(fusion.steps(gyro_step(Eigen::Vector3d(0.0, 0.0, 0.01), 1e6), 0.033, steps));
}

TEST(GyroFusion, PriorWithoutUsableInformationIsNoStep) {
  GyroFusion fusion(OdometryConfig{});
  GyroSteps steps;
  EXPECT_FALSE(fusion.steps(gyro_step(Eigen::Vector3d::Zero(), 0.0), 0.033, steps));
  EXPECT_FALSE(fusion.steps(gyro_step(Eigen::Vector3d::Zero(), -1.0), 0.033, steps));
  RotationPrior nan_prior = gyro_step(Eigen::Vector3d::Zero(), 1e6);
  nan_prior.R_prev_cur(0, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(fusion.steps(nan_prior, 0.033, steps));
  EXPECT_FALSE(fusion.steps(gyro_step(Eigen::Vector3d::Zero(), 1e6), 0.0, steps));
}

TEST(GyroFusion, PriorIsWeighedAgainstTheVisionsHonestScale) {
  OdometryConfig config;
  config.vision_information_scale = 0.04;
  config.rotation_prior_information_scale = 2.0;
  const GyroFusion fusion(config);
  const Eigen::Matrix3d covariance = Eigen::Vector3d(1e-4, 2e-4, 4e-4).asDiagonal();
  const Eigen::Matrix3d expected = (2.0 / 0.04) * covariance.inverse();
  EXPECT_TRUE(fusion.prior_information(covariance).isApprox(expected, 1e-12));
}

// A vision rotation that differs from the gyro chain by e over span_s says the bias left over
// is about -R^T e / span_s.
TEST(GyroFusion, VisionAgainstTheChainObservesTheBias) {
  OdometryConfig config;
  GyroFusion fusion(config);
  GyroSteps steps;
  ASSERT_TRUE(fusion.steps(gyro_step(Eigen::Vector3d(0.0, 0.0, 0.05), 1e6), 0.5, steps));
  const Eigen::Vector3d e(0.0, 0.002, 0.0);
  const Eigen::Matrix3d R_ref_cur_vision = geometry::exp_so3(e) * steps.chain.R_ref_cur;
  Eigen::Isometry3d T_cur_ref_vision = Eigen::Isometry3d::Identity();
  T_cur_ref_vision.linear() = R_ref_cur_vision.transpose();
  NormalEquations vision;
  vision.H = Matrix6d::Identity() * 1e8;
  GyroObservation observation;
  ASSERT_TRUE(fusion.observe(T_cur_ref_vision, vision, steps.chain.R_ref_cur, steps, observation));
  const Eigen::Vector3d expected = -steps.chain.R_ref_cur.transpose() * e / 0.5;
  EXPECT_LT((observation.bias_innovation - expected).norm(), 1e-9);
  EXPECT_DOUBLE_EQ(observation.span_s, 0.5);

  // Learnt: the estimate moves towards the observed bias, and the next step is corrected by it.
  fusion.learn(observation, true);
  EXPECT_GT(fusion.bias().dot(expected), 0.0);
  EXPECT_EQ(fusion.vision_scale(), config.vision_information_scale);  // not adapting
}

TEST(GyroFusion, VisionThatCannotSayObservesNothing) {
  GyroFusion fusion(OdometryConfig{});
  GyroSteps steps;
  ASSERT_TRUE(fusion.steps(gyro_step(Eigen::Vector3d(0.0, 0.0, 0.05), 1e6), 0.5, steps));
  GyroObservation observation;
  NormalEquations not_information;
  not_information.H = -Matrix6d::Identity();
  EXPECT_FALSE(fusion.observe(Eigen::Isometry3d::Identity(), not_information, steps.chain.R_ref_cur,
                              steps, observation));
  NormalEquations vision;
  vision.H = Matrix6d::Identity() * 1e8;
  Eigen::Isometry3d not_finite = Eigen::Isometry3d::Identity();
  not_finite.linear()(0, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(fusion.observe(not_finite, vision, steps.chain.R_ref_cur, steps, observation));
}

TEST(GyroFusion, AdaptedScaleFollowsTheObservedOverconfidence) {
  OdometryConfig config;
  config.adapt_vision_information = true;
  GyroFusion fusion(config);
  GyroObservation observation;
  observation.overconfidence = 100.0;
  fusion.learn(observation, false);
  // One sample: the scale is the chi-square(3) geometric mean over it.
  EXPECT_NEAR(fusion.vision_scale(), 0.6915 / 100.0, 1e-12);
  fusion.reset();
  EXPECT_EQ(fusion.vision_scale(), config.vision_information_scale);
}

}  // namespace
}  // namespace hq::odometry::detail
