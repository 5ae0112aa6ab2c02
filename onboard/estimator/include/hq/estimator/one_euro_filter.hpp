#pragma once
/// The 1€ filter (Casiez, Roussel, Vogel, CHI 2012) for vectors and for poses on SE(3), with
/// irregular sampling: dt comes from the stamps. Used on the odometry poses before eq. 2 of the
/// core paper differentiates them.

#include "hq/base/monotonic_clock.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cmath>
#include <cstdint>

namespace hq::config {
class StrictMap;
}

namespace hq::estimator {

/// Outcome of one filter update. Rejected samples leave the state unchanged.
enum class FilterStatus {
  kFirstSample,  ///< Became the state unchanged (the 1€ filter passes its first sample).
  kOk,
  kRejectedNonFinite,  ///< NaN or inf in the input.
  kRejectedTime,       ///< t_ns not after the previous accepted sample (dt <= 0).
};

/// Static text naming the status.
const char* to_string(FilterStatus status);

/// True for kFirstSample and kOk.
inline bool accepted(FilterStatus status) {
  return status == FilterStatus::kFirstSample || status == FilterStatus::kOk;
}

struct OneEuroConfig {
  double min_cutoff_hz = 1.0;  ///< Cutoff at rest: lower = smoother, more lag at low speed.
  double beta = 0.5;           ///< Cutoff increase per unit of speed (Hz per unit/s).
  double d_cutoff_hz = 1.0;    ///< Cutoff of the low-pass on the speed estimate.
};

/// Reads {min_cutoff_hz, beta, d_cutoff_hz} strictly.
void read_config(config::StrictMap& section, OneEuroConfig& out);

/// Smoothing factor of a first-order low-pass y += alpha (x - y) with cutoff f over dt:
/// alpha = 1 / (1 + tau / dt), tau = 1 / (2 pi f) (Casiez 2012, eq. after (1)).
inline double smoothing_factor(double cutoff_hz, double dt_s) {
  const double tau_s = 1.0 / (2.0 * M_PI * cutoff_hz);
  return 1.0 / (1.0 + tau_s / dt_s);
}

/// 1€ filter of an N-vector, each axis with its own adaptive cutoff. No allocation.
template <int N>
class OneEuroFilter {
 public:
  using Vector = Eigen::Matrix<double, N, 1>;

  explicit OneEuroFilter(const OneEuroConfig& config = {}) : config_(config) {}

  /// Filters x stamped t_ns. @return kFirstSample, kOk, or a rejection (state unchanged).
  FilterStatus update(std::int64_t t_ns, const Vector& x) {
    if (!x.allFinite()) return FilterStatus::kRejectedNonFinite;
    if (!initialized_) {
      x_hat_ = x;
      dx_hat_.setZero();
      t_ns_ = t_ns;
      initialized_ = true;
      return FilterStatus::kFirstSample;
    }
    const double dt_s = hq::to_seconds(t_ns - t_ns_);
    if (!(dt_s > 0.0)) return FilterStatus::kRejectedTime;
    // Speed from the raw sample against the previous estimate, itself low-passed (Casiez 2012).
    const Vector dx = (x - x_hat_) / dt_s;
    dx_hat_ += smoothing_factor(config_.d_cutoff_hz, dt_s) * (dx - dx_hat_);
    for (int i = 0; i < N; ++i) {
      const double cutoff_hz = config_.min_cutoff_hz + config_.beta * std::abs(dx_hat_[i]);
      x_hat_[i] += smoothing_factor(cutoff_hz, dt_s) * (x[i] - x_hat_[i]);
    }
    t_ns_ = t_ns;
    return FilterStatus::kOk;
  }

  /// Scalar convenience for N == 1.
  FilterStatus update(std::int64_t t_ns, double x) requires(N == 1) {
    return update(t_ns, Vector::Constant(x));
  }

  /// The filtered value. @pre initialized()
  [[nodiscard]] const Vector& value() const { return x_hat_; }
  /// The low-passed speed (units/s) that drives the cutoff.
  [[nodiscard]] const Vector& speed() const { return dx_hat_; }
  [[nodiscard]] bool initialized() const { return initialized_; }
  [[nodiscard]] std::int64_t t_ns() const { return t_ns_; }
  /// The next sample passes through again.
  void reset() { initialized_ = false; }

 private:
  OneEuroConfig config_;
  bool initialized_ = false;
  std::int64_t t_ns_ = 0;
  Vector x_hat_ = Vector::Zero();
  Vector dx_hat_ = Vector::Zero();
};

/// 1€ filter of a rigid pose: position per axis; orientation on SO(3) along the geodesic,
/// R_hat = R_prev * exp(alpha * log(R_prev^T R)), with alpha from the rotation increment's
/// angle rate. The result stays orthonormal.
class PoseOneEuroFilter {
 public:
  PoseOneEuroFilter(const OneEuroConfig& position, const OneEuroConfig& rotation);

  /// Filters T stamped t_ns (rotation part must be a rotation within 1e-3).
  FilterStatus update(std::int64_t t_ns, const Eigen::Isometry3d& T);

  /// The filtered pose. @pre initialized()
  [[nodiscard]] const Eigen::Isometry3d& pose() const { return T_hat_; }
  /// Low-passed angle rate (rad/s) that drives the rotation cutoff.
  [[nodiscard]] double angular_speed_radps() const { return angular_speed_hat_radps_; }
  [[nodiscard]] bool initialized() const { return position_.initialized(); }
  void reset();

 private:
  OneEuroConfig rotation_config_;
  OneEuroFilter<3> position_;
  Eigen::Isometry3d T_hat_ = Eigen::Isometry3d::Identity();
  double angular_speed_hat_radps_ = 0.0;
  std::int64_t t_ns_ = 0;
};

}  // namespace hq::estimator
