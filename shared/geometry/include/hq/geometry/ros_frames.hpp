#pragma once
/// The vehicle's frames to ROS's (REP-103, REP-105), in one place:
///   NED world (W, the marker map; L) -> E, ROS's ENU world (odom): x east, y north, z up.
///   B, body FRD                       -> F, ROS's FLU body (base_link): x forward, y left, z up.
///   H, horizontal FRD (core eq. 5)    -> F at zero roll and pitch (REP-120 base_stabilized).
/// Both swaps are proper rotations: R_E_NED = [[0,1,0],[1,0,0],[0,0,-1]], R_F_B = diag(1,-1,-1).
/// The camera (REP-103's suffix convention): camera_link looks along its x (x forward, y left,
/// z up), camera_optical is the optical frame C (z forward, x right, y down).
/// Pure geometry, so the ROS 2 bridge and the flight records (MCAP) place the vehicle alike.

#include "hq/geometry/camera_mount.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hq::geometry {

/// A vector in a NED frame, expressed in the ENU frame sharing its origin: (y, x, -z).
Eigen::Vector3d enu_from_ned(const Eigen::Vector3d& v_ned);
/// A vector in FRD (B or H), expressed in FLU (F): (x, -y, -z). Its own inverse.
Eigen::Vector3d flu_from_frd(const Eigen::Vector3d& v_frd);

/// R_NED_B of the Z-Y-X Euler angles of the body FRD in a NED world (yaw about down, from north
/// towards east; pitch nose up; roll right side down), as MAVLink and the estimator define them.
Eigen::Matrix3d R_ned_B(double roll_rad, double pitch_rad, double yaw_rad);

/// q_E_F: the orientation of the ROS body (FLU) in the ROS world (ENU) of a body FRD at the
/// given NED Euler angles. With yaw unknown pass 0: the ENU x axis is then the heading.
Eigen::Quaterniond q_E_F(double roll_rad, double pitch_rad, double yaw_rad);

/// The body velocity in F of a velocity v_H (horizontal FRD frame, core eq. 5) at roll and
/// pitch: v_B = R_H_B^T v_H with R_H_B = R_y(pitch) R_x(roll), then FRD -> FLU.
Eigen::Vector3d v_F_from_v_H(const Eigen::Vector3d& v_H_mps, double roll_rad, double pitch_rad);

/// A ROS velocity command (geometry_msgs/Twist, FLU at zero roll and pitch: linear.x forward,
/// y left, z up, angular.z counter-clockwise yaw rate seen from above) as the link's command in
/// H (FRD level: x forward, y right, z down; yaw rate clockwise from above).
struct HorizontalCommand {
  Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();
  double yaw_rate_radps = 0.0;
};
HorizontalCommand command_from_twist(const Eigen::Vector3d& linear_F_mps, double angular_z_F_radps);

/// The camera mount as the two fixed transforms of a ROS frame tree:
/// base_link -> camera_link -> camera_optical. Both frames sit at the optical centre.
struct RosCameraFrames {
  Eigen::Isometry3d T_F_camera_link = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_camera_link_optical = Eigen::Isometry3d::Identity();
};
RosCameraFrames ros_camera_frames(const CameraMount& mount);

}  // namespace hq::geometry
