#pragma once
// Camera poses for rendering the simulated marker grid, shared by the simulator tests.

#include <Eigen/Geometry>

namespace hq::markers::test {

/// Optical camera frame (z forward, x right, y down) at c_N_m looking at target_N_m,
/// image x kept horizontal (world z up).
inline Eigen::Isometry3d look_at(const Eigen::Vector3d& c_N_m, const Eigen::Vector3d& target_N_m) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const Eigen::Vector3d z = (target_N_m - c_N_m).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  T.linear().col(0) = x;
  T.linear().col(1) = z.cross(x);
  T.linear().col(2) = z;
  T.translation() = c_N_m;
  return T;
}

}  // namespace hq::markers::test
