#include "hq/haptics/teleop_mapping.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/geometry/camera_mount.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace hq::haptics {
namespace {

// A camera whose viewing direction has less horizontal extent than this (about 3 deg from
// vertical) has no meaningful forward direction for eq. 9.

double dead_band(double p_m, double band_m) {
  const double magnitude = std::max(std::abs(p_m) - band_m, 0.0);
  return std::copysign(magnitude, p_m);
}

double clamp_symmetric(double value, double limit, bool& saturated) {
  if (value > limit) {
    saturated = true;
    return limit;
  }
  if (value < -limit) {
    saturated = true;
    return -limit;
  }
  return value;
}

}  // namespace

TeleopMapping::TeleopMapping(const MappingConfig& config, const Eigen::Matrix3d& R_B_C)
    : config_(config) {
  try {
    alpha_rad_ = geometry::camera_heading_rad(R_B_C);  // eq. 9
  } catch (const InputError& e) {
    throw InputError(std::string("haptics: ") + e.what());
  }
  cos_alpha_ = std::cos(alpha_rad_);
  sin_alpha_ = std::sin(alpha_rad_);
}

MappedCommand TeleopMapping::map(const Eigen::Vector3d& p_D_m) const {
  MappedCommand out;
  if (!p_D_m.allFinite()) {
    out.reason = "end-effector position is not finite";
    return out;
  }
  const double p_x = dead_band(p_D_m.x(), config_.dead_band_m);
  const double p_y = dead_band(p_D_m.y(), config_.dead_band_m);
  const double p_z = dead_band(p_D_m.z(), config_.dead_band_m);
  const double k_v = config_.velocity_gain_mps_per_m;
  // Saturating the speed along alpha before splitting it keeps the command on the alpha line.
  const double forward_mps =
      clamp_symmetric(k_v * p_x, config_.max_horizontal_speed_mps, out.saturated);
  out.command.v_H_mps.x() = forward_mps * cos_alpha_;  // eq. 6
  out.command.v_H_mps.y() = forward_mps * sin_alpha_;  // eq. 7
  out.command.v_H_mps.z() =
      clamp_symmetric(-k_v * p_z, config_.max_vertical_speed_mps, out.saturated);  // eq. 8
  out.command.yaw_rate_radps = clamp_symmetric(-config_.yaw_gain_radps_per_m * p_y,
                                               config_.max_yaw_rate_radps, out.saturated);  // 10
  out.valid = true;
  return out;
}

Eigen::Vector3d TeleopMapping::displacement_for(const VelocityCommand& command) const {
  const double k_v = config_.velocity_gain_mps_per_m;
  // Pseudo-inverse of eq. 6-10's matrix: eq. 6-7 span only the alpha direction of H.
  return {(cos_alpha_ * command.v_H_mps.x() + sin_alpha_ * command.v_H_mps.y()) / k_v,
          -command.yaw_rate_radps / config_.yaw_gain_radps_per_m, -command.v_H_mps.z() / k_v};
}

ForceFeedback::ForceFeedback(const FeedbackConfig& config, const TeleopMapping& mapping)
    : config_(config), mapping_(mapping) {}

double ForceFeedback::cue_weight(std::int64_t t_ns, const VehicleEstimate& estimate) const {
  if (!estimate.valid) return 0.0;
  const double age_s = hq::to_seconds(t_ns - estimate.t_ns);
  if (age_s <= config_.stale_after_s) return 1.0;
  if (config_.fade_s <= 0.0) return 0.0;
  const double fraction = (age_s - config_.stale_after_s) / config_.fade_s;
  if (fraction >= 1.0) return 0.0;
  // Raised cosine: the cue leaves with zero slope at both ends, so the hand feels no step.
  return 0.5 * (1.0 + std::cos(std::numbers::pi * fraction));
}

FeedbackForce ForceFeedback::compute(std::int64_t t_ns, const Eigen::Vector3d& p_D_m,
                                     const Eigen::Vector3d& p_dot_D_mps,
                                     const VelocityCommand& command,
                                     const VehicleEstimate& estimate) const {
  FeedbackForce out;
  if (!p_D_m.allFinite() || !p_dot_D_mps.allFinite() || !command.v_H_mps.allFinite() ||
      !std::isfinite(command.yaw_rate_radps)) {
    return out;
  }
  Eigen::Vector3d F_D_n = -config_.centring_stiffness_n_per_m * p_D_m;
  F_D_n -= config_.damping_ns_per_m * p_dot_D_mps;
  Eigen::Vector3d F_cue_D_n = Eigen::Vector3d::Zero();

  out.cue_weight = cue_weight(t_ns, estimate);
  const bool estimate_finite =
      estimate.v_H_mps.allFinite() && std::isfinite(estimate.yaw_rate_radps);
  if (out.cue_weight > 0.0 && estimate_finite) {
    VelocityCommand error;
    error.v_H_mps = command.v_H_mps - estimate.v_H_mps;
    error.yaw_rate_radps = command.yaw_rate_radps - estimate.yaw_rate_radps;
    // Franchi et al. 2012b: F = -K (v_cmd - v_est), carried back to D by M^+.
    const Eigen::Vector3d error_D_m = mapping_.displacement_for(error);
    const Eigen::Vector3d stiffness_n_per_m(config_.velocity_stiffness_n_per_m,
                                            config_.yaw_stiffness_n_per_m,
                                            config_.velocity_stiffness_n_per_m);
    F_cue_D_n = -out.cue_weight * stiffness_n_per_m.cwiseProduct(error_D_m);
    F_D_n += F_cue_D_n;
  }
  const double magnitude_n = F_D_n.norm();
  if (magnitude_n > config_.max_force_n) {
    const double scale = config_.max_force_n / magnitude_n;
    F_D_n *= scale;
    F_cue_D_n *= scale;
    out.saturated = true;
  }
  out.F_D_n = F_D_n;
  out.F_cue_D_n = F_cue_D_n;
  return out;
}

}  // namespace hq::haptics
