#include "hq/sim/quadrotor.hpp"

#include <algorithm>
#include <cmath>

namespace hq::sim {

namespace {
constexpr double kGravityMps2 = 9.81;
constexpr double kPi = 3.14159265358979323846;

/// Rx(pi): NED axes in the NWU world (core paper §3).
Eigen::Matrix3d R_N_ned() { return Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal(); }

Eigen::Vector3d vee(const Eigen::Matrix3d& S) { return {S(2, 1), S(0, 2), S(1, 0)}; }

double wrap_angle(double a) { return std::remainder(a, 2.0 * kPi); }
}  // namespace

Eigen::Matrix3d R_N_B_from_euler(double roll_rad, double pitch_rad, double yaw_rad) {
  const Eigen::Matrix3d R_ned_B = (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
                                   Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
                                   Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
                                      .toRotationMatrix();
  return R_N_ned() * R_ned_B;
}

Eigen::Vector3d euler_from_R_N_B(const Eigen::Matrix3d& R_N_B) {
  const Eigen::Matrix3d R = R_N_ned() * R_N_B;  // R_ned_B; Rx(pi) is involutive.
  const double roll = std::atan2(R(2, 1), R(2, 2));
  const double pitch = -std::asin(std::clamp(R(2, 0), -1.0, 1.0));
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  return {roll, pitch, yaw};
}

Quadrotor::Quadrotor(const QuadrotorParams& params, std::uint64_t seed)
    : params_(params), rng_(seed) {
  // X configuration in body NED: rotor i at 45 + 90 i degrees, diagonal pairs spin alike.
  // A rotor at (x, y) pushing along -z gives torque r x F = (-y T, x T, 0); its drag torque
  // about z has the sign of its spin reaction.
  const double kf = params_.thrust_coefficient;
  const double km = params_.torque_coefficient;
  for (int i = 0; i < 4; ++i) {
    const double angle = kPi / 4.0 + i * kPi / 2.0;
    const double x = params_.arm_length_m * std::cos(angle);
    const double y = params_.arm_length_m * std::sin(angle);
    const double spin = (i % 2 == 0) ? 1.0 : -1.0;
    mixer_.col(i) << kf, -y * kf, x * kf, spin * km;
  }
  mixer_inverse_ = mixer_.inverse();
  wind_N_mps_ = params_.wind_mean_mps;
  reset(Eigen::Vector3d::Zero(), 0.0);
}

double Quadrotor::hover_thrust_n() const { return params_.mass_kg * kGravityMps2; }

void Quadrotor::reset(const Eigen::Vector3d& p_N_m, double yaw_rad) {
  state_ = QuadrotorState{};
  state_.p_N_m = p_N_m;
  state_.p_N_m.z() = std::max(p_N_m.z(), params_.rest_height_m);
  state_.on_ground = state_.p_N_m.z() <= params_.rest_height_m;
  state_.q_N_B = Eigen::Quaterniond(R_N_B_from_euler(0.0, 0.0, yaw_rad));
  yaw_setpoint_rad_ = yaw_rad;
  command_ = AttitudeCommand{};
  if (!state_.on_ground) {
    command_.thrust_n = hover_thrust_n();
    const double w = std::sqrt(hover_thrust_n() / (4.0 * params_.thrust_coefficient));
    state_.rotor_speed_radps.fill(w);
  }
}

void Quadrotor::set_command(const AttitudeCommand& command) { command_ = command; }

void Quadrotor::control(double dt_s, double rotor_speed_cmd_radps[4]) {
  const Eigen::Matrix3d R = state_.q_N_B.toRotationMatrix();
  yaw_setpoint_rad_ = wrap_angle(yaw_setpoint_rad_ + command_.yaw_rate_radps * dt_s);
  const double roll = std::clamp(command_.roll_rad, -params_.max_tilt_rad, params_.max_tilt_rad);
  const double pitch = std::clamp(command_.pitch_rad, -params_.max_tilt_rad, params_.max_tilt_rad);
  const Eigen::Matrix3d R_d = R_N_B_from_euler(roll, pitch, yaw_setpoint_rad_);

  // Geometric attitude control on SO(3) (Lee, Leok, McClamroch 2010, eqs. 10-11 and 16).
  const Eigen::Vector3d e_R = 0.5 * vee(R_d.transpose() * R - R.transpose() * R_d);
  const Eigen::Vector3d omega_d(0.0, 0.0, command_.yaw_rate_radps);
  const Eigen::Vector3d e_omega = state_.omega_B_radps - omega_d;
  const double wn = 2.0 * kPi * params_.attitude_natural_hz;
  const double k_r = wn * wn;
  const double k_omega = 2.0 * params_.attitude_damping * wn;
  // Yaw is slower: rotor drag torque gives little authority, and saturating it would steal
  // collective thrust.
  const double k_yaw_omega = params_.yaw_rate_gain_per_s;
  const double k_yaw_r = 0.25 * k_yaw_omega * k_yaw_omega;
  Eigen::Vector3d alpha_d;
  alpha_d.x() = -k_r * e_R.x() - k_omega * e_omega.x();
  alpha_d.y() = -k_r * e_R.y() - k_omega * e_omega.y();
  alpha_d.z() = -k_yaw_r * e_R.z() - k_yaw_omega * e_omega.z();
  const Eigen::Vector3d& J = params_.inertia_kgm2;
  const Eigen::Vector3d& w = state_.omega_B_radps;
  const Eigen::Vector3d tau = J.cwiseProduct(alpha_d) + w.cross(J.cwiseProduct(w));

  Eigen::Vector4d wrench;
  wrench << std::max(command_.thrust_n, 0.0), tau;
  const Eigen::Vector4d u = mixer_inverse_ * wrench;
  const double u_max = params_.max_rotor_speed_radps * params_.max_rotor_speed_radps;
  for (int i = 0; i < 4; ++i) rotor_speed_cmd_radps[i] = std::sqrt(std::clamp(u[i], 0.0, u_max));
}

void Quadrotor::step(double dt_s) {
  double rotor_cmd[4];
  control(dt_s, rotor_cmd);

  // First-order motor lag, discretised exactly for the step.
  const double lag = 1.0 - std::exp(-dt_s / params_.motor_time_constant_s);
  Eigen::Vector4d u;
  for (int i = 0; i < 4; ++i) {
    double& w = state_.rotor_speed_radps[static_cast<std::size_t>(i)];
    w += (rotor_cmd[i] - w) * lag;
    u[i] = w * w;
  }
  const Eigen::Vector4d wrench = mixer_ * u;

  // Gauss-Markov gusts: exact discretisation of d g = -g / tau dt + sigma sqrt(2 / tau) dW.
  if (params_.gust_sigma_mps > 0.0) {
    const double phi = std::exp(-dt_s / params_.gust_time_constant_s);
    const double s = params_.gust_sigma_mps * std::sqrt(1.0 - phi * phi);
    for (int i = 0; i < 3; ++i) gust_N_mps_[i] = phi * gust_N_mps_[i] + s * normal_(rng_);
  }
  wind_N_mps_ = params_.wind_mean_mps + gust_N_mps_;

  const Eigen::Matrix3d R = state_.q_N_B.toRotationMatrix();
  const Eigen::Vector3d thrust_N_n = R * Eigen::Vector3d(0.0, 0.0, -wrench[0]);
  const Eigen::Vector3d drag_N_n = -params_.linear_drag_nspm * (state_.v_N_mps - wind_N_mps_);
  const Eigen::Vector3d gravity_N_n(0.0, 0.0, -params_.mass_kg * kGravityMps2);
  Eigen::Vector3d a_N = (thrust_N_n + drag_N_n + gravity_N_n) / params_.mass_kg;

  const Eigen::Vector3d& J = params_.inertia_kgm2;
  Eigen::Vector3d& w = state_.omega_B_radps;
  const Eigen::Vector3d tau = wrench.tail<3>();
  const Eigen::Vector3d omega_dot = (tau - w.cross(J.cwiseProduct(w))).cwiseQuotient(J);

  // Ground contact: the floor pushes back as long as the vehicle presses on it.
  state_.floor_impact_speed_mps = 0.0;
  const bool touching = state_.p_N_m.z() <= params_.rest_height_m + 1e-9;
  if (touching && a_N.z() <= 0.0 && state_.v_N_mps.z() <= 0.0) {
    state_.floor_impact_speed_mps = -state_.v_N_mps.z();
    const double yaw = euler_from_R_N_B(R).z();
    state_.q_N_B = Eigen::Quaterniond(R_N_B_from_euler(0.0, 0.0, yaw));
    state_.v_N_mps.setZero();
    state_.omega_B_radps.setZero();
    state_.a_N_mps2.setZero();
    state_.p_N_m.z() = params_.rest_height_m;
    state_.on_ground = true;
    yaw_setpoint_rad_ = yaw;
    return;
  }
  state_.on_ground = false;

  // Semi-implicit Euler: velocities first, then positions and attitude with the new rates.
  state_.v_N_mps += a_N * dt_s;
  state_.p_N_m += state_.v_N_mps * dt_s;
  w += omega_dot * dt_s;
  const Eigen::Vector3d rotation = w * dt_s;
  const double angle = rotation.norm();
  if (angle > 0.0) {
    state_.q_N_B = state_.q_N_B * Eigen::Quaterniond(Eigen::AngleAxisd(angle, rotation / angle));
    state_.q_N_B.normalize();
  }
  if (state_.p_N_m.z() < params_.rest_height_m) {
    // Landing: the floor stops the descent (inelastic contact).
    state_.p_N_m.z() = params_.rest_height_m;
    a_N.z() += -state_.v_N_mps.z() / dt_s;
    state_.floor_impact_speed_mps = std::max(0.0, -state_.v_N_mps.z());
    state_.v_N_mps.z() = 0.0;
  }
  state_.a_N_mps2 = a_N;
}

}  // namespace hq::sim
