#pragma once
/// The vehicle's frame tree as Foxglove's 3D panel reads it (foxglove.FrameTransform,
/// foxglove.CameraCalibration; field names as the official schemas), in ROS's frames
/// (hq/geometry/ros_frames.hpp), so the records place the vehicle as the ROS 2 bridge does:
///   odom (ENU) -> base_link (FLU)            per state
///   base_link -> camera_link -> camera_optical from the vehicle file's camera mount

#include "hq/flight_log/json.hpp"
#include "hq/geometry/camera_mount.hpp"
#include "hq/geometry/pinhole_camera.hpp"
#include "hq/link/link.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>

namespace hq::flight_log {

inline constexpr const char* kOdomFrame = "odom";
inline constexpr const char* kBaseFrame = "base_link";
inline constexpr const char* kCameraLinkFrame = "camera_link";
inline constexpr const char* kCameraOpticalFrame = "camera_optical";

/// A rigid transform parent <- child: the child's origin and orientation in the parent.
struct RigidTransform {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
};

/// odom -> base_link of a body pose in a NED-like frame: position p_m, yaw about down, roll and
/// pitch (the estimator's), as ENU position and q_E_F.
RigidTransform odom_T_base_link(const Eigen::Vector3d& p_m, double yaw_rad, double roll_rad,
                                double pitch_rad);

/// The one place choosing the source of the odom pose in a state: the odometry's integrated
/// pose (p_odom_m, yaw_odom_rad: NED-like, origin and heading of the start, continuous as
/// REP-105 wants) once odom_valid, otherwise the origin with yaw 0 (nothing integrated yet).
RigidTransform odom_T_base_link(const link::VehicleState& state);

/// {"timestamp":..,"parent_frame_id":..,"child_frame_id":..,"translation":..,"rotation":..}
void frame_transform_json(Json& j, std::int64_t stamp_ns, const char* parent, const char* child,
                          const RigidTransform& T);
RigidTransform rigid(const Eigen::Isometry3d& T);

/// The camera's intrinsics for an image of width x height (scaled from the calibration's
/// size; the link's images are undistorted, so D is zero, plumb_bob).
void camera_calibration_json(Json& j, std::int64_t stamp_ns, const char* frame_id,
                             const geometry::PinholeCamera& camera, int width_px, int height_px);

}  // namespace hq::flight_log
