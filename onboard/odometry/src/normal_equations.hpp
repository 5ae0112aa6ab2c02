#pragma once
// The normal equations one alignment iteration leaves (private to hq_odometry): what the
// alignment steps with, the gyro fusion weighs against and the degeneracy checks read.

#include "hq/geometry/lie.hpp"
#include "hq/odometry/dense_odometry.hpp"

#include <Eigen/Core>

namespace hq::odometry::detail {

using Vector6d = geometry::Vector6d;
using Matrix7d = Eigen::Matrix<double, 7, 7>;  // the twist and the brightness offset
using Vector7d = Eigen::Matrix<double, 7, 1>;

// Normal equations of the pose twist and the brightness offset b (a seventh parameter with
// Jacobian 1), kept in blocks so that the pose-only system needs no copy.
struct NormalEquations {
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  Vector6d g = Vector6d::Zero();
  Vector6d H_pose_offset = Vector6d::Zero();
  double H_offset = 0.0;
  double g_offset = 0.0;
  // The depth rows' share of H's translation block (zero without the depth term).
  Eigen::Matrix3d H_depth_translation = Eigen::Matrix3d::Zero();
};

/// The information of the pose twist under independent pixels: with the brightness offset
/// estimated, its Schur complement (the offset is a nuisance, not part of the pose).
inline Matrix6d independent_pixel_information(const NormalEquations& normal,
                                              bool estimate_brightness_offset) {
  Matrix6d information = normal.H;
  if (estimate_brightness_offset && normal.H_offset > 0.0) {
    information -= normal.H_pose_offset * normal.H_pose_offset.transpose() / normal.H_offset;
  }
  return information;
}

}  // namespace hq::odometry::detail
