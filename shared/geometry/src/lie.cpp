#include "hq/geometry/lie.hpp"

#include <cmath>

namespace hq::geometry {
namespace {
// Below this angle the closed forms lose precision; their Taylor series take over.
constexpr double kSmallAngleRad = 1e-5;
}  // namespace

Eigen::Matrix3d hat(const Eigen::Vector3d& w) {
  Eigen::Matrix3d W;
  W << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return W;
}

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& omega_rad) {
  const double theta_sq = omega_rad.squaredNorm();
  const double theta = std::sqrt(theta_sq);
  const Eigen::Matrix3d W = hat(omega_rad);
  double a = 0.0;
  double b = 0.0;
  if (theta < kSmallAngleRad) {
    a = 1.0 - theta_sq / 6.0;
    b = 0.5 - theta_sq / 24.0;
  } else {
    a = std::sin(theta) / theta;
    b = (1.0 - std::cos(theta)) / theta_sq;
  }
  return Eigen::Matrix3d::Identity() + a * W + b * W * W;
}

Eigen::Vector3d log_so3(const Eigen::Matrix3d& R) {
  // Eigen's AngleAxis is stable near 0 and pi, unlike the acos-of-trace formula.
  const Eigen::AngleAxisd angle_axis(R);
  return angle_axis.angle() * angle_axis.axis();
}

namespace {
// Left Jacobian of SO(3): maps omega-rate to the translation part of exp_se3.
Eigen::Matrix3d left_jacobian_so3(const Eigen::Vector3d& omega) {
  const double theta_sq = omega.squaredNorm();
  const double theta = std::sqrt(theta_sq);
  const Eigen::Matrix3d W = hat(omega);
  double b = 0.0;
  double c = 0.0;
  if (theta < kSmallAngleRad) {
    b = 0.5 - theta_sq / 24.0;
    c = 1.0 / 6.0 - theta_sq / 120.0;
  } else {
    b = (1.0 - std::cos(theta)) / theta_sq;
    c = (theta - std::sin(theta)) / (theta_sq * theta);
  }
  return Eigen::Matrix3d::Identity() + b * W + c * W * W;
}

Eigen::Matrix3d inverse_left_jacobian_so3(const Eigen::Vector3d& omega) {
  const double theta_sq = omega.squaredNorm();
  const double theta = std::sqrt(theta_sq);
  const Eigen::Matrix3d W = hat(omega);
  double c = 0.0;
  if (theta < kSmallAngleRad) {
    c = 1.0 / 12.0 + theta_sq / 720.0;
  } else {
    c = (1.0 - theta * std::sin(theta) / (2.0 * (1.0 - std::cos(theta)))) / theta_sq;
  }
  return Eigen::Matrix3d::Identity() - 0.5 * W + c * W * W;
}
}  // namespace

Eigen::Isometry3d exp_se3(const Vector6d& xi) {
  const Eigen::Vector3d v = xi.head<3>();
  const Eigen::Vector3d omega = xi.tail<3>();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = exp_so3(omega);
  T.translation() = left_jacobian_so3(omega) * v;
  return T;
}

Vector6d log_se3(const Eigen::Isometry3d& T) {
  const Eigen::Vector3d omega = log_so3(T.linear());
  Vector6d xi;
  xi.head<3>() = inverse_left_jacobian_so3(omega) * T.translation();
  xi.tail<3>() = omega;
  return xi;
}

Eigen::Matrix3d orthonormalize(const Eigen::Matrix3d& R) {
  return Eigen::Quaterniond(R).normalized().toRotationMatrix();
}

Matrix6d adjoint(const Eigen::Isometry3d& T) {
  Matrix6d Ad = Matrix6d::Zero();
  Ad.topLeftCorner<3, 3>() = T.linear();
  Ad.topRightCorner<3, 3>() = hat(T.translation()) * T.linear();
  Ad.bottomRightCorner<3, 3>() = T.linear();
  return Ad;
}

}  // namespace hq::geometry
