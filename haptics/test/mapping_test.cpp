#include "hq/haptics/teleop_mapping.hpp"
#include "hq/testing/input_error.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include "test_support.hpp"
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

namespace hq::haptics {
namespace {

using ::testing::HasSubstr;

constexpr double kDeg = std::numbers::pi / 180.0;

TEST(TeleopMapping, AlphaIsTheYawOfTheCameraViewingDirection) {
  // GIVEN the core paper's vehicle file (camera yawed 45 deg right, pitched 30 deg down)
  const TeleopMapping mapping(MappingConfig{}, test::core_paper_R_B_C());
  // THEN eq. 9 gives the camera's yaw, not that of the image x axis (135 deg)
  EXPECT_NEAR(mapping.alpha_rad(), 45.0 * kDeg, 1e-9);
}

TEST(TeleopMapping, AlphaFollowsCameraYawForAnyPitchAndRoll) {
  for (double yaw_deg = -170.0; yaw_deg <= 170.0; yaw_deg += 34.0) {
    for (double pitch_deg : {-60.0, -30.0, 0.0, 45.0}) {
      for (double roll_deg : {-20.0, 0.0, 90.0}) {
        const Eigen::Matrix3d R_QC =
            R_B_C_from_angles(yaw_deg * kDeg, pitch_deg * kDeg, roll_deg * kDeg);
        const TeleopMapping mapping(MappingConfig{}, R_QC);
        EXPECT_NEAR(mapping.alpha_rad(), yaw_deg * kDeg, 1e-9)
            << "yaw " << yaw_deg << " pitch " << pitch_deg << " roll " << roll_deg;
      }
    }
  }
}

TEST(TeleopMapping, PushForwardCommandsAlongAlphaOnly) {
  const MappingConfig config;
  const TeleopMapping mapping(config, test::core_paper_R_B_C());
  const double p_x = 0.03;
  const MappedCommand out = mapping.map(Eigen::Vector3d(p_x, 0.0, 0.0));
  ASSERT_TRUE(out.valid);
  const double speed = config.velocity_gain_mps_per_m * (p_x - config.dead_band_m);
  EXPECT_NEAR(out.command.v_H_mps.x(), speed * std::cos(mapping.alpha_rad()), 1e-12);  // eq. 6
  EXPECT_NEAR(out.command.v_H_mps.y(), speed * std::sin(mapping.alpha_rad()), 1e-12);  // eq. 7
  EXPECT_EQ(out.command.v_H_mps.z(), 0.0);
  EXPECT_EQ(out.command.yaw_rate_radps, 0.0);
  // Pulling back reverses it.
  const MappedCommand back = mapping.map(Eigen::Vector3d(-p_x, 0.0, 0.0));
  EXPECT_TRUE(back.command.v_H_mps.isApprox(-out.command.v_H_mps));
}

TEST(TeleopMapping, VerticalFromPzWithTheSignOfEq8) {
  const MappingConfig config;
  const TeleopMapping mapping(config, test::core_paper_R_B_C());
  // D is NED: +p_z is the handle pushed down; eq. 8 v_z = -k_v p_z, a climb in NED H.
  const MappedCommand out = mapping.map(Eigen::Vector3d(0.0, 0.0, 0.02));
  EXPECT_NEAR(out.command.v_H_mps.z(),
              -config.velocity_gain_mps_per_m * (0.02 - config.dead_band_m), 1e-12);
  EXPECT_EQ(out.command.v_H_mps.head<2>().norm(), 0.0);
  EXPECT_EQ(out.command.yaw_rate_radps, 0.0);
}

TEST(TeleopMapping, YawRateFromPyWithTheSignOfEq10) {
  const MappingConfig config;
  const TeleopMapping mapping(config, test::core_paper_R_B_C());
  const MappedCommand out = mapping.map(Eigen::Vector3d(0.0, 0.01, 0.0));
  EXPECT_NEAR(out.command.yaw_rate_radps,
              -config.yaw_gain_radps_per_m * (0.01 - config.dead_band_m), 1e-12);
  EXPECT_EQ(out.command.v_H_mps.norm(), 0.0);
}

TEST(TeleopMapping, DeadBandGivesZeroInsideAndIsContinuousAtItsEdge) {
  MappingConfig config;
  config.dead_band_m = 0.004;
  const TeleopMapping mapping(config, test::core_paper_R_B_C());
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(0.004, -0.004, 0.0039), Eigen::Vector3d(-0.001, 0.002, -0.003)}) {
    const MappedCommand out = mapping.map(p);
    EXPECT_TRUE(out.valid);
    EXPECT_EQ(out.command.v_H_mps.norm(), 0.0);
    EXPECT_EQ(out.command.yaw_rate_radps, 0.0);
  }
  const MappedCommand just_out = mapping.map(Eigen::Vector3d(0.0041, 0.0, 0.0));
  EXPECT_NEAR(just_out.command.v_H_mps.norm(), config.velocity_gain_mps_per_m * 0.0001, 1e-12);
}

TEST(TeleopMapping, SaturationKeepsTheDirectionAndFlagsIt) {
  const MappingConfig config;
  const TeleopMapping mapping(config, test::core_paper_R_B_C());
  const MappedCommand out = mapping.map(Eigen::Vector3d(0.5, -0.5, -0.5));
  ASSERT_TRUE(out.valid);
  EXPECT_TRUE(out.saturated);
  EXPECT_NEAR(out.command.v_H_mps.head<2>().norm(), config.max_horizontal_speed_mps, 1e-12);
  EXPECT_NEAR(std::atan2(out.command.v_H_mps.y(), out.command.v_H_mps.x()), mapping.alpha_rad(),
              1e-12);
  EXPECT_NEAR(out.command.v_H_mps.z(), config.max_vertical_speed_mps, 1e-12);
  EXPECT_NEAR(out.command.yaw_rate_radps, config.max_yaw_rate_radps, 1e-12);
  EXPECT_FALSE(mapping.map(Eigen::Vector3d(0.01, 0.0, 0.0)).saturated);
}

TEST(TeleopMapping, NonFiniteInputGivesZeroCommandAndReason) {
  const TeleopMapping mapping(MappingConfig{}, test::core_paper_R_B_C());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(nan, 0.0, 0.0), Eigen::Vector3d(0.02, inf, 0.0),
                                   Eigen::Vector3d(0.0, 0.0, -inf)}) {
    const MappedCommand out = mapping.map(p);
    EXPECT_FALSE(out.valid);
    EXPECT_EQ(out.command.v_H_mps, Eigen::Vector3d::Zero());
    EXPECT_EQ(out.command.yaw_rate_radps, 0.0);
    EXPECT_THAT(out.reason, HasSubstr("not finite"));
  }
}

TEST(TeleopMapping, DisplacementForInvertsTheMappingOutsideTheDeadBand) {
  const MappingConfig config;
  const TeleopMapping mapping(config, test::core_paper_R_B_C());
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(0.02, 0.01, -0.015), Eigen::Vector3d(-0.05, -0.02, 0.03)}) {
    const MappedCommand out = mapping.map(p);
    ASSERT_FALSE(out.saturated);
    const Eigen::Vector3d expected =
        p - config.dead_band_m * p.cwiseSign();  // the dead-banded displacement
    EXPECT_TRUE(mapping.displacement_for(out.command).isApprox(expected, 1e-12));
  }
}

TEST(TeleopMapping, CameraLookingStraightDownIsRejected) {
  const Eigen::Matrix3d R_QC = R_B_C_from_angles(0.3, -90.0 * kDeg, 0.0);
  const std::string message =
      testing::input_error_message([&] { const TeleopMapping mapping(MappingConfig{}, R_QC); });
  EXPECT_THAT(message, HasSubstr("vertical"));
  EXPECT_THAT(message, HasSubstr("eq. 9"));
}

TEST(TeleopMapping, NonRotationIsRejected) {
  const std::string message = testing::input_error_message(
      [&] { const TeleopMapping mapping(MappingConfig{}, 2.0 * Eigen::Matrix3d::Identity()); });
  EXPECT_THAT(message, HasSubstr("not a rotation"));
}

}  // namespace
}  // namespace hq::haptics
