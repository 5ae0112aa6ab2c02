#include "hq/estimator/complementary_filter.hpp"

#include "hq/config/strict_yaml.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <fmt/format.h>

namespace hq::estimator {
namespace {

using testing::HasSubstr;

constexpr std::int64_t kImuNs = 5'000'000;  // 200 Hz
constexpr double kDeg = M_PI / 180.0;

// Specific force measured at rest by a body with this roll/pitch (any yaw): a = -R^T g e3.
Eigen::Vector3d static_accel(double roll_rad, double pitch_rad) {
  return -R_H_B_from_tilt(roll_rad, pitch_rad).transpose() *
         Eigen::Vector3d(0.0, 0.0, kGravityMps2);
}

TEST(HorizontalFrame, LevelVehicleGivesIdentity) {
  EXPECT_TRUE(R_H_B_from_tilt(0.0, 0.0).isApprox(Eigen::Matrix3d::Identity(), 1e-15));
}

TEST(HorizontalFrame, PitchedVehicleMovingForwardInH) {
  // GIVEN a vehicle pitched 10 deg nose down (NED pitch -10 deg) moving 1 m/s forward in H.
  const double pitch = -10.0 * kDeg;
  const Eigen::Matrix3d R_H_B = R_H_B_from_tilt(0.0, pitch);
  const Eigen::Vector3d v_B = R_H_B.transpose() * Eigen::Vector3d(1.0, 0.0, 0.0);
  // THEN the body sees most of it along its nose and the rest towards its belly's opposite:
  // body z (down through the belly) leans backwards, so v_B.z = sin(pitch) < 0.
  EXPECT_NEAR(v_B.x(), std::cos(10.0 * kDeg), 1e-12);
  EXPECT_NEAR(v_B.y(), 0.0, 1e-12);
  EXPECT_NEAR(v_B.z(), -std::sin(10.0 * kDeg), 1e-12);
  // AND the body nose axis in H points forward and down (NED z > 0).
  EXPECT_GT(R_H_B.col(0).z(), 0.0);
  // Rolled right: body y axis in H points right and down.
  const Eigen::Matrix3d R_roll = R_H_B_from_tilt(20.0 * kDeg, 0.0);
  EXPECT_NEAR(R_roll.col(1).z(), std::sin(20.0 * kDeg), 1e-12);
}

TEST(ComplementaryFilter, ConvergesToTheTrueRollAndPitchFromAStaticTiltedAccelerometer) {
  ComplementaryConfig config;
  config.init_from_accel = false;  // start level, so convergence is the filter's doing
  config.k_p = 1.0;
  config.k_i = 0.0;  // the bias loop (pole near -k_i / k_p) would only slow the settling
  ComplementaryFilter filter(config);
  const double roll = 12.0 * kDeg;
  const double pitch = -17.0 * kDeg;
  for (int k = 0; k < 200 * 15; ++k) {
    filter.update(k * kImuNs, Eigen::Vector3d::Zero(), static_accel(roll, pitch));
  }
  EXPECT_NEAR(filter.roll_rad(), roll, 0.05 * kDeg);
  EXPECT_NEAR(filter.pitch_rad(), pitch, 0.05 * kDeg);
  // World NWU = Rx(pi) NED: the body z (down) axis points to -Z_W, tilted.
  EXPECT_LT(filter.R_N_B().col(2).z(), -0.9);
}

TEST(ComplementaryFilter, InitialisesFromTheAccelerometer) {
  ComplementaryFilter filter;
  EXPECT_EQ(filter.update(0, Eigen::Vector3d::Zero(), static_accel(0.3, -0.2)),
            FilterStatus::kFirstSample);
  EXPECT_NEAR(filter.roll_rad(), 0.3, 1e-12);
  EXPECT_NEAR(filter.pitch_rad(), -0.2, 1e-12);
}

TEST(ComplementaryFilter, EstimatesAConstantGyroBias) {
  ComplementaryConfig config;
  config.k_p = 1.0;
  config.k_i = 0.2;
  ComplementaryFilter filter(config);
  // Gravity observes the two bias axes orthogonal to it; yaw bias is unobservable without a
  // heading reference (Mahony 2008, §V), so the test vehicle is level and the z bias zero.
  const Eigen::Vector3d bias(0.03, -0.02, 0.0);
  for (int k = 0; k < 200 * 40; ++k) {
    filter.update(k * kImuNs, bias, static_accel(0.0, 0.0));
  }
  EXPECT_NEAR(filter.gyro_bias_radps().x(), bias.x(), 1e-3);
  EXPECT_NEAR(filter.gyro_bias_radps().y(), bias.y(), 1e-3);
  // And the attitude did not drift away despite the biased gyro.
  EXPECT_NEAR(filter.roll_rad(), 0.0, 0.05 * kDeg);
  EXPECT_NEAR(filter.pitch_rad(), 0.0, 0.05 * kDeg);
}

// A multirotor accelerating at accel_mps2 along NED x for duration_s, its thrust tilted to do it
// (pitch -atan(a / g)), so that its accelerometer reads the thrust alone, straight down the
// body's -z. Every frame_s the filter is told how far the velocity it integrated from that
// accelerometer, levelled with its own roll and pitch, missed the true one (what
// VelocityEstimator does with the odometry's). Returns the estimated pitch's error in degrees.
double pitch_error_deg_accelerating(const ComplementaryConfig& config, double accel_mps2,
                                    double duration_s, bool velocity_aided) {
  const double pitch = -std::atan2(accel_mps2, kGravityMps2);
  const Eigen::Vector3d thrust_B(0.0, 0.0, -std::hypot(accel_mps2, kGravityMps2));
  ComplementaryFilter filter(config);
  filter.update(0, Eigen::Vector3d::Zero(), static_accel(0.0, pitch));  // starts right
  constexpr int kImuPerFrame = 6;                                       // 33 Hz frames
  Eigen::Vector3d integrated_dv_H = Eigen::Vector3d::Zero();
  const int steps = static_cast<int>(duration_s * 1e9 / kImuNs);
  for (int k = 1; k <= steps; ++k) {
    filter.update(k * kImuNs, Eigen::Vector3d::Zero(), thrust_B);
    integrated_dv_H += (R_H_B_from_tilt(filter.roll_rad(), filter.pitch_rad()) * thrust_B +
                        Eigen::Vector3d(0.0, 0.0, kGravityMps2)) *
                       1e-9 * kImuNs;
    if (velocity_aided && k % kImuPerFrame == 0) {
      const double span_s = 1e-9 * kImuNs * kImuPerFrame;
      const Eigen::Vector3d true_dv_H(accel_mps2 * span_s, 0.0, 0.0);
      EXPECT_TRUE(
          filter.level_on_velocity(k * kImuNs, (true_dv_H - integrated_dv_H) / span_s, span_s));
      integrated_dv_H.setZero();
    }
  }
  EXPECT_NEAR(filter.roll_rad(), 0.0, 0.01 * kDeg);
  return (filter.pitch_rad() - pitch) / kDeg;
}

// Velocity-aided levelling on, at the gain it had as the default before the fused filter's
// unseen acceleration took over its job (ComplementaryConfig::velocity_k_p).
ComplementaryConfig velocity_aided() {
  ComplementaryConfig config;
  config.velocity_k_p = 0.3;
  return config;
}

TEST(ComplementaryFilter, MeasuredVelocityKeepsTheTiltTheAccelerometerLevelsAway) {
  // GIVEN a multirotor accelerating at 1.5 m/s^2 for 10 s (pitched 8.7 deg): its
  // accelerometer reads the thrust, which looks level
  const ComplementaryConfig config = velocity_aided();  // with the levelling's pause
  // WHEN the filter has only the accelerometer, it levels onto the thrust, as Mahony's
  // filter assumes an unaccelerated body
  ComplementaryConfig accel_only = config;
  accel_only.velocity_k_p = 0.0;
  accel_only.velocity_k_i = 0.0;
  const double accel_only_deg = pitch_error_deg_accelerating(accel_only, 1.5, 10.0, false);
  // AND when a measured velocity tells it what its levelled accelerometer missed
  const double aided_deg = pitch_error_deg_accelerating(config, 1.5, 10.0, true);
  // AND with the accelerometer's proportional levelling left on beside the velocity's
  ComplementaryConfig both = config;
  both.accel_levelling_pause_s = 0.0;
  both.k_i = 0.0;
  const double both_deg = pitch_error_deg_accelerating(both, 1.5, 10.0, true);
  fmt::print(
      "pitch error after 10 s at 1.5 m/s^2: {:.3f} deg accelerometer only, {:.3f} aided, {:.3f} "
      "both\n",
      accel_only_deg, aided_deg, both_deg);
  // THEN alone it has lost the whole tilt (and its bias loop, which takes the levelling for a
  // gyro bias, a little more)
  const double tilt_deg = std::atan2(1.5, kGravityMps2) / kDeg;
  EXPECT_GT(std::abs(accel_only_deg), tilt_deg);
  // AND aided it keeps the true tilt (within 1 %: 0.053 of 8.7 deg at velocity_k_p 0.3, the
  // rest of the first seconds' transient at its 3 s time constant)
  EXPECT_LT(std::abs(aided_deg), 0.01 * tilt_deg);
  // AND the two levellings pull apart: k_p / (k_p + velocity_k_p) of the tilt is lost
  EXPECT_NEAR(std::abs(both_deg), config.k_p / (config.k_p + config.velocity_k_p) * tilt_deg, 0.2);
}

TEST(ComplementaryFilter, VelocityAidingNotATiltIsNotUsed) {
  ComplementaryFilter filter(velocity_aided());
  EXPECT_FALSE(filter.level_on_velocity(0, Eigen::Vector3d::Zero(), 0.03));  // not started
  filter.update(0, Eigen::Vector3d::Zero(), static_accel(0.0, 0.0));
  const double pitch = filter.pitch_rad();
  EXPECT_FALSE(filter.level_on_velocity(kImuNs, Eigen::Vector3d(NAN, 0.0, 0.0), 0.03));
  EXPECT_FALSE(filter.level_on_velocity(kImuNs, Eigen::Vector3d(0.1, 0.0, 0.0), 0.0));
  // More than accel_tolerance_mps2 (3) is a wrong velocity, not a tilt.
  EXPECT_FALSE(filter.level_on_velocity(kImuNs, Eigen::Vector3d(3.5, 0.0, 0.0), 0.03));
  EXPECT_EQ(filter.pitch_rad(), pitch);
  EXPECT_TRUE(filter.level_on_velocity(kImuNs, Eigen::Vector3d(1.0, 0.0, 0.0), 0.03));
  // Missing +x acceleration: the body is pitched further nose down than estimated.
  EXPECT_LT(filter.pitch_rad(), pitch);
}

TEST(ComplementaryFilter, VelocityAidingTurnedOffLeavesTheAccelerometerLevelling) {
  // GIVEN velocity_k_p and velocity_k_i 0, a filter pitched 10 deg off a level accelerometer
  ComplementaryConfig config;
  config.velocity_k_p = 0.0;
  config.velocity_k_i = 0.0;
  ComplementaryFilter filter(config);
  filter.update(0, Eigen::Vector3d::Zero(), static_accel(0.0, 10.0 * kDeg));
  ASSERT_NEAR(filter.pitch_rad(), 10.0 * kDeg, 1e-9);
  // WHEN velocity errors keep arriving, as the estimator sends them every tracked frame
  for (int k = 1; k <= 2000; ++k) {
    EXPECT_FALSE(filter.level_on_velocity(k * kImuNs, Eigen::Vector3d(0.5, 0.0, 0.0), 0.03));
    filter.update(k * kImuNs, Eigen::Vector3d::Zero(), static_accel(0.0, 0.0));
  }
  // THEN nothing pauses the accelerometer: 10 s at k_p 1 level it (paused, it would stay at
  // 10 deg; the bias loop's swing is still 0.35 deg)
  EXPECT_NEAR(filter.pitch_rad(), 0.0, 0.5 * kDeg);
}

// Pitch error (deg) after a 1.5 s coast on a gyro with a 0.8 deg/s pitch bias (the
// unseen-space campaign's worst), the accelerometer's levelling paused by a velocity-aided
// correction just before, as after the last tracked frame; vision_bias_radps is handed over
// first, as the estimator hands the odometry's.
double pitch_error_deg_after_a_coast(const Eigen::Vector3d& vision_bias_radps) {
  const Eigen::Vector3d bias(0.0, 0.8 * kDeg, 0.0);
  ComplementaryFilter filter(velocity_aided());
  filter.update(0, bias, static_accel(0.0, 0.0));
  filter.set_vision_gyro_bias(vision_bias_radps);
  EXPECT_TRUE(filter.level_on_velocity(0, Eigen::Vector3d::Zero(), 0.03));
  for (int k = 1; k <= static_cast<int>(1.5e9 / kImuNs); ++k) {
    filter.update(k * kImuNs, bias, static_accel(0.0, 0.0));
  }
  return filter.pitch_rad() / kDeg;
}

TEST(ComplementaryFilter, GyroBiasTheVisionMeasuredKeepsACoastLevel) {
  // WHEN nothing but the accelerometer has learnt the bias (not yet: it levels slowly, and it
  // is paused while the velocity aids the levelling), the coast drifts at the bias
  const double alone_deg = pitch_error_deg_after_a_coast(Eigen::Vector3d::Zero());
  // AND when the vision's estimate of it is handed over
  const double with_vision_deg =
      pitch_error_deg_after_a_coast(Eigen::Vector3d(0.0, 0.8 * kDeg, 0.0));
  fmt::print(
      "pitch after a 1.5 s coast at a 0.8 deg/s bias: {:.3f} deg alone, {:.4f} with the vision's "
      "bias\n",
      alone_deg, with_vision_deg);
  // THEN it does not
  EXPECT_NEAR(alone_deg, 1.2, 0.05);
  EXPECT_LT(std::abs(with_vision_deg), 0.01);
}

TEST(ComplementaryFilter, GyroBiasTheVisionMeasuredIsKeptApartBoundedAndCleared) {
  ComplementaryConfig config;
  config.max_bias_radps = 0.1;
  ComplementaryFilter filter(config);
  filter.update(0, Eigen::Vector3d::Zero(), static_accel(0.0, 0.0));
  filter.set_vision_gyro_bias(Eigen::Vector3d(0.01, -0.02, 0.5));
  // The whole bias has it (the z axis bounded); the levelling's own, which the odometry's
  // gyro prior is corrected by, does not.
  EXPECT_TRUE(filter.gyro_bias_radps().isApprox(Eigen::Vector3d(0.01, -0.02, 0.1)));
  EXPECT_TRUE(filter.levelling_gyro_bias_radps().isZero());
  filter.set_vision_gyro_bias(Eigen::Vector3d(NAN, 0.0, 0.0));  // ignored
  EXPECT_TRUE(filter.gyro_bias_radps().isApprox(Eigen::Vector3d(0.01, -0.02, 0.1)));
  filter.reset();
  EXPECT_TRUE(filter.gyro_bias_radps().isZero());
}

TEST(ComplementaryFilter, RejectsNanAndKeepsState) {
  ComplementaryFilter filter;
  filter.update(0, Eigen::Vector3d::Zero(), static_accel(0.1, 0.0));
  const double roll = filter.roll_rad();
  EXPECT_EQ(filter.update(kImuNs, Eigen::Vector3d(std::nan(""), 0, 0), static_accel(0.5, 0.0)),
            FilterStatus::kRejectedNonFinite);
  EXPECT_EQ(filter.update(kImuNs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(NAN)),
            FilterStatus::kRejectedNonFinite);
  EXPECT_EQ(filter.update(0, Eigen::Vector3d::Zero(), static_accel(0.5, 0.0)),
            FilterStatus::kRejectedTime);
  EXPECT_EQ(filter.roll_rad(), roll);
}

TEST(LowPassFilter, ConvergesToAConstantWithTheConfiguredTimeConstant) {
  LowPassFilter<3> filter(10.0);
  filter.update(0, Eigen::Vector3d::Zero());
  const double tau_s = 1.0 / (2.0 * M_PI * 10.0);
  std::int64_t t_ns = 0;
  while (t_ns < static_cast<std::int64_t>(tau_s * 1e9)) {
    t_ns += 100'000;
    filter.update(t_ns, Eigen::Vector3d::Ones());
  }
  // After one time constant a continuous first-order system reaches 1 - 1/e.
  EXPECT_NEAR(filter.value().x(), 1.0 - std::exp(-1.0), 0.01);
  EXPECT_EQ(filter.update(t_ns, Eigen::Vector3d::Ones()), FilterStatus::kRejectedTime);
}

TEST(ComplementaryConfig, BadValueIsRejectedNamingTheKey) {
  const YAML::Node node = YAML::Load("{k_p: 1.0, k_i: -0.5}");
  config::StrictMap section(node, "config/onboard.yaml", "estimator.complementary");
  ComplementaryConfig config;
  try {
    read_config(section, config);
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("estimator.complementary.k_i = -0.5"));
  }
}

TEST(ComplementaryConfig, VelocityAidingKeysAreReadAndRangeChecked) {
  ComplementaryConfig config;
  config::StrictMap section(
      YAML::Load("{velocity_k_p: 0.5, velocity_k_i: 0.01, accel_levelling_pause_s: 3}"),
      "config/onboard.yaml", "estimator.complementary");
  read_config(section, config);
  EXPECT_EQ(config.velocity_k_p, 0.5);
  EXPECT_EQ(config.velocity_k_i, 0.01);
  EXPECT_EQ(config.accel_levelling_pause_s, 3.0);
  config::StrictMap negative(YAML::Load("{accel_levelling_pause_s: -1}"), "config/onboard.yaml",
                             "estimator.complementary");
  try {
    read_config(negative, config);
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("estimator.complementary.accel_levelling_pause_s = -1"));
  }
}

}  // namespace
}  // namespace hq::estimator
