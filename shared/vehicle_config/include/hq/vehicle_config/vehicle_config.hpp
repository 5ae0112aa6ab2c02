#pragma once
/// The vehicle: mass, actuator limits and the camera extrinsics T_B_C, from a calib file
/// such as calib/vehicle_core_paper.yaml. Shared: the vehicle file is read by both processes
/// (the on-board chain flies it; the ground maps the operator's commands through its mount).
///
/// T_B_C is given as the camera's yaw_deg, pitch_deg, roll_deg in the NED body frame Q
/// (ZYX, aerospace: yaw right positive, pitch up positive) applied to a forward-looking optical
/// frame (z forward, x right, y down), plus p_B_C_m (the core paper's ^Q p_C):
///   R_QC = Rz(yaw) Ry(pitch) Rx(roll) * R_forward_optical,
///   R_forward_optical = [e_y e_z e_x] (optical x = body right, y = body down, z = body forward).

#include "hq/geometry/camera_mount.hpp"

#include <Eigen/Core>

#include <string>

namespace hq::config {
class StrictMap;
}

namespace hq {

struct VehicleConfig {
  double mass_kg = 1.0;
  double max_tilt_rad = 0.5236;  ///< Max angle between thrust and vertical.
  double min_thrust_n = 2.0;     ///< Keeps the rotors spinning.
  double max_thrust_n = 20.0;
  double max_yaw_rate_radps = 1.5708;
  /// T_B_C (R_QC, Q_p_C), validated when built. The default looks straight down (no heading
  /// for eq. 9: the on-board chain flies it, an operator cannot); vehicle files give the real
  /// mount and must have a heading.
  geometry::CameraMount camera = geometry::CameraMount::looking_down();
};

/// R_QC from the camera's yaw/pitch/roll in the body frame (see the file comment).
Eigen::Matrix3d R_B_C_from_angles(double yaw_rad, double pitch_rad, double roll_rad);

/// The mount of those angles with the lever arm p_B_C_m. @throws hq::InputError as CameraMount.
geometry::CameraMount camera_mount_from_angles(double yaw_rad, double pitch_rad, double roll_rad,
                                               const Eigen::Vector3d& p_B_C_m);

/// Reads a vehicle file's root: {mass_kg, limits: {max_tilt_deg, min_thrust_n, max_thrust_n,
/// max_yaw_rate_degps}, T_B_C: {yaw_deg, pitch_deg, roll_deg, p_B_C_m}}.
/// Every key is required; throws hq::InputError naming file, key, value and expectation, also
/// for a mount that is not a CameraMount or has no heading (a camera looking within 3 deg of
/// vertical): the programs that read vehicle files map operator commands through eq. 9.
void read_config(config::StrictMap& root, VehicleConfig& out);

/// Loads and validates a vehicle file.
VehicleConfig load_vehicle_config(const std::string& path);

}  // namespace hq
