#pragma once
/// The camera's heading on the vehicle: eq. 9 of the core paper, alpha = atan2(r21, r11) of
/// R_QC, the direction the operator's forward command takes (eqs. 6-7) and the one the camera
/// sees. The paper's camera frame looks along x; ours is optical (z forward, x right, y down),
/// so the viewing direction is R_QC's third column and alpha is its yaw in the body frame Q.

#include <Eigen/Core>

namespace hq::geometry {

/// alpha in (-pi, pi]: 45 deg for calib/vehicle_core_paper.yaml.
/// @throws hq::InputError if R_body_camera is not a rotation, or the camera looks within 3 deg
///         of straight up or down (no horizontal heading).
double camera_heading_rad(const Eigen::Matrix3d& R_body_camera);

}  // namespace hq::geometry
