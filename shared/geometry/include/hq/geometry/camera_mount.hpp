#pragma once
/// The camera on the vehicle: its extrinsics T_B_C (frames: hq/geometry/frames.hpp), checked once
/// where they are read, and its heading (eq. 9 of the core paper, alpha = atan2(r21, r11) of
/// R_QC), the direction the operator's forward command takes (eqs. 6-7) and the one the camera
/// sees. The paper's camera frame looks along x; ours is optical (z forward, x right, y down),
/// so the viewing direction is R_B_C's third column and alpha is its yaw in the body frame B.
///
/// Any rigid mount is a camera the on-board chain can use: eqs. 4-5 (camera velocity to B and
/// H) hold for every rotation, and the obstacle field and the seen-space limiter work in H (a
/// down-looking camera sees the floor as a support surface and proves no horizontal free
/// space). Only eq. 9 needs the camera to look somewhere horizontal: a camera looking straight
/// up or down has no heading, so the operator's "forward" has no meaning. Whoever maps operator
/// commands (the vehicle file, the haptic mapping, marker navigation) asks heading_rad(), which
/// names the problem.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <optional>

namespace hq::geometry {

/// alpha in (-pi, pi]: 45 deg for calib/vehicle_core_paper.yaml.
/// @throws hq::InputError if R_B_C is not a rotation, or the camera looks within 3 deg
///         of straight up or down (no horizontal heading).
double camera_heading_rad(const Eigen::Matrix3d& R_B_C);

/// A validated camera mount. Every holder of one may rely on T_B_C being a finite rigid
/// transform with a lever arm a vehicle can have, so no component re-checks it.
class CameraMount {
 public:
  /// @throws hq::InputError if R_B_C is not a rotation, or the lever arm is not finite or
  ///         longer than kMaxLeverArm_m.
  explicit CameraMount(const Eigen::Isometry3d& T_B_C);

  /// The camera looking straight down (optical z = body z, x = body x): T_B_C the identity.
  /// No heading; the rendered-floor tests fly it.
  static CameraMount looking_down() { return CameraMount(Eigen::Isometry3d::Identity()); }

  [[nodiscard]] const Eigen::Isometry3d& T_B_C() const { return T_B_C_; }
  [[nodiscard]] Eigen::Matrix3d R_B_C() const { return T_B_C_.linear(); }
  /// The camera's optical centre in B (the lever arm of core eq. 4).
  [[nodiscard]] Eigen::Vector3d p_B_C_m() const { return T_B_C_.translation(); }
  /// False when the camera looks within 3 deg of vertical: eq. 9 has no alpha.
  [[nodiscard]] bool has_heading() const { return heading_rad_.has_value(); }
  /// alpha of core eq. 9, in (-pi, pi].
  /// @throws hq::InputError if !has_heading(), naming the viewing direction.
  [[nodiscard]] double heading_rad() const;

  /// No camera sits further than this from the body origin on a vehicle this system flies.
  static constexpr double kMaxLeverArm_m = 2.0;

 private:
  Eigen::Isometry3d T_B_C_;
  std::optional<double> heading_rad_;
};

}  // namespace hq::geometry
