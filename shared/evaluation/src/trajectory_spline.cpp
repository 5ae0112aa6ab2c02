#include "hq/evaluation/trajectory_spline.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"

#include <Eigen/Sparse>

#include <algorithm>
#include <array>
#include <cmath>
#include <fmt/format.h>

namespace hq::evaluation {
namespace {

constexpr int kOrder = 4;  // cubic: each segment blends four control points
using Weights = std::array<double, 4>;

/// The uniform cubic B-spline's four blending weights at u in [0, 1], or their first or second
/// derivative with respect to u.
Weights basis(double u, int derivative) {
  const double v = 1.0 - u;
  switch (derivative) {
    case 0:
      return {v * v * v / 6.0, (3.0 * u * u * u - 6.0 * u * u + 4.0) / 6.0,
              (-3.0 * u * u * u + 3.0 * u * u + 3.0 * u + 1.0) / 6.0, u * u * u / 6.0};
    case 1:
      return {-v * v / 2.0, (3.0 * u * u - 4.0 * u) / 2.0, (-3.0 * u * u + 2.0 * u + 1.0) / 2.0,
              u * u / 2.0};
    default:
      return {v, 3.0 * u - 2.0, 1.0 - 3.0 * u, u};
  }
}

struct Segment {
  int first = 0;   // index of the first of the four control points
  double u = 0.0;  // position within the segment, 0..1
};

Segment locate(std::int64_t t_ns, std::int64_t t_begin_ns, double knot_spacing_s, int segments) {
  const double s = hq::to_seconds(t_ns - t_begin_ns) / knot_spacing_s;
  const int i = std::clamp(static_cast<int>(std::floor(s)), 0, segments - 1);
  return {i, std::clamp(s - i, 0.0, 1.0)};
}

}  // namespace

TrajectorySpline TrajectorySpline::fit(const std::vector<recording::StampedPose>& poses,
                                       const TrajectorySplineConfig& config) {
  if (!(config.knot_spacing_s > 0.0) || !(config.smoothing >= 0.0)) {
    throw InputError(
        fmt::format("trajectory spline: knot spacing {} s, smoothing {}, expected > 0 and >= 0",
                    config.knot_spacing_s, config.smoothing));
  }
  if (poses.size() < static_cast<std::size_t>(kOrder)) {
    throw InputError(
        fmt::format("trajectory spline: {} poses, expected at least {}", poses.size(), kOrder));
  }
  for (std::size_t k = 0; k < poses.size(); ++k) {
    if (!poses[k].T_G_S.matrix().allFinite()) {
      throw InputError(fmt::format("trajectory spline: pose {} is not finite", k + 1));
    }
    if (k > 0 && poses[k].t_ns <= poses[k - 1].t_ns) {
      throw InputError(fmt::format(
          "trajectory spline: pose {} stamped {} ns, not after the previous one ({} ns)", k + 1,
          poses[k].t_ns, poses[k - 1].t_ns));
    }
  }
  TrajectorySpline spline;
  spline.t_begin_ns_ = poses.front().t_ns;
  spline.t_end_ns_ = poses.back().t_ns;
  spline.knot_spacing_s_ = config.knot_spacing_s;
  const double span_s = hq::to_seconds(spline.t_end_ns_ - spline.t_begin_ns_);
  const int segments = std::max(1, static_cast<int>(std::ceil(span_s / config.knot_spacing_s)));
  const int n = segments + kOrder - 1;

  // The observations: position and the sign-continuous quaternion (q and -q are one rotation;
  // a spline needs one of them, the one nearest the previous sample).
  std::vector<Vector7d> observed(poses.size());
  Eigen::Quaterniond q_previous = Eigen::Quaterniond::Identity();
  for (std::size_t k = 0; k < poses.size(); ++k) {
    Eigen::Quaterniond q(poses[k].T_G_S.linear());
    q.normalize();
    if (k > 0 && q.coeffs().dot(q_previous.coeffs()) < 0.0) q.coeffs() = -q.coeffs();
    q_previous = q;
    observed[k] << poses[k].T_G_S.translation(), q.coeffs();
  }

  // Normal equations of the least-squares fit, banded (each pose touches four control points).
  std::vector<Eigen::Triplet<double>> entries;
  entries.reserve(poses.size() * 16 + static_cast<std::size_t>(n) * 9);
  Eigen::Matrix<double, Eigen::Dynamic, 7> rhs =
      Eigen::Matrix<double, Eigen::Dynamic, 7>::Zero(n, 7);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const Segment seg = locate(poses[k].t_ns, spline.t_begin_ns_, config.knot_spacing_s, segments);
    const Weights b = basis(seg.u, 0);
    for (std::size_t a = 0; a < b.size(); ++a) {
      const int row = seg.first + static_cast<int>(a);
      rhs.row(row) += b[a] * observed[k].transpose();
      for (std::size_t c = 0; c < b.size(); ++c) {
        entries.emplace_back(row, seg.first + static_cast<int>(c), b[a] * b[c]);
      }
    }
  }
  // Second differences c[j-1] - 2 c[j] + c[j+1]: keeps knots without data (gaps) determined.
  constexpr std::array<double, 3> kSecondDifference = {1.0, -2.0, 1.0};
  for (int j = 1; j + 1 < n; ++j) {
    for (std::size_t a = 0; a < kSecondDifference.size(); ++a) {
      for (std::size_t c = 0; c < kSecondDifference.size(); ++c) {
        entries.emplace_back(j - 1 + static_cast<int>(a), j - 1 + static_cast<int>(c),
                             config.smoothing * kSecondDifference[a] * kSecondDifference[c]);
      }
    }
  }
  Eigen::SparseMatrix<double> normal(n, n);
  normal.setFromTriplets(entries.begin(), entries.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(normal);
  if (solver.info() != Eigen::Success) {
    throw InputError(fmt::format(
        "trajectory spline: {} poses leave the fit of {} control points singular; expected "
        "poses spread over the span (a smaller knot spacing than the gaps needs smoothing > 0)",
        poses.size(), n));
  }
  const Eigen::Matrix<double, Eigen::Dynamic, 7> solution = solver.solve(rhs);
  spline.control_points_.resize(static_cast<std::size_t>(n));
  for (int j = 0; j < n; ++j) spline.control_points_[static_cast<std::size_t>(j)] = solution.row(j);

  double sq_m = 0.0;
  double sq_rad = 0.0;
  for (const recording::StampedPose& pose : poses) {
    const Eigen::Isometry3d fitted = spline.pose(pose.t_ns);
    sq_m += (fitted.translation() - pose.T_G_S.translation()).squaredNorm();
    const double angle =
        Eigen::AngleAxisd(fitted.linear().transpose() * pose.T_G_S.linear()).angle();
    sq_rad += angle * angle;
  }
  const auto count = static_cast<double>(poses.size());
  spline.residual_rms_m_ = std::sqrt(sq_m / count);
  spline.residual_rms_deg_ = std::sqrt(sq_rad / count) * 180.0 / M_PI;
  return spline;
}

TrajectorySpline::Vector7d TrajectorySpline::evaluate(std::int64_t t_ns, int derivative) const {
  const int segments = static_cast<int>(control_points_.size()) - (kOrder - 1);
  const Segment seg = locate(t_ns, t_begin_ns_, knot_spacing_s_, segments);
  const Weights b = basis(seg.u, derivative);
  const double scale = std::pow(knot_spacing_s_, -derivative);  // d/dt = (1 / spacing) d/du
  Vector7d out = Vector7d::Zero();
  for (std::size_t a = 0; a < b.size(); ++a) {
    out += b[a] * control_points_[static_cast<std::size_t>(seg.first) + a];
  }
  return scale * out;
}

Eigen::Isometry3d TrajectorySpline::pose(std::int64_t t_ns) const {
  const Vector7d x = evaluate(t_ns, 0);
  Eigen::Quaterniond q(x[6], x[3], x[4], x[5]);
  q.normalize();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.toRotationMatrix();
  T.translation() = x.head<3>();
  return T;
}

Eigen::Vector3d TrajectorySpline::velocity_G_mps(std::int64_t t_ns) const {
  return evaluate(t_ns, 1).head<3>();
}

Eigen::Vector3d TrajectorySpline::acceleration_G_mps2(std::int64_t t_ns) const {
  return evaluate(t_ns, 2).head<3>();
}

Eigen::Vector3d TrajectorySpline::omega_S_radps(std::int64_t t_ns) const {
  const Vector7d x = evaluate(t_ns, 0);
  const Vector7d dx = evaluate(t_ns, 1);
  const Eigen::Quaterniond p(x[6], x[3], x[4], x[5]);
  const Eigen::Quaterniond dp(dx[6], dx[3], dx[4], dx[5]);
  // q = p / |p|: q* q' = (p* p' - (p . p')) / |p|^2, whose vector part is Im(p* p') / |p|^2.
  return 2.0 * (p.conjugate() * dp).vec() / p.squaredNorm();
}

}  // namespace hq::evaluation
