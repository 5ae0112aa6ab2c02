#include "degeneracy.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <cmath>

namespace hq::odometry::detail {

namespace {

// An information matrix whose smallest eigenvalue is below this fraction of its largest is
// singular to double precision: some direction is not measured at all.
constexpr double kSingularEigenvalueRatio = 1e-12;

}  // namespace

Vector7d solve_remapped(const Matrix7d& A7, const Vector7d& b7, double degenerate_step_ratio) {
  if (degenerate_step_ratio <= 0.0) return A7.ldlt().solve(b7);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> translation(A7.topLeftCorner<3, 3>());
  if (translation.info() != Eigen::Success) return A7.ldlt().solve(b7);
  const Eigen::Vector3d& values = translation.eigenvalues();  // ascending
  int degenerate = 0;
  while (degenerate < 2 && !(values(degenerate) > degenerate_step_ratio * values(2))) {
    ++degenerate;
  }
  if (degenerate == 0) return A7.ldlt().solve(b7);
  Matrix7d Q = Matrix7d::Identity();
  Q.topLeftCorner<3, 3>() = translation.eigenvectors();
  Matrix7d A_rotated = Q.transpose() * A7 * Q;
  Vector7d b_rotated = Q.transpose() * b7;
  for (int i = 0; i < degenerate; ++i) {
    A_rotated.row(i).setZero();
    A_rotated.col(i).setZero();
    A_rotated(i, i) = 1.0;
    b_rotated(i) = 0.0;
  }
  return Q * A_rotated.ldlt().solve(b_rotated);
}

bool translation_information_too_weak(const NormalEquations& normal, double min_ratio) {
  if (min_ratio <= 0.0) return false;
  const double depth_best = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(
                                normal.H_depth_translation, Eigen::EigenvaluesOnly)
                                .eigenvalues()
                                .maxCoeff();
  const double weakest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(
                             normal.H.topLeftCorner<3, 3>(), Eigen::EigenvaluesOnly)
                             .eigenvalues()
                             .minCoeff();
  return !(weakest > min_ratio * depth_best);
}

bool translation_unconstrained(const NormalEquations& normal, const OdometryConfig& config) {
  // Eigen-decomposed rather than factorised: an LDLT solves a singular system by zeroing
  // the unconstrained directions, which would read as perfectly known.
  const Eigen::SelfAdjointEigenSolver<Matrix6d> information(
      config.vision_information_scale *
      independent_pixel_information(normal, config.estimate_brightness_offset));
  const Vector6d& values = information.eigenvalues();
  if (information.info() != Eigen::Success || !values.allFinite() ||
      values.minCoeff() <= kSingularEigenvalueRatio * values.maxCoeff()) {
    return true;
  }
  if (translation_information_too_weak(normal, config.min_translation_information_ratio)) {
    return true;
  }
  const Eigen::Matrix<double, 3, 6> V_t = information.eigenvectors().topRows<3>();
  const Eigen::Matrix3d covariance = V_t * values.cwiseInverse().asDiagonal() * V_t.transpose();
  const double largest =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(covariance, Eigen::EigenvaluesOnly)
          .eigenvalues()
          .maxCoeff();
  return !std::isfinite(largest) ||
         largest > config.max_translation_sigma_m * config.max_translation_sigma_m;
}

}  // namespace hq::odometry::detail
