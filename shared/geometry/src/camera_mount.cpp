#include "hq/geometry/camera_mount.hpp"

#include "hq/base/error.hpp"

#include <Eigen/LU>

#include <cmath>
#include <sstream>

namespace hq::geometry {

namespace {
constexpr double kMinHorizontalViewing = 0.05;  // sin(3 deg): the heading is still defined
}

double camera_heading_rad(const Eigen::Matrix3d& R_body_camera) {
  const bool is_rotation =
      R_body_camera.allFinite() &&
      (R_body_camera.transpose() * R_body_camera - Eigen::Matrix3d::Identity()).norm() < 1e-6 &&
      R_body_camera.determinant() > 0.0;
  if (!is_rotation) {
    std::ostringstream message;
    message << "R_body_camera is not a rotation matrix: [" << R_body_camera.row(0) << "; "
            << R_body_camera.row(1) << "; " << R_body_camera.row(2) << "]";
    throw InputError(message.str());
  }
  const Eigen::Vector3d viewing_Q = R_body_camera.col(2);
  if (std::hypot(viewing_Q.x(), viewing_Q.y()) < kMinHorizontalViewing) {
    std::ostringstream message;
    message << "camera viewing direction in the body frame (" << viewing_Q.transpose()
            << ") is within 3 deg of vertical; eq. 9 needs a horizontal component";
    throw InputError(message.str());
  }
  return std::atan2(viewing_Q.y(), viewing_Q.x());
}

}  // namespace hq::geometry
