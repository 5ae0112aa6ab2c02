#include "hq/estimator/velocity_estimator.hpp"

#include "hq/base/monotonic_clock.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <fmt/format.h>
#include <utility>
#include <vector>

namespace hq::estimator {
namespace {

using ::testing::HasSubstr;

constexpr std::int64_t kImuNs = 5'000'000;  // 200 Hz IMU
constexpr int kImuPerFrame = 6;             // 33.3 Hz camera
constexpr double kDeg = M_PI / 180.0;

Eigen::Matrix3d rz(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).matrix(); }

// Camera looking 45 deg right and 30 deg down, optical frame (z forward, x right, y down).
Eigen::Matrix3d default_R_B_C() {
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
  Eigen::Matrix3d R_B_C = default_R_B_C();
  Eigen::Vector3d p_B_C_m = Eigen::Vector3d(0.12, 0.06, 0.04);

  [[nodiscard]] Eigen::Matrix3d R_tilt() const { return R_H_B_from_tilt(roll_rad, pitch_rad); }
  [[nodiscard]] double yaw(double t_s) const { return yaw0_rad + yaw_rate_radps * t_s; }
  [[nodiscard]] Eigen::Isometry3d T_ned_camera(double t_s) const {
    Eigen::Isometry3d T_ned_B = Eigen::Isometry3d::Identity();
    T_ned_B.linear() = rz(yaw(t_s)) * R_tilt();
    T_ned_B.translation() = Eigen::Vector3d(1.0, 2.0, -1.5) + v_ned_mps * t_s;
    Eigen::Isometry3d T_B_C = Eigen::Isometry3d::Identity();
    T_B_C.linear() = R_B_C;
    T_B_C.translation() = p_B_C_m;
    return T_ned_B * T_B_C;
  }
  [[nodiscard]] Eigen::Vector3d gyro() const {
    return R_tilt().transpose() * Eigen::Vector3d(0.0, 0.0, yaw_rate_radps);
  }
  [[nodiscard]] Eigen::Vector3d accel(double t_s) const {
    return -(rz(yaw(t_s)) * R_tilt()).transpose() * Eigen::Vector3d(0.0, 0.0, kGravityMps2);
  }
  [[nodiscard]] Eigen::Vector3d v_H(double t_s) const {
    return rz(yaw(t_s)).transpose() * v_ned_mps;
  }
  [[nodiscard]] odometry::OdometryResult odometry_at(double t_s, std::int64_t t_ns,
                                                     bool first) const {
    odometry::OdometryResult result;
    result.status = first ? odometry::TrackingStatus::kFirstFrame : odometry::TrackingStatus::kOk;
    result.t_ns = t_ns;
    result.T_O_C = T_ned_camera(0.0).inverse() * T_ned_camera(t_s);
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
    const double t_s = hq::to_seconds(t_ns);
    estimator.update_imu(t_ns, motion.gyro(), motion.accel(t_s));
    if (k % kImuPerFrame == 0) last = estimator.update(t_ns, motion.odometry_at(t_s, t_ns, k == 0));
  }
  return last;
}

TEST(VelocityEstimator, LeverArmTermCancelsThePureRotationOfTheBody) {
  // GIVEN a vehicle yawing at 1 rad/s about its centre, camera 0.14 m off the centre.
  Motion motion;
  motion.yaw_rate_radps = 1.0;
  VelocityEstimator estimator(VelocityEstimatorConfig{}, motion.R_B_C, motion.p_B_C_m);
  const VelocityEstimate estimate = run(estimator, motion, 3.0);
  ASSERT_TRUE(estimate.ok()) << estimate.reason;
  // THEN the camera itself moves at |omega x p_B_C_m| ...
  const double camera_speed = (motion.R_B_C * estimate.v_C_mps).norm();
  const double lever_speed = motion.gyro().cross(motion.p_B_C_m).norm();
  EXPECT_NEAR(camera_speed, lever_speed, 0.1 * lever_speed);
  // ... AND eq. 4 removes it: the body centre is still (measured 0.005 m/s of 0.134 m/s).
  EXPECT_LT(estimate.v_B_mps.norm(), 0.01) << estimate.v_B_mps.transpose();
  EXPECT_LT(estimate.v_H_mps.norm(), 0.01);
  EXPECT_NEAR(estimate.omega_B_radps.z(), 1.0, 1e-6);
}

TEST(VelocityEstimator, ConstantVelocityCameraTrajectoryGivesTheRightHorizontalVelocity) {
  Motion motion;
  motion.yaw0_rad = 30.0 * kDeg;
  motion.v_ned_mps = Eigen::Vector3d(0.5, -0.3, -0.2);  // climbing: NED z < 0
  VelocityEstimator estimator(VelocityEstimatorConfig{}, motion.R_B_C, motion.p_B_C_m);
  const VelocityEstimate estimate = run(estimator, motion, 3.0);
  ASSERT_TRUE(estimate.ok()) << estimate.reason;
  EXPECT_LT((estimate.v_H_mps - motion.v_H(3.0)).norm(), 1e-3)
      << estimate.v_H_mps.transpose() << " vs " << motion.v_H(3.0).transpose();
  // The raw eq. 1 velocity is exact on a noise-free trajectory too.
  const Eigen::Vector3d true_v_C = motion.T_ned_camera(3.0).linear().transpose() * motion.v_ned_mps;
  EXPECT_LT((estimate.v_C_raw_mps - true_v_C).norm(), 1e-9);
}

TEST(VelocityEstimator, Eq5RemovesRollAndPitchOfATiltedVehicle) {
  // GIVEN a vehicle rolled 8 deg and pitched -12 deg, flying level in H at constant speed.
  Motion motion;
  motion.roll_rad = 8.0 * kDeg;
  motion.pitch_rad = -12.0 * kDeg;
  motion.yaw0_rad = -60.0 * kDeg;
  motion.v_ned_mps = Eigen::Vector3d(0.4, 0.4, 0.0);
  VelocityEstimator estimator(VelocityEstimatorConfig{}, motion.R_B_C, motion.p_B_C_m);
  const VelocityEstimate estimate = run(estimator, motion, 3.0);
  ASSERT_TRUE(estimate.ok()) << estimate.reason;
  EXPECT_NEAR(estimate.roll_rad, motion.roll_rad, 1e-3);
  EXPECT_NEAR(estimate.pitch_rad, motion.pitch_rad, 1e-3);
  // THEN the body sees a vertical component, H does not.
  const Eigen::Vector3d v_B_true =
      (rz(motion.yaw(3.0)) * motion.R_tilt()).transpose() * motion.v_ned_mps;
  EXPECT_GT(std::abs(v_B_true.z()), 0.04);
  EXPECT_LT((estimate.v_B_mps - v_B_true).norm(), 2e-3);
  EXPECT_LT((estimate.v_H_mps - motion.v_H(3.0)).norm(), 2e-3) << estimate.v_H_mps.transpose();
}

TEST(VelocityEstimator, RejectedOdometryIsUnavailableForAGrowingTime) {
  Motion motion;
  motion.v_ned_mps = Eigen::Vector3d(0.3, 0.0, 0.0);
  VelocityEstimator estimator(VelocityEstimatorConfig{}, motion.R_B_C, motion.p_B_C_m);
  const VelocityEstimate last_ok = run(estimator, motion, 1.0);
  ASSERT_TRUE(last_ok.ok());
  const std::int64_t t_last_ok_ns = last_ok.t_ns;

  double previous = 0.0;
  for (int i = 1; i <= 5; ++i) {
    const std::int64_t t_ns = t_last_ok_ns + i * kImuPerFrame * kImuNs;
    const double t_s = hq::to_seconds(t_ns);
    estimator.update_imu(t_ns, motion.gyro(), motion.accel(t_s));
    odometry::OdometryResult odometry = motion.odometry_at(t_s, t_ns, false);
    if (i % 2 == 0) {
      odometry.status = odometry::TrackingStatus::kLost;
    } else {
      odometry.valid_ratio = 0.01;
    }
    const VelocityEstimate estimate = estimator.update(t_ns, odometry);
    EXPECT_FALSE(estimate.ok());
    // Within inertial_coast_s (0.15 s of 2 s) the estimate coasts on the IMU from the last good
    // value instead of going to zero; the motion has no acceleration, so it stays there.
    EXPECT_EQ(estimate.status, EstimateStatus::kInertial);
    EXPECT_TRUE(estimate.usable());
    EXPECT_LT((estimate.v_H_mps - last_ok.v_H_mps).norm(), 2e-3) << estimate.v_H_mps.transpose();
    EXPECT_NEAR(estimate.unavailable_for_s, hq::to_seconds(t_ns - t_last_ok_ns), 1e-9);
    EXPECT_GT(estimate.unavailable_for_s, previous);
    previous = estimate.unavailable_for_s;
    EXPECT_THAT(estimate.reason, HasSubstr(i % 2 == 0 ? "lost" : "valid_ratio"));
  }
  // Recovery re-seeds the pose filter; the fused velocity needs no warm-up, only a second
  // frame that agrees (reacquire_frames), and is then close to the truth.
  const VelocityEstimatorConfig config;
  std::int64_t t_ns = t_last_ok_ns + 6 * kImuPerFrame * kImuNs;
  const std::int64_t t_seed_ns = t_ns;
  VelocityEstimate recovered;
  for (; !recovered.ok() && t_ns < t_seed_ns + 1'000'000'000; t_ns += kImuPerFrame * kImuNs) {
    estimator.update_imu(t_ns, motion.gyro(), motion.accel(hq::to_seconds(t_ns)));
    recovered = estimator.update(t_ns, motion.odometry_at(hq::to_seconds(t_ns), t_ns, false));
    if (!recovered.ok()) {
      EXPECT_GT(recovered.unavailable_for_s, previous);
    }
  }
  ASSERT_TRUE(recovered.ok()) << recovered.reason;
  const double frame_s = hq::to_seconds(kImuPerFrame * kImuNs);
  EXPECT_NEAR(hq::to_seconds(recovered.t_ns - t_seed_ns), config.reacquire_frames * frame_s, 1e-9);
  EXPECT_EQ(recovered.unavailable_for_s, 0.0);
  EXPECT_NEAR(recovered.v_H_mps.x(), 0.3, 0.005);
  // With the 1-euro output (the core paper's eq. 2 as it is) the filter's 0.2 s warm-up comes
  // first, and its first velocity reads low: measured 0.284 m/s for the true 0.3.
  VelocityEstimatorConfig one_euro;
  one_euro.velocity_output = VelocityEstimatorConfig::VelocityOutput::kOneEuro;
  VelocityEstimator paper(one_euro, motion.R_B_C, motion.p_B_C_m);
  const VelocityEstimate paper_ok = run(paper, motion, 0.5);
  ASSERT_TRUE(paper_ok.ok()) << paper_ok.reason;
  EXPECT_NEAR(paper_ok.v_H_mps.x(), 0.3, 0.03);
  EXPECT_EQ(paper_ok.v_H_mps, paper_ok.v_H_one_euro_mps);
}

TEST(VelocityEstimator, FusedVelocityHasNoLagWhereTheOneEuroLags) {
  // GIVEN a level vehicle hovering for 1 s, then accelerating along north at 2 m/s^2 for
  // 0.4 s, seen by both the odometry and the accelerometer
  const Motion motion;
  constexpr double kStartS = 1.0;
  const auto moving_s = [](double t_s) { return std::max(0.0, t_s - kStartS); };
  for (const auto output : {VelocityEstimatorConfig::VelocityOutput::kFused,
                            VelocityEstimatorConfig::VelocityOutput::kOneEuro}) {
    VelocityEstimatorConfig config;
    config.velocity_output = output;
    VelocityEstimator estimator(config, motion.R_B_C, motion.p_B_C_m);
    const auto T_ned_camera = [&](double t_s) {
      Eigen::Isometry3d T = motion.T_ned_camera(0.0);
      T.translation().x() += moving_s(t_s) * moving_s(t_s);
      return T;
    };
    VelocityEstimate last;
    for (int k = 0; k <= static_cast<int>((kStartS + 0.4) * 1e9 / kImuNs); ++k) {
      const std::int64_t t_ns = k * kImuNs;
      const double t_s = hq::to_seconds(t_ns);
      const double a_mps2 = t_s > kStartS ? 2.0 : 0.0;
      estimator.update_imu(t_ns, Eigen::Vector3d::Zero(),
                           motion.accel(t_s) + Eigen::Vector3d(a_mps2, 0.0, 0.0));
      if (k % kImuPerFrame != 0) continue;
      odometry::OdometryResult odometry = motion.odometry_at(t_s, t_ns, k == 0);
      odometry.T_O_C = T_ned_camera(0.0).inverse() * T_ned_camera(t_s);
      last = estimator.update(t_ns, odometry);
    }
    ASSERT_TRUE(last.ok()) << last.reason;
    const double lag_s = moving_s(hq::to_seconds(last.t_ns)) - last.v_H_mps.x() / 2.0;
    fmt::print("{} output: lag {:.1f} ms at 2 m/s^2\n",
               output == VelocityEstimatorConfig::VelocityOutput::kFused ? "fused" : "one-euro",
               1e3 * lag_s);
    // THEN the fused velocity is the one at the frame's time (eq. 1's mean over the last
    // interval, moved to its end by the accelerometer), the 1-euro's tens of ms behind it
    if (output == VelocityEstimatorConfig::VelocityOutput::kFused) {
      EXPECT_LT(std::abs(lag_s), 0.005);
      EXPECT_GT(last.v_H_covariance.trace(), 0.0);
    } else {
      EXPECT_GT(lag_s, 0.02);
    }
  }
}

TEST(VelocityEstimator, NoImuMeansUnavailable) {
  Motion motion;
  VelocityEstimatorConfig config;
  config.warmup_s = 0.0;
  VelocityEstimator estimator(config, motion.R_B_C, motion.p_B_C_m);
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
  VelocityEstimator estimator(VelocityEstimatorConfig{}, motion.R_B_C, motion.p_B_C_m);
  std::array<odometry::OdometryResult, 60> frames;
  for (int i = 0; i < 60; ++i) {
    frames[static_cast<std::size_t>(i)] =
        motion.odometry_at(i * 0.03, i * kImuPerFrame * kImuNs, i == 0);
  }
  const long before = hq::testing::allocation_count();
  for (int i = 0; i < 60 * kImuPerFrame; ++i) {
    const std::int64_t t_ns = i * kImuNs;
    estimator.update_imu(t_ns, motion.gyro(), motion.accel(hq::to_seconds(t_ns)));
    if (i % kImuPerFrame == 0)
      estimator.update(t_ns, frames[static_cast<std::size_t>(i / kImuPerFrame)]);
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

TEST(VelocityEstimator, WithoutTheCoastRejectedOdometryIsUnavailable) {
  Motion motion;
  motion.v_ned_mps = Eigen::Vector3d(0.3, 0.0, 0.0);
  VelocityEstimatorConfig config;
  config.inertial_coast_s = 0.0;  // disables the coast
  VelocityEstimator estimator(config, motion.R_B_C, motion.p_B_C_m);
  const VelocityEstimate last_ok = run(estimator, motion, 1.0);
  ASSERT_TRUE(last_ok.ok());
  const std::int64_t t_ns = last_ok.t_ns + kImuPerFrame * kImuNs;
  estimator.update_imu(t_ns, motion.gyro(), motion.accel(hq::to_seconds(t_ns)));
  odometry::OdometryResult lost = motion.odometry_at(hq::to_seconds(t_ns), t_ns, false);
  lost.status = odometry::TrackingStatus::kLost;
  const VelocityEstimate estimate = estimator.update(t_ns, lost);
  EXPECT_EQ(estimate.status, EstimateStatus::kUnavailable);
  EXPECT_FALSE(estimate.usable());
  EXPECT_TRUE(estimate.v_H_mps.isZero());
}

// Loses odometry after `good_s` of the motion and then feeds the IMU a specific force that
// accelerates the vehicle at a_vertical_mps2 along NED z (keeping its attitude, so the
// complementary filter's roll and pitch stay right). Returns estimates at each lost frame.
struct CoastRun {
  VelocityEstimate last_ok;
  std::int64_t t_accel_start_ns = 0;  ///< Last IMU sample of the unaccelerated motion.
  std::vector<VelocityEstimate> lost;
};

CoastRun coast_after_loss(VelocityEstimator& estimator, const Motion& motion, double good_s,
                          double lost_s, double a_vertical_mps2) {
  CoastRun out;
  out.last_ok = run(estimator, motion, good_s);
  // run() may integrate IMU samples after its last frame: continue on its IMU and frame grid.
  const int good_steps = static_cast<int>(good_s * 1e9 / kImuNs);
  out.t_accel_start_ns = good_steps * kImuNs;
  const int steps = good_steps + static_cast<int>(lost_s * 1e9 / kImuNs);
  for (int k = good_steps + 1; k <= steps; ++k) {
    const std::int64_t t_ns = k * kImuNs;
    const double t_s = hq::to_seconds(t_ns);
    const Eigen::Matrix3d R_NQ = rz(motion.yaw(t_s)) * motion.R_tilt();
    // f = R_QN (a - g e_z) in NED.
    const Eigen::Vector3d accel =
        R_NQ.transpose() * Eigen::Vector3d(0.0, 0.0, a_vertical_mps2 - kGravityMps2);
    estimator.update_imu(t_ns, motion.gyro(), accel);
    if (k % kImuPerFrame == 0) {
      odometry::OdometryResult lost = motion.odometry_at(t_s, t_ns, false);
      lost.status = odometry::TrackingStatus::kLost;
      out.lost.push_back(estimator.update(t_ns, lost));
    }
  }
  return out;
}

TEST(VelocityEstimator, InertialCoastIntegratesTheRotatedAccelerometer) {
  // GIVEN a vehicle rolled 8 deg and pitched -12 deg flying at constant velocity, whose
  // odometry is then lost while it accelerates upwards at 1 m/s^2.
  Motion motion;
  motion.roll_rad = 8.0 * kDeg;
  motion.pitch_rad = -12.0 * kDeg;
  motion.yaw0_rad = 30.0 * kDeg;
  motion.v_ned_mps = Eigen::Vector3d(0.3, -0.2, 0.0);
  VelocityEstimatorConfig config;
  config.inertial_coast_s = 0.6;
  VelocityEstimator estimator(config, motion.R_B_C, motion.p_B_C_m);
  const double a_z = -1.0;  // NED: climbing faster
  const CoastRun coast = coast_after_loss(estimator, motion, 1.0, 1.0, a_z);
  ASSERT_TRUE(coast.last_ok.ok()) << coast.last_ok.reason;
  int inertial = 0;
  int unavailable = 0;
  for (const VelocityEstimate& estimate : coast.lost) {
    const double coast_s = hq::to_seconds(estimate.t_ns - coast.last_ok.t_ns);
    if (coast_s <= config.inertial_coast_s) {
      // THEN within inertial_coast_s: kInertial, the last good velocity plus a t along H z
      // (the specific force rotated with roll and pitch: unrotated, the tilt would add
      // g sin(12 deg) = 2 m/s^2 sideways).
      ASSERT_EQ(estimate.status, EstimateStatus::kInertial) << coast_s;
      EXPECT_STREQ(estimate.reason, "odometry lost");
      const double accel_s = hq::to_seconds(estimate.t_ns - coast.t_accel_start_ns);
      const Eigen::Vector3d expected =
          coast.last_ok.v_H_mps + Eigen::Vector3d(0.0, 0.0, a_z * accel_s);
      EXPECT_LT((estimate.v_H_mps - expected).norm(), 5e-3)
          << coast_s << ": " << estimate.v_H_mps.transpose() << " vs " << expected.transpose();
      EXPECT_NEAR(estimate.unavailable_for_s, coast_s, 1e-9);
      ++inertial;
    } else {
      // ... AND after it: unavailable, zero velocity.
      EXPECT_EQ(estimate.status, EstimateStatus::kUnavailable) << coast_s;
      EXPECT_TRUE(estimate.v_H_mps.isZero());
      ++unavailable;
    }
  }
  EXPECT_GE(inertial, 15);
  EXPECT_GE(unavailable, 10);
}

TEST(VelocityEstimator, CoastTurnsWithTheHeading) {
  // GIVEN a tilted vehicle yawing at 1 rad/s while it flies a constant 0.85 m/s over the
  // ground, whose odometry is lost after 5 s
  Motion motion;
  motion.roll_rad = 8.0 * kDeg;
  motion.pitch_rad = -12.0 * kDeg;
  motion.yaw_rate_radps = 1.0;
  motion.v_ned_mps = Eigen::Vector3d(0.8, -0.3, 0.0);
  VelocityEstimator estimator(VelocityEstimatorConfig{}, motion.R_B_C, motion.p_B_C_m);
  const CoastRun coast = coast_after_loss(estimator, motion, 5.0, 1.5, 0.0);
  ASSERT_TRUE(coast.last_ok.ok()) << coast.last_ok.reason;
  // (the 1-euro filter's lag under the turn has the last ok estimate 4 cm/s off the truth
  // already; the coast is judged against that estimate turned by the truth's heading change)
  const double t_ok_s = hq::to_seconds(coast.last_ok.t_ns);
  double max_error_mps = 0.0;
  for (const VelocityEstimate& estimate : coast.lost) {
    ASSERT_EQ(estimate.status, EstimateStatus::kInertial);
    const double t_s = hq::to_seconds(estimate.t_ns);
    const Eigen::Vector3d turned =
        rz(motion.yaw(t_s) - motion.yaw(t_ok_s)).transpose() * coast.last_ok.v_H_mps;
    max_error_mps = std::max(max_error_mps, (estimate.v_H_mps - turned).norm());
  }
  // THEN the coast's velocity turns the other way in H: within 1 mm/s over 1.5 s (fixed in H
  // it would be 2 x 0.85 x sin(0.75) = 1.16 m/s off by the end; 7 mm/s while the unseen
  // acceleration was learnt from the lagging 1-euro velocity)
  fmt::print("coast error over 1.5 s of 1 rad/s yaw: {:.4f} m/s\n", max_error_mps);
  EXPECT_LT(max_error_mps, 0.001);
  EXPECT_GE(coast.lost.size(), 40U);
}

// A level vehicle accelerating along north at accel_mps2 while its accelerometer reads rest (its
// bias held "level" by the filter: the acceleration it misses). Tracked for tracked_s, then
// lost for lost_s; returns the coast's north velocity error against the truth at the end.
struct UnseenAccelRun {
  double coast_error_mps = 0.0;  ///< The coast's north velocity error against the truth.
  Eigen::Vector3d learnt_mps2 = Eigen::Vector3d::Zero();
  EstimateStatus last_status = EstimateStatus::kUnavailable;
  double coast_horizon_s = 0.0;
};

UnseenAccelRun fly_with_unseen_accel(const VelocityEstimatorConfig& config, double accel_mps2,
                                     double tracked_s, double lost_s) {
  const Motion motion;  // level, yaw 0: H is NED
  VelocityEstimator estimator(config, motion.R_B_C, motion.p_B_C_m);
  const auto T_ned_camera = [&](double t_s) {
    Eigen::Isometry3d T = motion.T_ned_camera(0.0);
    T.translation().x() += 0.5 * accel_mps2 * t_s * t_s;
    return T;
  };
  VelocityEstimate last;
  const int steps = static_cast<int>((tracked_s + lost_s) * 1e9 / kImuNs);
  for (int k = 0; k <= steps; ++k) {
    const std::int64_t t_ns = k * kImuNs;
    const double t_s = hq::to_seconds(t_ns);
    estimator.update_imu(t_ns, Eigen::Vector3d::Zero(), motion.accel(t_s));
    if (k % kImuPerFrame != 0) continue;
    odometry::OdometryResult odometry;
    odometry.status = k == 0             ? odometry::TrackingStatus::kFirstFrame
                      : t_s <= tracked_s ? odometry::TrackingStatus::kOk
                                         : odometry::TrackingStatus::kLost;
    odometry.t_ns = t_ns;
    odometry.T_O_C = T_ned_camera(0.0).inverse() * T_ned_camera(t_s);
    odometry.valid_ratio = 0.4;
    odometry.mean_weighted_error = 50.0;
    last = estimator.update(t_ns, odometry);
  }
  UnseenAccelRun run;
  run.coast_error_mps = std::abs(last.v_H_mps.x() - accel_mps2 * (tracked_s + lost_s));
  run.learnt_mps2 = estimator.unseen_accel_H_mps2();
  run.last_status = last.status;
  run.coast_horizon_s = estimator.coast_horizon_s();
  return run;
}

// The learning alone: without velocity-aided levelling, which would put the missed acceleration
// into the tilt instead (VelocityEstimator.VelocityAidedTiltCarriesWhatTheAccelerometerMisses).
VelocityEstimatorConfig without_velocity_aiding() {
  VelocityEstimatorConfig config;
  config.complementary.velocity_k_p = 0.0;
  config.complementary.velocity_k_i = 0.0;
  return config;
}

double coast_error_with_unseen_accel(bool learn, double accel_mps2, double tracked_s, double lost_s,
                                     Eigen::Vector3d* learnt = nullptr) {
  VelocityEstimatorConfig config = without_velocity_aiding();
  // Not learning (no unseen acceleration state), the coast is not cut short either.
  if (!learn) config.unseen_accel_sigma_mps2 = 0.0;
  const UnseenAccelRun run = fly_with_unseen_accel(config, accel_mps2, tracked_s, lost_s);
  if (learnt != nullptr) *learnt = run.learnt_mps2;
  EXPECT_EQ(run.last_status, EstimateStatus::kInertial);
  return run.coast_error_mps;
}

TEST(VelocityEstimator, AccelerationTheAccelerometerMissesIsCarriedIntoTheCoast) {
  // GIVEN 0.08 m/s^2 the accelerometer does not see (an MPU-class bias's tilt), 20 s tracked
  // WHEN the odometry is then lost for 1.5 s
  Eigen::Vector3d learnt;
  const double with_state = coast_error_with_unseen_accel(true, 0.08, 20.0, 1.5, &learnt);
  const double without_state = coast_error_with_unseen_accel(false, 0.08, 20.0, 1.5);
  fmt::print(
      "coast error after 1.5 s: {:.4f} m/s with the unseen acceleration state ({:.4f} m/s^2 of "
      "it), {:.4f} without\n",
      with_state, learnt.x(), without_state);
  // THEN the coast follows the vehicle instead of gathering the 0.12 m/s that 0.08 m/s^2 makes
  // over 1.5 s: the attitude, levelled on the accelerometer less the fused velocity's own
  // acceleration, tilts until gravity carries it (a bias and a tilt are one to a velocity),
  // and the filter's unseen acceleration takes whatever the tilt has not, within its bound
  EXPECT_LT(with_state, 0.1 * 0.08 * 1.5);
  EXPECT_LT(without_state, 0.1 * 0.08 * 1.5);
  EXPECT_LE(learnt.norm(), 3.0 * VelocityEstimatorConfig{}.unseen_accel_sigma_mps2);
}

TEST(VelocityEstimator, CoastBeforeTheOdometryHasCheckedTheAccelerometerIsShort) {
  // GIVEN the default 0.1 m/s^2 that may go unseen and 0.1 m/s the coast may gather from it
  const VelocityEstimatorConfig config;
  // WHEN the odometry is lost a few frames after the start, nothing learnt yet
  const UnseenAccelRun early_09 = fly_with_unseen_accel(config, 0.0, 0.3, 0.9);
  const UnseenAccelRun early_11 = fly_with_unseen_accel(config, 0.0, 0.3, 1.1);
  // THEN the coast lasts about 0.1 / 0.1 = 1 s, not inertial_coast_s: an accelerometer
  // nothing has checked drives the vehicle at its bias while it holds "still" (the filter's
  // 0.1 m/s^2 prior is barely narrowed by a few frames: 1.07 s measured)
  fmt::print("coast horizon after 0.3 s tracked: {:.3f} s\n", early_09.coast_horizon_s);
  EXPECT_GT(early_09.coast_horizon_s, 1.0);
  EXPECT_LT(early_09.coast_horizon_s, 1.1);
  EXPECT_EQ(early_09.last_status, EstimateStatus::kInertial);
  EXPECT_EQ(early_11.last_status, EstimateStatus::kUnavailable);
  // AND after 20 s tracked (all but 2 % learnt) the whole inertial_coast_s is flown
  const UnseenAccelRun learnt = fly_with_unseen_accel(config, 0.0, 20.0, 1.9);
  EXPECT_EQ(learnt.coast_horizon_s, config.inertial_coast_s);
  EXPECT_EQ(learnt.last_status, EstimateStatus::kInertial);
  // AND with unseen_accel_sigma_mps2 0 (an accelerometer trusted as it is) it is never cut
  VelocityEstimatorConfig trusted;
  trusted.unseen_accel_sigma_mps2 = 0.0;
  EXPECT_EQ(fly_with_unseen_accel(trusted, 0.0, 0.3, 1.9).last_status, EstimateStatus::kInertial);
}

TEST(VelocityEstimator, LearntUnseenAccelerationIsBoundedToWhatAnAccelerometerCanMiss) {
  // GIVEN odometry that says the vehicle accelerates at 1.5 m/s^2 while the IMU reads rest
  for (const double gate_chi2 : {VelocityEstimatorConfig{}.velocity_gate_chi2, 1e6}) {
    VelocityEstimatorConfig config = without_velocity_aiding();
    config.velocity_gate_chi2 = gate_chi2;
    const UnseenAccelRun run = fly_with_unseen_accel(config, 1.5, 20.0, 0.1);
    fmt::print("gate {:.0f}: learnt {:.3f} m/s^2 of 1.5\n", gate_chi2, run.learnt_mps2.norm());
    // THEN what the filter learns stays within 3 x unseen_accel_sigma_mps2, gate or no gate
    EXPECT_LE(run.learnt_mps2.norm(), 3.0 * config.unseen_accel_sigma_mps2 + 1e-9);
  }
}

TEST(VelocityEstimator, HoldAtRestAnchorsTheCoastAtZero) {
  Motion motion;  // level, at rest
  VelocityEstimatorConfig config;
  VelocityEstimator estimator(config, motion.R_B_C, motion.p_B_C_m);
  std::int64_t t_ns = 0;
  for (; t_ns <= 500'000'000; t_ns += kImuNs) {
    estimator.update_imu(t_ns, motion.gyro(), motion.accel(hq::to_seconds(t_ns)));
  }
  t_ns -= kImuNs;
  // GIVEN no odometry ever: nothing to coast from.
  EXPECT_EQ(estimator.between_frames(t_ns, "no frame").status, EstimateStatus::kUnavailable);
  // WHEN the vehicle is known to rest on the ground
  estimator.hold_at_rest(t_ns);
  const VelocityEstimate at_rest = estimator.between_frames(t_ns, "no frame");
  EXPECT_EQ(at_rest.status, EstimateStatus::kInertial);
  EXPECT_STREQ(at_rest.reason, "no frame");
  EXPECT_TRUE(at_rest.v_H_mps.isZero());
  // THEN a take-off climb at 2 m/s^2 for 0.5 s is followed on the IMU from zero.
  const std::int64_t t_anchor_ns = t_ns;
  for (int k = 1; k <= 100; ++k) {
    t_ns = t_anchor_ns + k * kImuNs;
    estimator.update_imu(t_ns, motion.gyro(), Eigen::Vector3d(0.0, 0.0, -2.0 - kGravityMps2));
  }
  const VelocityEstimate climbing = estimator.between_frames(t_ns, "no frame");
  ASSERT_EQ(climbing.status, EstimateStatus::kInertial);
  EXPECT_NEAR(climbing.v_H_mps.z(), -2.0 * 0.5, 1e-6);
  EXPECT_NEAR(climbing.v_H_mps.head<2>().norm(), 0.0, 1e-6);

  // AND after flight at 0.3 m/s, hold_at_rest forgets that velocity.
  Motion flying;
  flying.v_ned_mps = Eigen::Vector3d(0.3, 0.0, 0.0);
  VelocityEstimator moving(config, flying.R_B_C, flying.p_B_C_m);
  const VelocityEstimate last_ok = run(moving, flying, 1.0);
  ASSERT_TRUE(last_ok.ok());
  ASSERT_GT(moving.between_frames(last_ok.t_ns, "no frame").v_H_mps.norm(), 0.25);
  moving.hold_at_rest(last_ok.t_ns);
  const VelocityEstimate held = moving.between_frames(last_ok.t_ns, "no frame");
  EXPECT_EQ(held.status, EstimateStatus::kInertial);
  EXPECT_TRUE(held.v_H_mps.isZero());
}

// Flies the motion, then from `jump_s` on reports odometry displaced by jump_C_m in the camera
// frame (a wrong match); returns the estimate of the first displaced frame.
VelocityEstimate first_jumped_frame(const VelocityEstimatorConfig& config,
                                    const Eigen::Vector3d& jump_C_m) {
  Motion motion;
  motion.v_ned_mps = Eigen::Vector3d(0.3, 0.0, 0.0);
  VelocityEstimator estimator(config, motion.R_B_C, motion.p_B_C_m);
  const VelocityEstimate last_ok = run(estimator, motion, 1.0);
  EXPECT_TRUE(last_ok.ok());
  const std::int64_t t_ns = last_ok.t_ns + kImuPerFrame * kImuNs;
  for (std::int64_t t = last_ok.t_ns + kImuNs; t <= t_ns; t += kImuNs) {
    estimator.update_imu(t, motion.gyro(), motion.accel(hq::to_seconds(t)));
  }
  odometry::OdometryResult jumped = motion.odometry_at(hq::to_seconds(t_ns), t_ns, false);
  jumped.T_O_C.translation() += jumped.T_O_C.linear() * jump_C_m;
  return estimator.update(t_ns, jumped);
}

TEST(VelocityEstimator, OdometryVelocityDisagreeingWithTheImuIsRejected) {
  // GIVEN a 0.3 m jump in one frame (a wrong match near the range limit), the IMU saying the
  // velocity is unchanged.
  const Eigen::Vector3d jump_C_m(0.0, 0.0, -0.3);
  const VelocityEstimate rejected = first_jumped_frame(VelocityEstimatorConfig{}, jump_C_m);
  EXPECT_FALSE(rejected.ok());
  EXPECT_STREQ(rejected.reason, "odometry velocity disagrees with the IMU");
  // THEN the coast carries on from the last good velocity instead.
  EXPECT_EQ(rejected.status, EstimateStatus::kInertial);
  EXPECT_NEAR(rejected.v_H_mps.x(), 0.3, 0.01);
  EXPECT_GT(rejected.innovation_chi2, VelocityEstimatorConfig{}.velocity_gate_chi2);
  // A gate wider than the jumped velocity's distance lets the same frame through.
  VelocityEstimatorConfig wide;
  wide.velocity_gate_chi2 = 1e6;
  const VelocityEstimate accepted = first_jumped_frame(wide, jump_C_m);
  ASSERT_TRUE(accepted.ok()) << accepted.reason;
  EXPECT_GT(accepted.innovation_chi2, VelocityEstimatorConfig{}.velocity_gate_chi2);
  EXPECT_GT((accepted.v_H_mps - Eigen::Vector3d(0.3, 0.0, 0.0)).norm(), 0.5);
  // A small jump within the gate is accepted too.
  EXPECT_TRUE(first_jumped_frame(VelocityEstimatorConfig{}, 0.01 * jump_C_m).ok());
}

// Hovers level at rest for duration_s, the IMU at 200 Hz and a frame every kImuPerFrame samples,
// the true odometry of each frame changed by edit(t_s, odometry) and each estimate handed to
// seen(t_s, estimate).
template <typename Edit, typename Seen>
void hover(const VelocityEstimatorConfig& config, double duration_s, Edit edit, Seen seen) {
  const Motion motion;
  VelocityEstimator estimator(config, motion.R_B_C, motion.p_B_C_m);
  const int steps = static_cast<int>(duration_s * 1e9 / kImuNs);
  for (int k = 0; k <= steps; ++k) {
    const std::int64_t t_ns = k * kImuNs;
    const double t_s = hq::to_seconds(t_ns);
    estimator.update_imu(t_ns, motion.gyro(), motion.accel(t_s));
    if (k % kImuPerFrame != 0) continue;
    odometry::OdometryResult odometry = motion.odometry_at(t_s, t_ns, k == 0);
    edit(t_s, odometry);
    seen(t_s, estimator.update(t_ns, odometry));
  }
}

// Hovers tracked for 1 s, loses the odometry for lost_s, then has it back for 0.4 s reporting
// returned_v_mps along x while the IMU says rest; returns the last estimate.
VelocityEstimate estimate_after_a_loss(const VelocityEstimatorConfig& config, double lost_s,
                                       double returned_v_mps) {
  const double return_s = 1.0 + lost_s;
  VelocityEstimate last;
  hover(
      config, return_s + 0.4,
      [&](double t_s, odometry::OdometryResult& odometry) {
        if (t_s > 1.0 && t_s < return_s) odometry.status = odometry::TrackingStatus::kLost;
        if (t_s >= return_s) odometry.T_O_C.translation().x() += returned_v_mps * (t_s - return_s);
      },
      [&](double, const VelocityEstimate& estimate) { last = estimate; });
  return last;
}

TEST(VelocityEstimator, OdometryReturningAfterTheCoastHasEndedIsCheckedAgainstTheImu) {
  // GIVEN a loss of 1.5 s, longer than the coast (1.2 s after 1 s tracked): the vehicle hovers
  // level on no estimate, the IMU still integrating from the last good velocity (rest)
  const VelocityEstimatorConfig config;
  // WHEN the odometry comes back with 1.8 m/s the accelerometer never saw
  const VelocityEstimate wrong = estimate_after_a_loss(config, 1.5, 1.8);
  // THEN it is rejected: the coast's covariance has grown with 0.1 m/s^2 of unseen acceleration
  // over 1.7 s to a gate of about 0.75 m/s, not opened
  fmt::print("gate after the loss: {} ({})\n", to_string(wrong.status), wrong.reason);
  EXPECT_FALSE(wrong.ok());
  EXPECT_STREQ(wrong.reason, "odometry velocity disagrees with the IMU");
  // AND odometry that agrees with the IMU is taken back
  EXPECT_TRUE(estimate_after_a_loss(config, 1.5, 0.0).ok());
  // AND after a loss long enough for the coast to be that far off (10 s: a gate of about 4.5
  // m/s) the same velocity is taken, so a drifted coast cannot keep the vehicle blind for ever
  EXPECT_TRUE(estimate_after_a_loss(config, 10.0, 1.8).ok());
  // AND with an accelerometer trusted to miss nothing the gate grows with its white noise only
  VelocityEstimatorConfig trusted;
  trusted.unseen_accel_sigma_mps2 = 0.0;
  EXPECT_FALSE(estimate_after_a_loss(trusted, 10.0, 1.8).ok());
}

// Hovers tracked for 1 s, loses the odometry for 0.5 s, then has it back, drifting at 0.2 m/s
// along x (within the IMU gate) while the IMU says rest, for the frame that re-seeds and
// `returned_frames` frames after it, and loses it again. Whether any estimate after the first
// loss was ok.
bool taken_after_a_loss(const VelocityEstimatorConfig& config, int returned_frames) {
  constexpr double kReturnS = 1.5;
  const double frame_s = kImuPerFrame * hq::to_seconds(kImuNs);
  const double lost_again_s = kReturnS + frame_s + (returned_frames - 0.5) * frame_s;
  bool taken = false;
  hover(
      config, 2.5,
      [&](double t_s, odometry::OdometryResult& odometry) {
        if (t_s > 1.0 && (t_s < kReturnS || t_s > lost_again_s)) {
          odometry.status = odometry::TrackingStatus::kLost;
        }
        if (t_s >= kReturnS) odometry.T_O_C.translation().x() += 0.2 * (t_s - kReturnS);
      },
      [&](double t_s, const VelocityEstimate& estimate) {
        if (t_s > 1.0 && estimate.ok()) taken = true;
      });
  return taken;
}

TEST(VelocityEstimator, OneFrameBetweenLostOnesIsNotTaken) {
  // GIVEN the default config: a frame must be followed by one more that agrees
  const VelocityEstimatorConfig config;
  ASSERT_EQ(config.reacquire_frames, 2);
  // WHEN the odometry returns after a loss for one frame past the one that re-seeds, wrong by
  // 0.2 m/s but inside the gate, and is lost again
  // THEN its velocity is never used: the vehicle keeps coasting on the IMU
  EXPECT_FALSE(taken_after_a_loss(config, 1));
  // AND when it stays, the second frame is taken
  EXPECT_TRUE(taken_after_a_loss(config, 2));
  // AND with reacquire_frames 1 (before) the lone frame was taken
  VelocityEstimatorConfig first_frame;
  first_frame.reacquire_frames = 1;
  EXPECT_TRUE(taken_after_a_loss(first_frame, 1));
}

// Hovers tracked for 1 s; from 1.0 to 1.3 s the odometry slides away at 1.5 m/s along x (a
// wrong match, far outside the IMU gate), then reports rest again from where it slid to. The
// fastest velocity any ok estimate after 1 s gave, and whether there was one.
std::pair<double, bool> fastest_taken_after_a_slide(const VelocityEstimatorConfig& config) {
  double fastest_mps = 0.0;
  bool any = false;
  hover(
      config, 2.5,
      [](double t_s, odometry::OdometryResult& odometry) {
        odometry.T_O_C.translation().x() += 1.5 * std::clamp(t_s - 1.0, 0.0, 0.3);
      },
      [&](double t_s, const VelocityEstimate& estimate) {
        if (t_s > 1.0 && estimate.ok()) {
          any = true;
          fastest_mps = std::max(fastest_mps, estimate.v_H_mps.norm());
        }
      });
  return {fastest_mps, any};
}

TEST(VelocityEstimator, RejectedFramesDoNotDragTheFilterPastTheGate) {
  // GIVEN a slide the gate rejects, then odometry right again
  const auto [fastest_mps, any] = fastest_taken_after_a_slide(VelocityEstimatorConfig{});
  fmt::print("fastest velocity taken after the slide: {:.3f} m/s\n", fastest_mps);
  // THEN the estimate comes back
  EXPECT_TRUE(any);
  // AND no velocity of the slide reaches it: the gate looks at eq. 1's velocity before the
  // filter takes the pose, so the rejected poses never entered the filter (checked against
  // gating the filtered velocity alone, as before: 1.68 m/s was taken)
  EXPECT_LT(fastest_mps, 0.05);
}

// The attitude's whole gyro bias less what its levelling learnt, after 2 s of frames that
// carry the odometry's bias estimate b_C (camera axes), with valid_ratio each.
Eigen::Vector3d vision_bias_in_the_attitude(const VelocityEstimatorConfig& config,
                                            const Eigen::Vector3d& b_C, double valid_ratio) {
  const Motion motion;  // the camera 45 deg right and 30 deg down: its axes are not B's
  VelocityEstimator estimator(config, motion.R_B_C, motion.p_B_C_m);
  for (int k = 0; k <= static_cast<int>(2e9 / kImuNs); ++k) {
    const std::int64_t t_ns = k * kImuNs;
    const double t_s = hq::to_seconds(t_ns);
    estimator.update_imu(t_ns, motion.gyro(), motion.accel(t_s));
    if (k % kImuPerFrame != 0) continue;
    odometry::OdometryResult odometry = motion.odometry_at(t_s, t_ns, k == 0);
    odometry.gyro_bias_radps = b_C;
    odometry.valid_ratio = valid_ratio;
    estimator.update(t_ns, odometry);
  }
  return estimator.attitude().gyro_bias_radps() - estimator.attitude().levelling_gyro_bias_radps();
}

TEST(VelocityEstimator, OdometrysGyroBiasReachesTheAttitudeInBodyAxes) {
  const Eigen::Vector3d b_C(0.004, -0.006, 0.01);
  const Motion motion;
  // Accepted frames hand it over, turned from the camera's axes into the body's.
  EXPECT_TRUE(vision_bias_in_the_attitude(VelocityEstimatorConfig{}, b_C, 0.4)
                  .isApprox(motion.R_B_C * b_C, 1e-9));
  // Rejected frames (too little of the image in use) do not.
  EXPECT_TRUE(vision_bias_in_the_attitude(VelocityEstimatorConfig{}, b_C, 0.01).isZero());
  // Nor does anything when it is turned off.
  VelocityEstimatorConfig off;
  off.gyro_bias_from_odometry = false;
  EXPECT_TRUE(vision_bias_in_the_attitude(off, b_C, 0.4).isZero());
}

TEST(VelocityEstimatorConfig, CoastKeysAreReadAndRangeChecked) {
  VelocityEstimatorConfig config;
  config::StrictMap section(YAML::Load("{inertial_coast_s: 1.5, velocity_gate_chi2: 11.3,"
                                       " vision_position_sigma_m: 0.002,"
                                       " accel_noise_density_mps2: 0.1,"
                                       " velocity_output: one_euro,"
                                       " reacquire_frames: 3,"
                                       " unseen_accel_random_walk: 0.1,"
                                       " unseen_accel_sigma_mps2: 0.2,"
                                       " coast_max_velocity_error_mps: 0.3,"
                                       " gyro_bias_from_odometry: false}"),
                            "config/onboard.yaml", "estimator");
  read_config(section, config);
  EXPECT_EQ(config.inertial_coast_s, 1.5);
  EXPECT_EQ(config.velocity_gate_chi2, 11.3);
  EXPECT_EQ(config.vision_position_sigma_m, 0.002);
  EXPECT_EQ(config.accel_noise_density_mps2, 0.1);
  EXPECT_EQ(config.velocity_output, VelocityEstimatorConfig::VelocityOutput::kOneEuro);
  EXPECT_EQ(config.reacquire_frames, 3);
  EXPECT_EQ(config.unseen_accel_random_walk, 0.1);
  EXPECT_EQ(config.unseen_accel_sigma_mps2, 0.2);
  EXPECT_EQ(config.coast_max_velocity_error_mps, 0.3);
  EXPECT_FALSE(config.gyro_bias_from_odometry);
  const auto error = [](const char* yaml) {
    config::StrictMap bad(YAML::Load(yaml), "config/onboard.yaml", "estimator");
    VelocityEstimatorConfig out;
    return hq::testing::input_error_message([&] { read_config(bad, out); });
  };
  EXPECT_THAT(
      error("{inertial_coast_s: -1}"),
      HasSubstr("config/onboard.yaml: estimator.inertial_coast_s = -1, expected in [0, 10]"));
  EXPECT_THAT(error("{inertial_coast_s: 11}"),
              HasSubstr("estimator.inertial_coast_s = 11, expected in [0, 10]"));
  EXPECT_THAT(error("{velocity_gate_chi2: 0}"),
              HasSubstr("estimator.velocity_gate_chi2 = 0, expected > 0"));
  EXPECT_THAT(error("{velocity_output: raw}"), HasSubstr("estimator.velocity_output"));
  EXPECT_THAT(error("{vision_position_sigma_m: -0.001}"),
              HasSubstr("estimator.vision_position_sigma_m = -0.001, expected > 0"));
  EXPECT_THAT(error("{reacquire_frames: 0}"),
              HasSubstr("estimator.reacquire_frames = 0, expected in [1, 30]"));
  EXPECT_THAT(error("{accel_noise_density_mps2: .inf}"),
              HasSubstr("estimator.accel_noise_density_mps2"));
  EXPECT_THAT(error("{unseen_accel_random_walk: .nan}"),
              HasSubstr("estimator.unseen_accel_random_walk"));
  EXPECT_THAT(error("{unseen_accel_sigma_mps2: -0.1}"),
              HasSubstr("estimator.unseen_accel_sigma_mps2 = -0.1, expected in [0, 10]"));
  EXPECT_THAT(error("{coast_max_velocity_error_mps: 0}"),
              HasSubstr("estimator.coast_max_velocity_error_mps = 0, expected > 0"));
  EXPECT_THAT(error("{gyro_bias_from_odometry: 3}"),
              HasSubstr("estimator.gyro_bias_from_odometry"));
}

}  // namespace
}  // namespace hq::estimator
