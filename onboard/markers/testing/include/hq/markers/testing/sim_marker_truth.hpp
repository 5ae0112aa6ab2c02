#pragma once
// Simulator truth in the detector's marker frame, shared by the simulator tests.

#include "hq/sim/world.hpp"

#include <Eigen/Geometry>

#include <cmath>

namespace hq::markers::test {

/// T_N_M of a simulated marker in ViSP's tag frame. The renderer prints the tag with
/// its image "right" = up x n and "down" = -up as seen from the side the normal n points to
/// (hq/sim rgbd_renderer.cpp); ViSP's frame has x = -right, y = down, z = n (measured: R^T R
/// was diag(-1, 1, -1) against x = right, z = -n).
inline Eigen::Isometry3d T_N_M(const sim::Marker& m) {
  const Eigen::Vector3d n = m.normal_N.normalized();
  Eigen::Vector3d up = std::abs(n.z()) > 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitZ();
  up = (up - up.dot(n) * n).normalized();
  up = Eigen::AngleAxisd(m.rotation_rad, n) * up;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = n.cross(up);
  T.linear().col(1) = -up;
  T.linear().col(2) = n;
  T.translation() = m.center_N_m;
  return T;
}

/// Rotation angle (rad) of R_a^T R_b.
inline double angle_between_rad(const Eigen::Matrix3d& R_a, const Eigen::Matrix3d& R_b) {
  return Eigen::AngleAxisd(R_a.transpose() * R_b).angle();
}

}  // namespace hq::markers::test
