#include "hq/sitl/vision_velocity_filter.hpp"

#include <Eigen/LU>

#include <algorithm>
#include <cmath>

namespace hq::sitl {

namespace {
// A measurement stamped this far ahead of the last IMU step is taken as of that step (the
// companion's clock mapping is good to a few milliseconds, not better).
constexpr std::int64_t kAheadToleranceNs = 20'000'000;
}  // namespace

VisionVelocityFilter::VisionVelocityFilter(const VisionVelocityFilterConfig& config)
    : config_(config) {}

void VisionVelocityFilter::predict(std::int64_t t_ns, const Eigen::Vector3d& a_NED_mps2) {
  if (t_last_ns_ >= 0 && t_ns > t_last_ns_ && initialised_) {
    const double dt_s = static_cast<double>(t_ns - t_last_ns_) * 1e-9;
    v_NED_mps_ += a_NED_mps2 * dt_s;
    const double q = config_.accel_noise_density_mps2;
    P_.diagonal().array() += q * q * dt_s;
  }
  t_last_ns_ = t_ns;
  history_[history_next_] = {t_ns, v_NED_mps_};
  history_next_ = (history_next_ + 1) % kHistory;
  history_count_ = std::min(history_count_ + 1, kHistory);
}

bool VisionVelocityFilter::velocity_at(std::int64_t t_ns, Eigen::Vector3d& v_NED_mps) const {
  if (history_count_ == 0) return false;
  const std::size_t newest = (history_next_ + kHistory - 1) % kHistory;
  if (t_ns >= history_[newest].t_ns) {
    if (t_ns - history_[newest].t_ns > kAheadToleranceNs) return false;
    v_NED_mps = history_[newest].v_NED_mps;
    return true;
  }
  for (std::size_t k = 1; k < history_count_; ++k) {
    const Past& past = history_[(newest + kHistory - k) % kHistory];
    if (past.t_ns <= t_ns) {
      v_NED_mps = past.v_NED_mps;
      return true;
    }
  }
  return false;  // older than the history
}

Eigen::Matrix3d VisionVelocityFilter::floored(const Eigen::Matrix3d& R_NED) const {
  const double floor = config_.min_velocity_sigma_mps * config_.min_velocity_sigma_mps;
  if (!R_NED.allFinite() || R_NED.diagonal().minCoeff() <= 0.0) {
    return floor * Eigen::Matrix3d::Identity();
  }
  Eigen::Matrix3d R = R_NED;
  for (int i = 0; i < 3; ++i) R(i, i) = std::max(R(i, i), floor);
  return R;
}

VisionFuse VisionVelocityFilter::fuse(std::int64_t t_meas_ns, const Eigen::Vector3d& z_NED_mps,
                                      const Eigen::Matrix3d& R_NED, std::uint8_t reset_counter) {
  const Eigen::Matrix3d R = floored(R_NED);
  Eigen::Vector3d v_then = Eigen::Vector3d::Zero();
  const bool have_then = velocity_at(t_meas_ns, v_then);
  if (!initialised_ || reset_counter != reset_counter_) {
    // A reset: start on the measurement, carried to now by the IMU since its stamp.
    const Eigen::Vector3d carried =
        have_then ? Eigen::Vector3d(v_NED_mps_ - v_then) : Eigen::Vector3d::Zero();
    const bool was_reset = initialised_;
    v_NED_mps_ = z_NED_mps + (initialised_ ? carried : Eigen::Vector3d::Zero());
    P_ = R;
    initialised_ = true;
    reset_counter_ = reset_counter;
    t_last_fused_ns_ = t_last_ns_;
    return was_reset ? VisionFuse::kReset : VisionFuse::kFused;
  }
  if (!have_then) return VisionFuse::kRejectedStamp;
  const Eigen::Vector3d innovation = z_NED_mps - v_then;
  const Eigen::Matrix3d S = P_ + R;
  for (int i = 0; i < 3; ++i) {
    const double limit = config_.gate_sigma * config_.gate_sigma * S(i, i);
    if (innovation[i] * innovation[i] > limit) return VisionFuse::kRejectedGate;
  }
  // The correction found at the measurement's time holds now: between the two the filter only
  // added the IMU's acceleration, the same whatever the velocity was.
  const Eigen::Matrix3d K = P_ * S.inverse();
  v_NED_mps_ += K * innovation;
  P_ = (Eigen::Matrix3d::Identity() - K) * P_;
  P_ = 0.5 * (P_ + P_.transpose()).eval();
  t_last_fused_ns_ = std::max(t_last_fused_ns_, t_last_ns_);
  return VisionFuse::kFused;
}

bool VisionVelocityFilter::fresh(std::int64_t t_ns) const {
  return initialised_ && t_last_fused_ns_ >= 0 && t_ns - t_last_fused_ns_ <= config_.stale_after_ns;
}

}  // namespace hq::sitl
