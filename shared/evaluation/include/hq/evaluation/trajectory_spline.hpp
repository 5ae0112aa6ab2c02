#pragma once
/// A smooth trajectory through a ground truth's poses: a uniform cubic B-spline fitted by least
/// squares (a regression spline, not an interpolating one, so the motion capture's own noise is
/// averaged out instead of being differentiated twice). Its derivatives give what an IMU riding
/// on the tracked sensor would measure: the body rate and the acceleration.
///
/// Position: each coordinate of p_G_S(t) is a spline. Rotation: the four coordinates of the
/// sign-continuous unit quaternion q_G_S are splines and the evaluated quaternion is normalised;
/// with p(t) the unnormalised spline, omega_S = 2 Im(conj(p) p') / |p|^2, which holds for any
/// rotation range (a whole turn as in fr1_360 included).

#include "hq/recording/tum_io.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <vector>

namespace hq::evaluation {

struct TrajectorySplineConfig {
  /// Knot spacing: the shortest motion the fit follows. 0.05 s keeps a hand's or a
  /// multirotor's manoeuvres (a few Hz) and averages five 100 Hz motion-capture samples a knot.
  double knot_spacing_s = 0.05;
  /// Weight of the second difference of neighbouring control points against one pose's
  /// squared error: only keeps gaps in the ground truth well posed, far below the data's.
  double smoothing = 1e-6;
};

class TrajectorySpline {
 public:
  /// Fits poses (T_G_S, strictly increasing stamps). Throws hq::InputError for fewer
  /// than 4 poses, non-finite or unordered poses, or a knot spacing that is not positive.
  static TrajectorySpline fit(const std::vector<recording::StampedPose>& poses,
                              const TrajectorySplineConfig& config = {});

  /// The fitted span: the first to the last pose's stamp.
  [[nodiscard]] std::int64_t t_begin_ns() const { return t_begin_ns_; }
  [[nodiscard]] std::int64_t t_end_ns() const { return t_end_ns_; }
  [[nodiscard]] bool contains(std::int64_t t_ns) const {
    return t_ns >= t_begin_ns_ && t_ns <= t_end_ns_;
  }

  /// T_G_S at t. @pre contains(t_ns)
  [[nodiscard]] Eigen::Isometry3d pose(std::int64_t t_ns) const;
  /// d/dt p_G_S (m/s), world frame. @pre contains(t_ns)
  [[nodiscard]] Eigen::Vector3d velocity_G_mps(std::int64_t t_ns) const;
  /// d^2/dt^2 p_G_S (m/s^2), world frame. @pre contains(t_ns)
  [[nodiscard]] Eigen::Vector3d acceleration_G_mps2(std::int64_t t_ns) const;
  /// The sensor's angular rate in its own frame, omega_S (rad/s). @pre contains(t_ns)
  [[nodiscard]] Eigen::Vector3d omega_S_radps(std::int64_t t_ns) const;

  /// RMS distance and angle between the fit and the poses it was fitted to: the fit's
  /// residual, of the order of the ground truth's own noise when the knots are dense enough.
  [[nodiscard]] double residual_rms_m() const { return residual_rms_m_; }
  [[nodiscard]] double residual_rms_deg() const { return residual_rms_deg_; }

 private:
  using Vector7d = Eigen::Matrix<double, 7, 1>;
  /// The 7 coordinates (p, then q's x y z w) and their first or second derivative.
  [[nodiscard]] Vector7d evaluate(std::int64_t t_ns, int derivative) const;

  std::int64_t t_begin_ns_ = 0;
  std::int64_t t_end_ns_ = 0;
  double knot_spacing_s_ = 0.05;
  std::vector<Vector7d> control_points_;
  double residual_rms_m_ = 0.0;
  double residual_rms_deg_ = 0.0;
};

}  // namespace hq::evaluation
