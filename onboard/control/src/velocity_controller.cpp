#include "hq/control/velocity_controller.hpp"

#include "hq/base/monotonic_clock.hpp"
#include "hq/config/strict_yaml.hpp"

#include <algorithm>
#include <cmath>

namespace hq::control {

void read_config(config::StrictMap& section, VelocityControllerConfig& out) {
  // A zero proportional gain never tracks a velocity command; integral and derivative terms
  // may be zero.
  section.read_positive("kp_xy_per_s", out.kp_xy_per_s, 100.0);
  section.read("ki_xy_per_s2", out.ki_xy_per_s2, 0.0, 100.0);
  section.read("kd_xy", out.kd_xy, 0.0, 10.0);
  section.read_positive("kp_z_per_s", out.kp_z_per_s, 100.0);
  section.read("ki_z_per_s2", out.ki_z_per_s2, 0.0, 100.0);
  section.read("kd_z", out.kd_z, 0.0, 10.0);
  section.read("max_integral_m", out.max_integral_m, 0.0, 1e3);
  section.read_positive("d_cutoff_hz", out.d_cutoff_hz, 1e3);
  section.read_positive("max_dt_s", out.max_dt_s, 10.0);
  section.finish();
}

VelocityController::VelocityController(const VelocityControllerConfig& config,
                                       const VehicleConfig& vehicle)
    : config_(config),
      vehicle_(vehicle),
      kp_(config.kp_xy_per_s, config.kp_xy_per_s, config.kp_z_per_s),
      ki_(config.ki_xy_per_s2, config.ki_xy_per_s2, config.ki_z_per_s2),
      kd_(config.kd_xy, config.kd_xy, config.kd_z) {}

void VelocityController::reset() {
  integral_m_.setZero();
  accel_filtered_mps2_.setZero();
  have_previous_ = false;
}

void VelocityController::rescale_thrust(double ratio) {
  if (!(ratio > 0.0 && std::isfinite(ratio)) || config_.ki_z_per_s2 <= 0.0) return;
  // The integral's acceleration (NED: up is -z) is the part of the command that persists.
  const double a_z_mps2 = config_.ki_z_per_s2 * integral_m_.z();
  const double a_z_new_mps2 = kGravityMps2 - ratio * (kGravityMps2 - a_z_mps2);
  integral_m_.z() = std::clamp(a_z_new_mps2 / config_.ki_z_per_s2, -config_.max_integral_m,
                               config_.max_integral_m);
}

AttitudeSetpoint VelocityController::hover_setpoint() const {
  AttitudeSetpoint hover;
  hover.thrust_n = vehicle_.mass_kg * kGravityMps2;
  return hover;
}

ControlOutput VelocityController::update(std::int64_t t_ns, const Eigen::Vector3d& v_des_H_mps,
                                         double yaw_rate_des_radps,
                                         const std::optional<Eigen::Vector3d>& v_est_H_mps) {
  ControlOutput out;
  const bool finite = v_des_H_mps.allFinite() && std::isfinite(yaw_rate_des_radps) &&
                      (!v_est_H_mps || v_est_H_mps->allFinite());
  if (!v_est_H_mps || !finite) {
    out.setpoint = hover_setpoint();
    out.safe_hover = true;
    out.reason = finite ? "no velocity estimate: hover" : "non-finite velocity input: hover";
    have_previous_ = false;  // no derivative across the gap; the integral is kept frozen
    return out;
  }
  const Eigen::Vector3d& v_H_est_mps = *v_est_H_mps;

  const double dt_s = hq::to_seconds(t_ns - t_prev_ns_);
  const bool step_valid = have_previous_ && dt_s > 0.0 && dt_s <= config_.max_dt_s;
  if (step_valid) {
    // Derivative on measurement, low-passed: a setpoint step does not kick the output.
    const Eigen::Vector3d accel_mps2 = (v_H_est_mps - v_prev_mps_) / dt_s;
    const double tau_s = 1.0 / (2.0 * M_PI * config_.d_cutoff_hz);
    accel_filtered_mps2_ += dt_s / (tau_s + dt_s) * (accel_mps2 - accel_filtered_mps2_);
  }
  v_prev_mps_ = v_H_est_mps;
  t_prev_ns_ = t_ns;
  if (!have_previous_) accel_filtered_mps2_.setZero();
  have_previous_ = true;

  const Eigen::Vector3d error_mps = v_des_H_mps - v_H_est_mps;
  const Eigen::Vector3d a_cmd = kp_.cwiseProduct(error_mps) + ki_.cwiseProduct(integral_m_) -
                                kd_.cwiseProduct(accel_filtered_mps2_);
  out.a_command_mps2 = a_cmd;

  // Gravity compensation: the force the rotors must give is m (a - g e3) in NED.
  const Eigen::Vector3d force_n = vehicle_.mass_kg * (a_cmd - Eigen::Vector3d(0, 0, kGravityMps2));
  // Vertical first: the upward thrust component within the thrust range.
  double up_n = -force_n.z();
  if (up_n > vehicle_.max_thrust_n || up_n < vehicle_.min_thrust_n) {
    out.thrust_saturated = true;
    up_n = std::clamp(up_n, vehicle_.min_thrust_n, vehicle_.max_thrust_n);
  }
  // Then horizontal within the tilt limit and what thrust is left.
  Eigen::Vector2d horizontal_n = force_n.head<2>();
  const double max_horizontal_n = std::min(
      up_n * std::tan(vehicle_.max_tilt_rad),
      std::sqrt(std::max(0.0, vehicle_.max_thrust_n * vehicle_.max_thrust_n - up_n * up_n)));
  const double horizontal_norm = horizontal_n.norm();
  if (horizontal_norm > max_horizontal_n) {
    out.tilt_saturated = true;
    horizontal_n *= max_horizontal_n / horizontal_norm;
  }

  // Conditional integration: an axis whose output saturates integrates only errors that unwind
  // its integral, so a long saturation leaves nothing to overshoot on afterwards.
  if (step_valid) {
    for (int i = 0; i < 3; ++i) {
      const bool saturated = (i < 2) ? out.tilt_saturated : out.thrust_saturated;
      if (!saturated || error_mps[i] * integral_m_[i] < 0.0) {
        integral_m_[i] = std::clamp(integral_m_[i] + error_mps[i] * dt_s, -config_.max_integral_m,
                                    config_.max_integral_m);
      }
    }
  }

  // F = -T (c_phi s_theta, -s_phi, c_phi c_theta) for R_HQ = Ry(theta) Rx(phi), thrust along -z_Q.
  const double thrust_n = std::sqrt(up_n * up_n + horizontal_n.squaredNorm());
  out.setpoint.thrust_n = thrust_n;
  out.setpoint.roll_rad = std::asin(std::clamp(horizontal_n.y() / thrust_n, -1.0, 1.0));
  out.setpoint.pitch_rad = std::atan2(-horizontal_n.x(), up_n);
  out.setpoint.yaw_rate_radps =
      std::clamp(yaw_rate_des_radps, -vehicle_.max_yaw_rate_radps, vehicle_.max_yaw_rate_radps);
  return out;
}

}  // namespace hq::control
