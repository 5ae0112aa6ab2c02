#include "hq/estimator/velocity_estimator.hpp"

#include "hq/config/strict_yaml.hpp"

#include "hq/testing/allocation_counter.hpp"
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <array>
#include <cmath>

namespace hq::estimator {
namespace {

using ::testing::HasSubstr;

constexpr std::int64_t kImuNs = 5'000'000;  // 200 Hz IMU
constexpr int kImuPerFrame = 6;             // 33.3 Hz camera
constexpr double kDeg = M_PI / 180.0;

Eigen::Matrix3d rz(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).matrix(); }

// Camera looking 45 deg right and 30 deg down, optical frame (z forward, x right, y down).
Eigen::Matrix3d default_R_body_camera() {
  Eigen::Matrix3d R_forward_optical;
  R_forward_optical << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  return rz(45.0 * kDeg) * Eigen::AngleAxisd(-30.0 * kDeg, Eigen::Vector3d::UnitY()).matrix() *
         R_forward_optical;
}

// A rigid-body motion in the NED world N: fixed roll/pitch, yaw psi0 + yaw_rate t, constant
// velocity. Produces IMU samples and the odometry the camera would report (C0_T_Ck).
struct Motion {
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  double yaw0_rad = 0.0;
  double yaw_rate_radps = 0.0;
  Eigen::Vector3d v_ned_mps = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R_QC = default_R_body_camera();
  Eigen::Vector3d p_QC = Eigen::Vector3d(0.12, 0.06, 0.04);

  [[nodiscard]] Eigen::Matrix3d R_tilt() const { return R_horizontal_body(roll_rad, pitch_rad); }
  [[nodiscard]] double yaw(double t_s) const { return yaw0_rad + yaw_rate_radps * t_s; }
  [[nodiscard]] Eigen::Isometry3d T_ned_camera(double t_s) const {
    Eigen::Isometry3d T_NQ = Eigen::Isometry3d::Identity();
    T_NQ.linear() = rz(yaw(t_s)) * R_tilt();
    T_NQ.translation() = Eigen::Vector3d(1.0, 2.0, -1.5) + v_ned_mps * t_s;
    Eigen::Isometry3d T_QC = Eigen::Isometry3d::Identity();
    T_QC.linear() = R_QC;
    T_QC.translation() = p_QC;
    return T_NQ * T_QC;
  }
  [[nodiscard]] Eigen::Vector3d gyro() const {
    return R_tilt().transpose() * Eigen::Vector3d(0.0, 0.0, yaw_rate_radps);
  }
  [[nodiscard]] Eigen::Vector3d accel(double t_s) const {
    return -(rz(yaw(t_s)) * R_tilt()).transpose() * Eigen::Vector3d(0.0, 0.0, kGravityMps2);
  }
  [[nodiscard]] Eigen::Vector3d v_horizontal(double t_s) const {
    return rz(yaw(t_s)).transpose() * v_ned_mps;
  }
  [[nodiscard]] odometry::OdometryResult odometry_at(double t_s, std::int64_t t_ns,
                                                     bool first) const {
    odometry::OdometryResult result;
    result.status = first ? odometry::TrackingStatus::kFirstFrame : odometry::TrackingStatus::kOk;
    result.t_ns = t_ns;
    result.T_world_cur = T_ned_camera(0.0).inverse() * T_ned_camera(t_s);
    result.valid_ratio = 0.4;
    result.mean_weighted_error = 50.0;
    return result;
  }
};

// Runs the motion for duration_s and returns the last estimate.
VelocityEstimate run(VelocityEstimator& estimator, const Motion& motion, double duration_s) {
  VelocityEstimate last;
  const int steps = static_cast<int>(duration_s * 1e9 / kImuNs);
  for (int k = 0; k <= steps; ++k) {
    const std::int64_t t_ns = k * kImuNs;
    const double t_s = 1e-9 * static_cast<double>(t_ns);
    estimator.update_imu(t_ns, motion.gyro(), motion.accel(t_s));
    if (k % kImuPerFrame == 0) last = estimator.update(t_ns, motion.odometry_at(t_s, t_ns, k == 0));
  }
  return last;
}

TEST(VelocityEstimator, LeverArmTermCancelsThePureRotationOfTheBody) {
  // GIVEN a vehicle yawing at 1 rad/s about its centre, camera 0.14 m off the centre.
  Motion motion;
  motion.yaw_rate_radps = 1.0;
  VelocityEstimator estimator(VelocityEstimatorConfig{}, motion.R_QC, motion.p_QC);
  const VelocityEstimate estimate = run(estimator, motion, 3.0);
  ASSERT_TRUE(estimate.ok()) << estimate.reason;
  // THEN the camera itself moves at |omega x p_QC| ...
  const double camera_speed = (motion.R_QC * estimate.v_camera_mps).norm();
  const double lever_speed = motion.gyro().cross(motion.p_QC).norm();
  EXPECT_NEAR(camera_speed, lever_speed, 0.1 * lever_speed);
  // ... AND eq. 4 removes it: the body centre is still (measured 0.005 m/s of 0.134 m/s).
  EXPECT_LT(estimate.v_body_mps.norm(), 0.01) << estimate.v_body_mps.transpose();
  EXPECT_LT(estimate.v_horizontal_mps.norm(), 0.01);
  EXPECT_NEAR(estimate.omega_body_radps.z(), 1.0, 1e-6);
}

TEST(VelocityEstimator, ConstantVelocityCameraTrajectoryGivesTheRightHorizontalVelocity) {
  Motion motion;
  motion.yaw0_rad = 30.0 * kDeg;
  motion.v_ned_mps = Eigen::Vector3d(0.5, -0.3, -0.2);  // climbing: NED z < 0
  VelocityEstimator estimator(VelocityEstimatorConfig{}, motion.R_QC, motion.p_QC);
  const VelocityEstimate estimate = run(estimator, motion, 3.0);
  ASSERT_TRUE(estimate.ok()) << estimate.reason;
  EXPECT_LT((estimate.v_horizontal_mps - motion.v_horizontal(3.0)).norm(), 1e-3)
      << estimate.v_horizontal_mps.transpose() << " vs " << motion.v_horizontal(3.0).transpose();
  // The raw eq. 1 velocity is exact on a noise-free trajectory too.
  EXPECT_LT((motion.R_QC * estimate.v_camera_raw_mps - estimate.v_body_mps).norm(), 1e-6);
}

TEST(VelocityEstimator, Eq5RemovesRollAndPitchOfATiltedVehicle) {
  // GIVEN a vehicle rolled 8 deg and pitched -12 deg, flying level in H at constant speed.
  Motion motion;
  motion.roll_rad = 8.0 * kDeg;
  motion.pitch_rad = -12.0 * kDeg;
  motion.yaw0_rad = -60.0 * kDeg;
  motion.v_ned_mps = Eigen::Vector3d(0.4, 0.4, 0.0);
  VelocityEstimator estimator(VelocityEstimatorConfig{}, motion.R_QC, motion.p_QC);
  const VelocityEstimate estimate = run(estimator, motion, 3.0);
  ASSERT_TRUE(estimate.ok()) << estimate.reason;
  EXPECT_NEAR(estimate.roll_rad, motion.roll_rad, 1e-3);
  EXPECT_NEAR(estimate.pitch_rad, motion.pitch_rad, 1e-3);
  // THEN the body sees a vertical component, H does not.
  const Eigen::Vector3d v_body_true =
      (rz(motion.yaw(3.0)) * motion.R_tilt()).transpose() * motion.v_ned_mps;
  EXPECT_GT(std::abs(v_body_true.z()), 0.04);
  EXPECT_LT((estimate.v_body_mps - v_body_true).norm(), 2e-3);
  EXPECT_LT((estimate.v_horizontal_mps - motion.v_horizontal(3.0)).norm(), 2e-3)
      << estimate.v_horizontal_mps.transpose();
}

TEST(VelocityEstimator, RejectedOdometryIsUnavailableForAGrowingTime) {
  Motion motion;
  motion.v_ned_mps = Eigen::Vector3d(0.3, 0.0, 0.0);
  VelocityEstimator estimator(VelocityEstimatorConfig{}, motion.R_QC, motion.p_QC);
  const VelocityEstimate last_ok = run(estimator, motion, 1.0);
  ASSERT_TRUE(last_ok.ok());
  const std::int64_t t_last_ok_ns = last_ok.t_ns;

  double previous = 0.0;
  for (int i = 1; i <= 5; ++i) {
    const std::int64_t t_ns = t_last_ok_ns + i * kImuPerFrame * kImuNs;
    const double t_s = 1e-9 * static_cast<double>(t_ns);
    estimator.update_imu(t_ns, motion.gyro(), motion.accel(t_s));
    odometry::OdometryResult odometry = motion.odometry_at(t_s, t_ns, false);
    if (i % 2 == 0) {
      odometry.status = odometry::TrackingStatus::kLost;
    } else {
      odometry.valid_ratio = 0.01;
    }
    const VelocityEstimate estimate = estimator.update(t_ns, odometry);
    EXPECT_FALSE(estimate.ok());
    EXPECT_TRUE(estimate.v_horizontal_mps.isZero());
    EXPECT_NEAR(estimate.unavailable_for_s, 1e-9 * static_cast<double>(t_ns - t_last_ok_ns), 1e-9);
    EXPECT_GT(estimate.unavailable_for_s, previous);
    previous = estimate.unavailable_for_s;
    EXPECT_THAT(estimate.reason, HasSubstr(i % 2 == 0 ? "lost" : "valid_ratio"));
  }
  // Recovery re-seeds the pose filter: unavailable while it warms up, then close to the truth.
  const VelocityEstimatorConfig config;
  std::int64_t t_ns = t_last_ok_ns + 6 * kImuPerFrame * kImuNs;
  const std::int64_t t_seed_ns = t_ns;
  VelocityEstimate recovered;
  for (; !recovered.ok() && t_ns < t_seed_ns + 1'000'000'000; t_ns += kImuPerFrame * kImuNs) {
    estimator.update_imu(t_ns, motion.gyro(), motion.accel(1e-9 * t_ns));
    recovered = estimator.update(t_ns, motion.odometry_at(1e-9 * t_ns, t_ns, false));
    if (!recovered.ok()) {
      EXPECT_GT(recovered.unavailable_for_s, previous);
    }
  }
  ASSERT_TRUE(recovered.ok()) << recovered.reason;
  EXPECT_GE(1e-9 * static_cast<double>(recovered.t_ns - t_seed_ns), config.warmup_s);
  EXPECT_EQ(recovered.unavailable_for_s, 0.0);
  // First estimate after the 0.2 s warm-up: measured 0.284 m/s for the true 0.3.
  EXPECT_NEAR(recovered.v_horizontal_mps.x(), 0.3, 0.03);
}

TEST(VelocityEstimator, NoImuMeansUnavailable) {
  Motion motion;
  VelocityEstimatorConfig config;
  config.warmup_s = 0.0;
  VelocityEstimator estimator(config, motion.R_QC, motion.p_QC);
  estimator.update(0, motion.odometry_at(0.0, 0, true));
  const VelocityEstimate estimate = estimator.update(
      kImuPerFrame * kImuNs, motion.odometry_at(0.03, kImuPerFrame * kImuNs, false));
  EXPECT_FALSE(estimate.ok());
  EXPECT_STREQ(estimate.reason, "no IMU sample yet");
}

TEST(VelocityEstimator, UpdatesAllocateNothing) {
  Motion motion;
  motion.yaw_rate_radps = 0.5;
  motion.v_ned_mps = Eigen::Vector3d(0.2, 0.1, 0.0);
  VelocityEstimator estimator(VelocityEstimatorConfig{}, motion.R_QC, motion.p_QC);
  std::array<odometry::OdometryResult, 60> frames;
  for (int i = 0; i < 60; ++i) {
    frames[i] = motion.odometry_at(i * 0.03, i * kImuPerFrame * kImuNs, i == 0);
  }
  const long before = hq::testing::allocation_count();
  for (int i = 0; i < 60 * kImuPerFrame; ++i) {
    const std::int64_t t_ns = i * kImuNs;
    estimator.update_imu(t_ns, motion.gyro(), motion.accel(1e-9 * t_ns));
    if (i % kImuPerFrame == 0) estimator.update(t_ns, frames[i / kImuPerFrame]);
  }
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
}

TEST(VelocityEstimatorConfig, BadValueIsRejectedNamingTheKey) {
  const YAML::Node node =
      YAML::Load("{gyro_cutoff_hz: 20, one_euro_rotation: {beta: 1.0}, min_valid_ratio: 1.5}");
  config::StrictMap section(node, "config/onboard.yaml", "estimator");
  VelocityEstimatorConfig config;
  try {
    read_config(section, config);
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("config/onboard.yaml: estimator.min_valid_ratio = 1.5"));
  }
  const YAML::Node unknown = YAML::Load("{gyro_cutoff: 20}");
  config::StrictMap section2(unknown, "config/onboard.yaml", "estimator");
  EXPECT_THROW(read_config(section2, config), InputError);
}

TEST(VelocityEstimatorConfig, ShippedOnboardYamlSectionLoads) {
  const YAML::Node root = config::load_yaml_file("config/onboard.yaml");
  config::StrictMap section(root["estimator"], "config/onboard.yaml", "estimator");
  VelocityEstimatorConfig config;
  EXPECT_NO_THROW(read_config(section, config));
}

}  // namespace
}  // namespace hq::estimator
