#include "hq/geometry/camera_mount.hpp"

#include "hq/base/error.hpp"

#include <Eigen/LU>

#include <cmath>
#include <sstream>

namespace hq::geometry {

namespace {
constexpr double kMinHorizontalViewing = 0.05;  // sin(3 deg): the heading is still defined
}

double camera_heading_rad(const Eigen::Matrix3d& R_B_C) {
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
  const Eigen::Vector3d viewing_B = R_B_C.col(2);
  if (std::hypot(viewing_B.x(), viewing_B.y()) < kMinHorizontalViewing) {
    std::ostringstream message;
    message << "camera viewing direction in the body frame (" << viewing_B.transpose()
            << ") is within 3 deg of vertical; eq. 9 needs a horizontal component";
    throw InputError(message.str());
  }
  return std::atan2(viewing_B.y(), viewing_B.x());
}

CameraMount::CameraMount(const Eigen::Isometry3d& T_B_C)
    : T_B_C_(T_B_C), heading_rad_(camera_heading_rad(T_B_C.linear())) {
  const Eigen::Vector3d p_B_C_m = T_B_C.translation();
  if (!p_B_C_m.allFinite() || p_B_C_m.norm() > kMaxLeverArm_m) {
    std::ostringstream message;
    message << "camera position in the body frame (" << p_B_C_m.transpose()
            << " m) must be finite and within " << kMaxLeverArm_m << " m of the body origin";
    throw InputError(message.str());
  }
}

}  // namespace hq::geometry
