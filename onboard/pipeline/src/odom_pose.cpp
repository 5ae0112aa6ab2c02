#include "hq/pipeline/odom_pose.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace hq::pipeline {
namespace {

// A gap longer than this between samples is a stall, not a step to integrate over.
constexpr double kMaxStep_s = 0.1;

double step_s(std::int64_t& t_last_ns, std::int64_t t_ns) {
  const double dt_s =
      t_last_ns >= 0 ? std::clamp(1e-9 * static_cast<double>(t_ns - t_last_ns), 0.0, kMaxStep_s)
                     : 0.0;
  if (t_last_ns < 0 || t_ns > t_last_ns) t_last_ns = t_ns;
  return dt_s;
}

}  // namespace

void OdomPose::on_yaw_rate(std::int64_t t_ns, double yaw_rate_H_radps) {
  const double dt_s = step_s(t_yaw_ns_, t_ns);
  if (std::isfinite(yaw_rate_H_radps)) {
    pose_.yaw_rad = std::remainder(pose_.yaw_rad + yaw_rate_H_radps * dt_s, 2.0 * M_PI);
  }
  pose_.yaw_sigma_rad += config_.yaw_drift_radps * dt_s;
}

const OdomPoseEstimate& OdomPose::on_estimate(std::int64_t t_ns,
                                               const estimator::VelocityEstimate& estimate,
                                               bool landed) {
  const double dt_s = step_s(t_position_ns_, t_ns);
  if (landed) {
    pose_.valid = true;
    return pose_;
  }
  if (!estimate.usable() || !estimate.v_H_mps.allFinite()) {
    systematic_m_ += config_.blind_drift_mps * dt_s;
    pose_.position_sigma_m = std::sqrt(random_variance_m2_) + systematic_m_;
    return pose_;
  }
  // H and odom share z (both level): turning by the yaw takes v_H into odom.
  const Eigen::Vector3d v_odom_mps = Eigen::AngleAxisd(pose_.yaw_rad, Eigen::Vector3d::UnitZ()) *
                                     estimate.v_H_mps;
  pose_.p_odom_m += v_odom_mps * dt_s;
  const double speed_mps = estimate.v_H_mps.head<2>().norm();
  const double variance_xy = estimate.v_H_covariance(0, 0) + estimate.v_H_covariance(1, 1);
  if (std::isfinite(variance_xy) && variance_xy > 0.0) {
    random_variance_m2_ += 2.0 * config_.velocity_error_correlation_s * variance_xy * dt_s;
  }
  systematic_m_ +=
      (config_.velocity_error_fraction + pose_.yaw_sigma_rad) * speed_mps * dt_s;
  pose_.position_sigma_m = std::sqrt(random_variance_m2_) + systematic_m_;
  pose_.valid = true;
  return pose_;
}

}  // namespace hq::pipeline
