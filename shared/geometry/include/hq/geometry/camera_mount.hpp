#pragma once
/// The camera on the vehicle: its extrinsics T_B_C (frames: hq/geometry/frames.hpp), checked once
/// where they are read, and its heading (eq. 9 of the core paper, alpha = atan2(r21, r11) of
/// R_QC), the direction the operator's forward command takes (eqs. 6-7) and the one the camera
/// sees. The paper's camera frame looks along x; ours is optical (z forward, x right, y down),
/// so the viewing direction is R_B_C's third column and alpha is its yaw in the body frame B.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hq::geometry {

/// alpha in (-pi, pi]: 45 deg for calib/vehicle_core_paper.yaml.
/// @throws hq::InputError if R_B_C is not a rotation, or the camera looks within 3 deg
///         of straight up or down (no horizontal heading).
double camera_heading_rad(const Eigen::Matrix3d& R_B_C);

/// A validated camera mount. Every holder of one may rely on T_B_C being a finite rigid
/// transform with a horizontal heading, so no component re-checks it.
class CameraMount {
 public:
  /// @throws hq::InputError if R_B_C is not a rotation, the lever arm is not finite or longer
  ///         than kMaxLeverArm_m, or the camera looks within 3 deg of vertical.
  explicit CameraMount(const Eigen::Isometry3d& T_B_C);

  [[nodiscard]] const Eigen::Isometry3d& T_B_C() const { return T_B_C_; }
  [[nodiscard]] Eigen::Matrix3d R_B_C() const { return T_B_C_.linear(); }
  /// The camera's optical centre in B (the lever arm of core eq. 4).
  [[nodiscard]] Eigen::Vector3d p_B_C_m() const { return T_B_C_.translation(); }
  /// alpha of core eq. 9, in (-pi, pi].
  [[nodiscard]] double heading_rad() const { return heading_rad_; }

  /// No camera sits further than this from the body origin on a vehicle this system flies.
  static constexpr double kMaxLeverArm_m = 2.0;

 private:
  Eigen::Isometry3d T_B_C_;
  double heading_rad_;
};

}  // namespace hq::geometry
