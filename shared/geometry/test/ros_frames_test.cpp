#include "hq/geometry/ros_frames.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace hq::geometry {
namespace {

constexpr double kPi = std::numbers::pi;

void expect_near(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double tol = 1e-12) {
  EXPECT_LT((a - b).norm(), tol) << a.transpose() << " vs " << b.transpose();
}

// North is ENU's y, east its x, down its -z.
TEST(RosFrames, NedToEnuSwapsNorthEastAndFlipsDown) {
  expect_near(enu_from_ned({1, 0, 0}), {0, 1, 0});
  expect_near(enu_from_ned({0, 1, 0}), {1, 0, 0});
  expect_near(enu_from_ned({0, 0, 1}), {0, 0, -1});
}

TEST(RosFrames, FrdToFluFlipsRightAndDownAndIsItsOwnInverse) {
  expect_near(flu_from_frd({1, 2, 3}), {1, -2, -3});
  const Eigen::Vector3d v(0.3, -1.2, 2.5);
  expect_near(flu_from_frd(flu_from_frd(v)), v);
}

// Level and facing north: the FLU body's forward is ENU's north (y), its left is west (-x).
TEST(RosFrames, LevelFacingNorthLooksAlongEnuY) {
  const Eigen::Quaterniond q = q_E_F(0.0, 0.0, 0.0);
  expect_near(q * Eigen::Vector3d::UnitX(), {0, 1, 0});
  expect_near(q * Eigen::Vector3d::UnitY(), {-1, 0, 0});
  expect_near(q * Eigen::Vector3d::UnitZ(), {0, 0, 1});
  // ENU yaw of a north-facing body is +90 deg (REP-103: yaw 0 faces east).
  EXPECT_NEAR(q.toRotationMatrix().eulerAngles(2, 1, 0)[0], kPi / 2, 1e-12);
}

// Facing east (NED yaw +90 deg): forward is ENU x, and the ENU yaw is 0.
TEST(RosFrames, FacingEastIsEnuYawZero) {
  const Eigen::Quaterniond q = q_E_F(0.0, 0.0, kPi / 2);
  expect_near(q * Eigen::Vector3d::UnitX(), {1, 0, 0}, 1e-12);
  expect_near(q * Eigen::Vector3d::UnitZ(), {0, 0, 1}, 1e-12);
}

// Nose up 0.3 rad (NED pitch +): forward points up, i.e. ENU z > 0; roll right side down
// (NED roll +): FLU left (y) points up.
TEST(RosFrames, PitchUpAndRollRightKeepTheirMeaning) {
  const Eigen::Quaterniond up = q_E_F(0.0, 0.3, 0.0);
  EXPECT_NEAR((up * Eigen::Vector3d::UnitX()).z(), std::sin(0.3), 1e-12);
  const Eigen::Quaterniond right_down = q_E_F(0.2, 0.0, 0.0);
  EXPECT_NEAR((right_down * Eigen::Vector3d::UnitY()).z(), std::sin(0.2), 1e-12);
}

// Every orientation maps the body's vectors as R_ned_B does, seen through both swaps.
TEST(RosFrames, QuaternionAgreesWithTheNedRotationForManyAttitudes) {
  for (double roll = -1.0; roll <= 1.0; roll += 0.5) {
    for (double pitch = -1.0; pitch <= 1.0; pitch += 0.5) {
      for (double yaw = -3.0; yaw <= 3.0; yaw += 1.0) {
        const Eigen::Vector3d v_B(0.4, -0.7, 1.1);
        const Eigen::Vector3d v_ned = R_ned_B(roll, pitch, yaw) * v_B;
        const Eigen::Quaterniond q = q_E_F(roll, pitch, yaw);
        EXPECT_NEAR(q.norm(), 1.0, 1e-12);
        expect_near(q * flu_from_frd(v_B), enu_from_ned(v_ned), 1e-12);
      }
    }
  }
}

// Level, v_F is v_H with y and z flipped; pitched, forward speed in H tilts into the body.
TEST(RosFrames, BodyVelocityFromHorizontal) {
  expect_near(v_F_from_v_H({1.0, 0.5, -0.2}, 0.0, 0.0), {1.0, -0.5, 0.2});
  const double pitch = 0.3;  // nose up: a level forward velocity has a body-down component
  const Eigen::Vector3d v_F = v_F_from_v_H({1.0, 0.0, 0.0}, 0.0, pitch);
  EXPECT_NEAR(v_F.x(), std::cos(pitch), 1e-12);
  EXPECT_NEAR(v_F.z(), -std::sin(pitch), 1e-12);  // below the nose: FRD +z, FLU -z
  EXPECT_NEAR(v_F.norm(), 1.0, 1e-12);
}

// ROS teleop: forward, left, up and counter-clockwise become forward, -right, -down and a
// negative (anticlockwise) FRD yaw rate.
TEST(RosFrames, TwistCommandBecomesHorizontalFrdCommand) {
  const HorizontalCommand c = command_from_twist({0.5, 0.2, 0.1}, 0.4);
  expect_near(c.v_H_mps, {0.5, -0.2, -0.1});
  EXPECT_DOUBLE_EQ(c.yaw_rate_radps, -0.4);
}

// The core paper's mount (camera 45 deg right of the nose, 30 deg down, 0.1 m ahead): the
// optical axis in base_link points forward, right (-y in FLU) and down, and camera_link's x is
// that same axis; the lever arm flips its y and z into FLU.
TEST(RosFrames, CameraFramesLookAlongTheMountsOpticalAxis) {
  const double yaw = kPi / 4;
  const double pitch = -kPi / 6;
  Eigen::Isometry3d T_B_C = Eigen::Isometry3d::Identity();
  // Optical (z forward, x right, y down) from a body-aligned camera looking along body x.
  Eigen::Matrix3d R_forward;
  R_forward << 0, 0, 1,  //
      1, 0, 0,           //
      0, 1, 0;
  T_B_C.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                    Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()))
                       .toRotationMatrix() *
                   R_forward;
  T_B_C.translation() = Eigen::Vector3d(0.1, 0.02, -0.03);
  const RosCameraFrames frames = ros_camera_frames(CameraMount(T_B_C));

  const Eigen::Vector3d axis_B = T_B_C.linear().col(2);
  const Eigen::Isometry3d T_F_optical = frames.T_F_camera_link * frames.T_camera_link_optical;
  expect_near(T_F_optical.linear().col(2), flu_from_frd(axis_B));
  expect_near(frames.T_F_camera_link.linear().col(0), flu_from_frd(axis_B));
  EXPECT_GT(axis_B.z(), 0.4);  // looks down in FRD: z down
  expect_near(frames.T_F_camera_link.translation(), {0.1, -0.02, 0.03});
  expect_near(frames.T_camera_link_optical.translation(), Eigen::Vector3d::Zero());
  // Optical x (image right) is camera_link's -y, optical y (image down) its -z.
  expect_near(frames.T_camera_link_optical.linear().col(0), {0, -1, 0});
  expect_near(frames.T_camera_link_optical.linear().col(1), {0, 0, -1});
  EXPECT_NEAR(frames.T_F_camera_link.linear().determinant(), 1.0, 1e-12);
}

}  // namespace
}  // namespace hq::geometry
