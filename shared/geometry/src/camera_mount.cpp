#include "hq/geometry/camera_mount.hpp"

#include "hq/base/error.hpp"

#include <Eigen/LU>

#include <cmath>
#include <optional>
#include <sstream>

namespace hq::geometry {

namespace {
constexpr double kMinHorizontalViewing = 0.05;  // sin(3 deg): the heading is still defined

void require_rotation(const Eigen::Matrix3d& R_B_C) {
  const bool is_rotation =
      R_B_C.allFinite() &&
      (R_B_C.transpose() * R_B_C - Eigen::Matrix3d::Identity()).norm() < 1e-6 &&
      R_B_C.determinant() > 0.0;
  if (!is_rotation) {
    std::ostringstream message;
    message << "R_B_C is not a rotation matrix: [" << R_B_C.row(0) << "; " << R_B_C.row(1) << "; "
            << R_B_C.row(2) << "]";
    throw InputError(message.str());
  }
}

/// alpha of a rotation, or nothing when the camera looks within 3 deg of vertical.
std::optional<double> heading_of(const Eigen::Matrix3d& R_B_C) {
  const Eigen::Vector3d viewing_B = R_B_C.col(2);
  if (std::hypot(viewing_B.x(), viewing_B.y()) < kMinHorizontalViewing) return std::nullopt;
  return std::atan2(viewing_B.y(), viewing_B.x());
}

[[noreturn]] void throw_vertical(const Eigen::Matrix3d& R_B_C) {
  std::ostringstream message;
  message << "camera viewing direction in the body frame (" << R_B_C.col(2).transpose()
          << ") is within 3 deg of vertical; eq. 9 needs a horizontal component";
  throw InputError(message.str());
}
}  // namespace

double camera_heading_rad(const Eigen::Matrix3d& R_B_C) {
  require_rotation(R_B_C);
  const std::optional<double> heading_rad = heading_of(R_B_C);
  if (!heading_rad) throw_vertical(R_B_C);
  return *heading_rad;
}

CameraMount::CameraMount(const Eigen::Isometry3d& T_B_C) : T_B_C_(T_B_C) {
  require_rotation(T_B_C.linear());
  const Eigen::Vector3d p_B_C_m = T_B_C.translation();
  if (!p_B_C_m.allFinite() || p_B_C_m.norm() > kMaxLeverArm_m) {
    std::ostringstream message;
    message << "camera position in the body frame (" << p_B_C_m.transpose()
            << " m) must be finite and within " << kMaxLeverArm_m << " m of the body origin";
    throw InputError(message.str());
  }
  heading_rad_ = heading_of(T_B_C.linear());
}

double CameraMount::heading_rad() const {
  if (!heading_rad_) throw_vertical(T_B_C_.linear());
  return *heading_rad_;
}

}  // namespace hq::geometry
