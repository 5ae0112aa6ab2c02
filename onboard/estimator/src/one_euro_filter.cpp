#include "hq/estimator/one_euro_filter.hpp"

#include "hq/base/monotonic_clock.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/geometry/lie.hpp"

namespace hq::estimator {

const char* to_string(FilterStatus status) {
  switch (status) {
    case FilterStatus::kFirstSample:
      return "first sample";
    case FilterStatus::kOk:
      return "ok";
    case FilterStatus::kRejectedNonFinite:
      return "rejected: non-finite input";
    case FilterStatus::kRejectedTime:
      return "rejected: stamp not after the previous sample";
  }
  return "unknown";
}

void read_config(config::StrictMap& section, OneEuroConfig& out) {
  section.read_positive("min_cutoff_hz", out.min_cutoff_hz, 1000.0);
  section.read("beta", out.beta, 0.0, 1e6);
  section.read_positive("d_cutoff_hz", out.d_cutoff_hz, 1000.0);
  section.finish();
}

PoseOneEuroFilter::PoseOneEuroFilter(const OneEuroConfig& position, const OneEuroConfig& rotation)
    : rotation_config_(rotation), position_(position) {}

void PoseOneEuroFilter::reset() {
  position_.reset();
  angular_speed_hat_radps_ = 0.0;
}

FilterStatus PoseOneEuroFilter::update(std::int64_t t_ns, const Eigen::Isometry3d& T) {
  if (!T.matrix().allFinite()) return FilterStatus::kRejectedNonFinite;
  const Eigen::Matrix3d R = T.linear();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-3 ||
      R.determinant() < 0.0) {
    return FilterStatus::kRejectedNonFinite;
  }
  if (!position_.initialized()) {
    position_.update(t_ns, T.translation());
    T_hat_.linear() = geometry::orthonormalize(R);
    T_hat_.translation() = T.translation();
    angular_speed_hat_radps_ = 0.0;
    t_ns_ = t_ns;
    return FilterStatus::kFirstSample;
  }
  const double dt_s = hq::to_seconds(t_ns - t_ns_);
  if (!(dt_s > 0.0)) return FilterStatus::kRejectedTime;
  position_.update(t_ns, T.translation());

  // Rotation: the increment from the previous estimate to the sample, as a tangent vector.
  const Eigen::Matrix3d R_prev = T_hat_.linear();
  const Eigen::Vector3d increment_rad = geometry::log_so3(R_prev.transpose() * R);
  const double angular_speed_radps = increment_rad.norm() / dt_s;
  angular_speed_hat_radps_ += smoothing_factor(rotation_config_.d_cutoff_hz, dt_s) *
                              (angular_speed_radps - angular_speed_hat_radps_);
  const double cutoff_hz =
      rotation_config_.min_cutoff_hz + rotation_config_.beta * angular_speed_hat_radps_;
  const double alpha = smoothing_factor(cutoff_hz, dt_s);
  // Geodesic interpolation R_prev -> R by alpha: the SO(3) analogue of x_hat += alpha (x - x_hat).
  T_hat_.linear() = geometry::orthonormalize(R_prev * geometry::exp_so3(alpha * increment_rad));
  T_hat_.translation() = position_.value();
  t_ns_ = t_ns;
  return FilterStatus::kOk;
}

}  // namespace hq::estimator
