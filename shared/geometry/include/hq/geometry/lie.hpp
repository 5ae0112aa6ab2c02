#pragma once
/// SO(3) and SE(3) exponential and logarithm maps on Eigen types.
/// Twist order is (v, omega): translation part first, as in Sophus and basalt.
/// exp_se3(xi) acts on points on the left: p' = exp_se3(xi) * p.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hq::geometry {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// The skew-symmetric matrix [w]x such that hat(w) * p == w.cross(p).
Eigen::Matrix3d hat(const Eigen::Vector3d& w);

/// Rotation by the axis-angle vector omega_rad (Rodrigues), exact for small angles too.
Eigen::Matrix3d exp_so3(const Eigen::Vector3d& omega_rad);
/// Axis-angle vector of a rotation matrix; angle in [0, pi].
/// @pre R is orthonormal with det +1 (within 1e-6).
Eigen::Vector3d log_so3(const Eigen::Matrix3d& R);

/// Rigid transform of a twist xi = (v, omega).
Eigen::Isometry3d exp_se3(const Vector6d& xi);
/// Twist of a rigid transform; inverse of exp_se3 for angles below pi.
Vector6d log_se3(const Eigen::Isometry3d& T);

/// Projects a nearly-orthonormal matrix (e.g. after integration) back onto SO(3).
Eigen::Matrix3d orthonormalize(const Eigen::Matrix3d& R);

/// 6x6 adjoint of T in the (v, omega) twist order: Ad(T) xi = log(T exp(xi) T^-1).
Matrix6d adjoint(const Eigen::Isometry3d& T);

}  // namespace hq::geometry
