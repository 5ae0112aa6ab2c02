#include "hq/estimator/complementary_filter.hpp"

#include "hq/base/monotonic_clock.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/geometry/lie.hpp"

#include <algorithm>
#include <cmath>

namespace hq::estimator {

Eigen::Matrix3d R_H_B_from_tilt(double roll_rad, double pitch_rad) {
  return (Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

void read_config(config::StrictMap& section, ComplementaryConfig& out) {
  section.read("k_p", out.k_p, 0.0, 100.0);
  section.read("k_i", out.k_i, 0.0, 100.0);
  section.read_positive("accel_tolerance_mps2", out.accel_tolerance_mps2, 100.0);
  section.read("max_bias_radps", out.max_bias_radps, 0.0, 10.0);
  section.read_positive("max_dt_s", out.max_dt_s, 10.0);
  section.read("init_from_accel", out.init_from_accel);
  section.read("velocity_k_p", out.velocity_k_p, 0.0, 100.0);
  section.read("velocity_k_i", out.velocity_k_i, 0.0, 100.0);
  section.read("accel_levelling_pause_s", out.accel_levelling_pause_s, 0.0, 100.0);
  section.finish();
}

ComplementaryFilter::ComplementaryFilter(const ComplementaryConfig& config) : config_(config) {}

void ComplementaryFilter::reset() {
  initialized_ = false;
  velocity_aided_ = false;
  R_ned_B_.setIdentity();
  bias_radps_.setZero();
  vision_bias_radps_.setZero();
}

void ComplementaryFilter::initialize(const Eigen::Vector3d& accel_mps2) {
  R_ned_B_.setIdentity();
  const double norm = accel_mps2.norm();
  if (config_.init_from_accel && norm > 1e-3) {
    // At rest a = -R^T g e3, so the measured "down" in Q is -a/|a| = (-s_th, c_th s_ph, c_th c_ph).
    const Eigen::Vector3d down = -accel_mps2 / norm;
    const double roll = std::atan2(down.y(), down.z());
    const double pitch = std::asin(std::clamp(-down.x(), -1.0, 1.0));
    R_ned_B_ = R_H_B_from_tilt(roll, pitch);
  }
}

FilterStatus ComplementaryFilter::update(std::int64_t t_ns, const Eigen::Vector3d& gyro_radps,
                                         const Eigen::Vector3d& accel_mps2) {
  if (!gyro_radps.allFinite() || !accel_mps2.allFinite()) {
    return FilterStatus::kRejectedNonFinite;
  }
  if (initialized_ && t_ns <= t_ns_) return FilterStatus::kRejectedTime;
  const double dt_s = hq::to_seconds(t_ns - t_ns_);
  if (!initialized_ || dt_s > config_.max_dt_s) {
    initialize(accel_mps2);
    initialized_ = true;
    t_ns_ = t_ns;
    return FilterStatus::kFirstSample;
  }

  // Mahony 2008, eq. 32 with the single direction v0 = e3 (gravity, NED): measured
  // v = -a/|a| = R^T e3 at rest, estimated v_hat = R_hat^T e3, correction omega_mes = v x v_hat.
  // The accelerometer is trusted only near 1 g, where it measures mostly gravity.
  Eigen::Vector3d omega_mes = Eigen::Vector3d::Zero();
  const double norm = accel_mps2.norm();
  const bool levelling_paused = velocity_aided_ && hq::to_seconds(t_ns - t_velocity_aided_ns_) <
                                                       config_.accel_levelling_pause_s;
  if (!levelling_paused && std::abs(norm - kGravityMps2) <= config_.accel_tolerance_mps2 &&
      norm > 1e-3) {
    const Eigen::Vector3d v = -accel_mps2 / norm;
    const Eigen::Vector3d v_hat = R_ned_B_.transpose() * Eigen::Vector3d::UnitZ();
    omega_mes = v.cross(v_hat);
  }
  const Eigen::Vector3d omega_rad =
      (gyro_radps - bias_radps_ - vision_bias_radps_ + config_.k_p * omega_mes) * dt_s;
  R_ned_B_ = geometry::orthonormalize(R_ned_B_ * geometry::exp_so3(omega_rad));
  bias_radps_ -= config_.k_i * omega_mes * dt_s;
  bias_radps_ = bias_radps_.cwiseMax(-config_.max_bias_radps).cwiseMin(config_.max_bias_radps);
  t_ns_ = t_ns;
  return FilterStatus::kOk;
}

bool ComplementaryFilter::level_on_velocity(std::int64_t t_ns,
                                            const Eigen::Vector3d& accel_error_H_mps2,
                                            double span_s) {
  // Off, it must not pause the accelerometer's levelling either.
  const bool off = config_.velocity_k_p <= 0.0 && config_.velocity_k_i <= 0.0;
  if (off || !initialized_ || !accel_error_H_mps2.allFinite() || !(span_s > 0.0) ||
      accel_error_H_mps2.head<2>().norm() > config_.accel_tolerance_mps2) {
    return false;
  }
  const Eigen::Vector3d down_B = R_ned_B_.transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d horizontal_error_H(accel_error_H_mps2.x(), accel_error_H_mps2.y(), 0.0);
  const Eigen::Vector3d error_B =
      R_H_B_from_tilt(roll_rad(), pitch_rad()).transpose() * horizontal_error_H;
  const Eigen::Vector3d omega_mes = (error_B / kGravityMps2).cross(down_B);
  R_ned_B_ = geometry::orthonormalize(R_ned_B_ *
                                      geometry::exp_so3(config_.velocity_k_p * span_s * omega_mes));
  bias_radps_ -= config_.velocity_k_i * omega_mes * span_s;
  bias_radps_ = bias_radps_.cwiseMax(-config_.max_bias_radps).cwiseMin(config_.max_bias_radps);
  velocity_aided_ = true;
  t_velocity_aided_ns_ = t_ns;
  return true;
}

void ComplementaryFilter::pause_levelling(std::int64_t t_ns) {
  velocity_aided_ = true;
  t_velocity_aided_ns_ = t_ns;
}

void ComplementaryFilter::set_vision_gyro_bias(const Eigen::Vector3d& bias_radps) {
  if (!bias_radps.allFinite()) return;
  vision_bias_radps_ =
      bias_radps.cwiseMax(-config_.max_bias_radps).cwiseMin(config_.max_bias_radps);
}

Eigen::Matrix3d ComplementaryFilter::R_N_B() const {
  return Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix() * R_ned_B_;
}

double ComplementaryFilter::roll_rad() const {
  // R = Rz(psi) Ry(theta) Rx(phi): row 2 is (-s_th, c_th s_ph, c_th c_ph).
  return std::atan2(R_ned_B_(2, 1), R_ned_B_(2, 2));
}

double ComplementaryFilter::pitch_rad() const {
  return std::asin(std::clamp(-R_ned_B_(2, 0), -1.0, 1.0));
}

}  // namespace hq::estimator
