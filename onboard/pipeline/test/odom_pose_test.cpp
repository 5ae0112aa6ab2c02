// The odom pose's dead reckoning: v_H turned by the gyro's integrated yaw, its uncertainty
// growing with distance and time, standing on the floor, growing blind without an estimate.
#include "hq/pipeline/odom_pose.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace hq::pipeline {
namespace {

constexpr std::int64_t kStep_ns = 10'000'000;  // 100 Hz

estimator::VelocityEstimate moving(const Eigen::Vector3d& v_H_mps, double sigma_mps) {
  estimator::VelocityEstimate e;
  e.status = estimator::EstimateStatus::kOk;
  e.v_H_mps = v_H_mps;
  e.v_H_covariance = Eigen::Matrix3d::Identity() * sigma_mps * sigma_mps;
  return e;
}

// Steps both inputs for `seconds` from t_ns; returns the time reached.
std::int64_t fly(OdomPose& odom, std::int64_t t_ns, double seconds, double yaw_rate_radps,
                 const estimator::VelocityEstimate& estimate, bool landed = false) {
  const auto steps = static_cast<int>(std::lround(seconds * 1e9 / kStep_ns));
  for (int i = 0; i < steps; ++i) {
    t_ns += kStep_ns;
    odom.on_yaw_rate(t_ns, yaw_rate_radps);
    odom.on_estimate(t_ns, estimate, landed);
  }
  return t_ns;
}

TEST(OdomPose, IntegratesTheVelocityInTheFrameOfTheStartHeading) {
  OdomPose odom;
  odom.on_yaw_rate(0, 0.0);
  odom.on_estimate(0, moving(Eigen::Vector3d::Zero(), 0.0), true);
  // 2 s forward at 0.5 m/s, a quarter turn right on the spot, 2 s "forward" again, climbing.
  std::int64_t t = fly(odom, 0, 2.0, 0.0, moving({0.5, 0.0, 0.0}, 0.02));
  t = fly(odom, t, 1.0, M_PI / 2.0, moving(Eigen::Vector3d::Zero(), 0.02));
  fly(odom, t, 2.0, 0.0, moving({0.5, 0.0, -0.1}, 0.02));
  const OdomPoseEstimate& p = odom.pose();
  EXPECT_TRUE(p.valid);
  EXPECT_TRUE(p.yaw_relative_to_start);
  EXPECT_NEAR(p.yaw_rad, M_PI / 2.0, 1e-9);
  // Forward then, after turning right (NED: +yaw), along odom's +y; z down, so the climb is -.
  EXPECT_NEAR(p.p_odom_m.x(), 1.0, 1e-6);
  EXPECT_NEAR(p.p_odom_m.y(), 1.0, 1e-6);
  EXPECT_NEAR(p.p_odom_m.z(), -0.2, 1e-6);
}

TEST(OdomPose, UncertaintyGrowsWithDistanceAndTimeAndStandsOnTheFloor) {
  OdomPoseConfig config;
  OdomPose odom(config);
  odom.on_yaw_rate(0, 0.0);  // the clocks start here
  odom.on_estimate(0, moving(Eigen::Vector3d::Zero(), 0.0), true);
  std::int64_t t = fly(odom, 0, 5.0, 0.0, moving(Eigen::Vector3d::Zero(), 0.0), true);
  EXPECT_DOUBLE_EQ(odom.pose().position_sigma_m, 0.0);  // on the floor: known to stand still
  EXPECT_NEAR(odom.pose().yaw_sigma_rad, 5.0 * config.yaw_drift_radps, 1e-9);
  t = fly(odom, t, 10.0, 0.0, moving({1.0, 0.0, 0.0}, 0.0));
  // Noise-free velocity: the systematic part alone, fraction and yaw's sigma (its mean over the
  // leg, from 5 s to 15 s of drift) times 10 m.
  const double yaw_sigma_mean = (5.0 + 15.0) / 2.0 * config.yaw_drift_radps;
  EXPECT_NEAR(odom.pose().position_sigma_m,
              10.0 * (config.velocity_error_fraction + yaw_sigma_mean), 1e-3);
  const double after_leg = odom.pose().position_sigma_m;
  // Hovering with a noisy velocity: the random part grows as sqrt(2 tau sigma^2 t).
  fly(odom, t, 10.0, 0.0, moving(Eigen::Vector3d::Zero(), 0.05));
  const double random =
      std::sqrt(2.0 * config.velocity_error_correlation_s * 2.0 * 0.05 * 0.05 * 10.0);
  EXPECT_NEAR(odom.pose().position_sigma_m, after_leg + random, 1e-3);
}

TEST(OdomPose, WithoutAnEstimateThePositionStandsAndItsSigmaGrowsBlind) {
  OdomPoseConfig config;
  OdomPose odom(config);
  std::int64_t t = fly(odom, 0, 1.0, 0.0, moving({0.5, 0.0, 0.0}, 0.0));
  const Eigen::Vector3d before = odom.pose().p_odom_m;
  const double sigma_before = odom.pose().position_sigma_m;
  estimator::VelocityEstimate lost;  // kUnavailable
  lost.v_H_mps = {3.0, 3.0, 3.0};    // whatever it says, it is not used
  t = fly(odom, t, 2.0, 0.0, lost);
  EXPECT_EQ(odom.pose().p_odom_m, before);
  EXPECT_NEAR(odom.pose().position_sigma_m, sigma_before + 2.0 * config.blind_drift_mps, 1e-6);
  // Non-finite inputs change nothing but the clocks.
  estimator::VelocityEstimate nan = moving({std::nan(""), 0.0, 0.0}, 0.0);
  nan.status = estimator::EstimateStatus::kOk;
  const double yaw = odom.pose().yaw_rad;
  t += kStep_ns;
  odom.on_yaw_rate(t, std::numeric_limits<double>::quiet_NaN());
  odom.on_estimate(t, nan, false);
  EXPECT_EQ(odom.pose().p_odom_m, before);
  EXPECT_DOUBLE_EQ(odom.pose().yaw_rad, yaw);
}

TEST(OdomPose, InvalidUntilItHasSomethingToStartFrom) {
  OdomPose odom;
  EXPECT_FALSE(odom.pose().valid);
  odom.on_estimate(0, estimator::VelocityEstimate{}, false);  // airborne, no estimate
  EXPECT_FALSE(odom.pose().valid);
  odom.on_estimate(kStep_ns, moving(Eigen::Vector3d::Zero(), 0.01), false);
  EXPECT_TRUE(odom.pose().valid);
}

}  // namespace
}  // namespace hq::pipeline
