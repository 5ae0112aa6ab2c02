#include "hq/geometry/camera_mount.hpp"

#include "hq/testing/input_error.hpp"

#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace hq::geometry {
namespace {

using ::testing::HasSubstr;

// A camera yawed by yaw and pitched by pitch in Q (NED body), optical axes as in calib/.
Eigen::Matrix3d mount(double yaw_rad, double pitch_rad, double roll_rad) {
  Eigen::Matrix3d optical_in_forward;  // columns: optical x (right), y (down), z (forward)
  optical_in_forward << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  return (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
             .toRotationMatrix() *
         optical_in_forward;
}

TEST(CameraHeading, IsTheCameraYawWhateverItsPitchAndRoll) {
  constexpr double kDeg = std::numbers::pi / 180.0;
  for (const double yaw : {-170.0, -90.0, 0.0, 45.0, 135.0}) {
    for (const double pitch : {-60.0, -30.0, 0.0, 20.0}) {
      for (const double roll : {-15.0, 0.0, 30.0}) {
        EXPECT_NEAR(camera_heading_rad(mount(yaw * kDeg, pitch * kDeg, roll * kDeg)), yaw * kDeg,
                    1e-9)
            << yaw << " " << pitch << " " << roll;
      }
    }
  }
}

TEST(CameraHeading, RejectsANonRotationAndAVerticalCamera) {
  EXPECT_THAT(testing::input_error_message(
                  [] { (void)camera_heading_rad(2.0 * Eigen::Matrix3d::Identity()); }),
              HasSubstr("not a rotation"));
  EXPECT_THAT(testing::input_error_message(
                  [] { (void)camera_heading_rad(mount(0.3, -std::numbers::pi / 2, 0.0)); }),
              HasSubstr("vertical"));
}

TEST(CameraMount, HoldsTheHeadingAndRefusesAnImpossibleLeverArm) {
  Eigen::Isometry3d T_B_C = Eigen::Isometry3d::Identity();
  T_B_C.linear() = mount(0.5, -0.2, 0.0);
  T_B_C.translation() = Eigen::Vector3d(0.1, 0.0, -0.05);
  const CameraMount camera_mount(T_B_C);
  EXPECT_TRUE(camera_mount.has_heading());
  EXPECT_NEAR(camera_mount.heading_rad(), 0.5, 1e-9);
  EXPECT_TRUE(camera_mount.p_B_C_m().isApprox(T_B_C.translation()));

  T_B_C.translation() = Eigen::Vector3d(3.0, 0.0, 0.0);
  EXPECT_THAT(testing::input_error_message([&] { (void)CameraMount(T_B_C); }),
              HasSubstr("within 2 m"));
  T_B_C.translation() = Eigen::Vector3d(std::nan(""), 0.0, 0.0);
  EXPECT_THAT(testing::input_error_message([&] { (void)CameraMount(T_B_C); }), HasSubstr("finite"));
  T_B_C.translation().setZero();
  T_B_C.linear() = 2.0 * Eigen::Matrix3d::Identity();
  EXPECT_THAT(testing::input_error_message([&] { (void)CameraMount(T_B_C); }),
              HasSubstr("not a rotation"));
}

// A down-looking camera is a mount the chain flies (eqs. 4-5 and the obstacle field hold for any
// rotation); only eq. 9 needs a heading, and asking for it names why there is none.
TEST(CameraMount, AcceptsADownLookingCameraWhichHasNoHeading) {
  Eigen::Isometry3d T_B_C = Eigen::Isometry3d::Identity();
  T_B_C.linear() = mount(0.3, -std::numbers::pi / 2, 0.0);
  T_B_C.translation() = Eigen::Vector3d(0.0, 0.0, 0.1);
  const CameraMount down(T_B_C);
  EXPECT_FALSE(down.has_heading());
  EXPECT_TRUE(down.R_B_C().col(2).isApprox(Eigen::Vector3d::UnitZ(), 1e-12));
  EXPECT_THAT(testing::input_error_message([&] { (void)down.heading_rad(); }),
              HasSubstr("within 3 deg of vertical"));
  const CameraMount looking_down = CameraMount::looking_down();
  EXPECT_FALSE(looking_down.has_heading());
  EXPECT_TRUE(looking_down.T_B_C().isApprox(Eigen::Isometry3d::Identity()));
}

}  // namespace
}  // namespace hq::geometry
