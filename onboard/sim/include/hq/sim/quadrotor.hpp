#pragma once
/// Quadrotor rigid body with rotor lag, linear air drag, seeded wind gusts, a floor at z = 0 and
/// the attitude controller + mixer a flight controller runs. Frames (core paper §3): world W is
/// NWU, body Q is NED; R_N_B = Rx(pi) Rz(psi) Ry(theta) Rx(phi).

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <random>

namespace hq::sim {

/// The four numbers the on-board velocity tracker produces (core paper §3.1).
struct AttitudeCommand {
  double thrust_n = 0.0;        ///< collective thrust along body -z.
  double roll_rad = 0.0;        ///< phi of R_N_B = Rx(pi) Rz(psi) Ry(theta) Rx(phi).
  double pitch_rad = 0.0;       ///< theta (positive: nose up, accelerates backwards).
  double yaw_rate_radps = 0.0;  ///< d psi / dt.
};

struct QuadrotorParams {
  double mass_kg = 1.0;  ///< core paper §2: about 1 kg with the camera.
  Eigen::Vector3d inertia_kgm2 = Eigen::Vector3d(0.012, 0.012, 0.022);  ///< body diag.
  double arm_length_m = 0.25;          ///< 0.5 m span (core paper §2).
  double thrust_coefficient = 6.8e-6;  ///< rotor thrust (N) per (rad/s)^2.
  double torque_coefficient = 1.1e-7;  ///< rotor drag torque (N m) per (rad/s)^2.
  double max_rotor_speed_radps = 1100.0;
  double motor_time_constant_s = 0.02;  ///< first-order lag of rotor speed.
  double linear_drag_nspm = 0.25;       ///< air drag force per relative airspeed (N s/m).
  double rest_height_m = 0.08;          ///< body centre height when standing on the floor.
  // Attitude controller (a flight controller's inner loop), per unit inertia.
  double attitude_natural_hz = 3.0;  ///< roll/pitch loop natural frequency.
  double attitude_damping = 0.8;
  double yaw_rate_gain_per_s = 8.0;
  double max_tilt_rad = 0.6;  ///< commands beyond this are clamped.
  // Wind: mean plus a first-order Gauss-Markov gust per axis (W frame).
  Eigen::Vector3d wind_mean_mps = Eigen::Vector3d::Zero();
  double gust_sigma_mps = 0.0;  ///< stationary standard deviation of each gust axis.
  double gust_time_constant_s = 2.0;
};

/// Truth state of the rigid body.
struct QuadrotorState {
  Eigen::Vector3d p_N_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_N_mps = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_N_B = Eigen::Quaterniond(0.0, 1.0, 0.0, 0.0);  ///< Rx(pi): level.
  Eigen::Vector3d omega_B_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d a_N_mps2 = Eigen::Vector3d::Zero();  ///< of the last step.
  std::array<double, 4> rotor_speed_radps{};
  bool on_ground = true;
  /// Speed at which the floor stopped the vehicle in the last step (m/s), 0 when it did not.
  double floor_impact_speed_mps = 0.0;
};

/// Rotation R_N_B of NED body Euler angles in the NWU world (core paper §3).
Eigen::Matrix3d R_N_B_from_euler(double roll_rad, double pitch_rad, double yaw_rad);
/// Inverse of R_N_B_from_euler: (roll, pitch, yaw).
Eigen::Vector3d euler_from_R_N_B(const Eigen::Matrix3d& R_N_B);

class Quadrotor {
 public:
  Quadrotor(const QuadrotorParams& params, std::uint64_t seed);

  /// Places the vehicle at rest on the floor (or at p_N_m if above it) with yaw.
  void reset(const Eigen::Vector3d& p_N_m, double yaw_rad);
  void set_command(const AttitudeCommand& command);
  /// Advances by dt_s (fixed step; semi-implicit Euler). Allocates nothing.
  void step(double dt_s);

  [[nodiscard]] const QuadrotorState& state() const { return state_; }
  [[nodiscard]] const QuadrotorParams& params() const { return params_; }
  [[nodiscard]] const Eigen::Vector3d& wind_N_mps() const { return wind_N_mps_; }
  /// Thrust needed to hover (N).
  [[nodiscard]] double hover_thrust_n() const;

 private:
  void control(double dt_s, double rotor_speed_cmd_radps[4]);

  QuadrotorParams params_;
  QuadrotorState state_;
  AttitudeCommand command_;
  double yaw_setpoint_rad_ = 0.0;
  Eigen::Matrix4d mixer_inverse_ = Eigen::Matrix4d::Identity();  ///< [T; tau] -> rotor w^2.
  Eigen::Matrix4d mixer_ = Eigen::Matrix4d::Identity();          ///< rotor w^2 -> [T; tau].
  Eigen::Vector3d wind_N_mps_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d gust_N_mps_ = Eigen::Vector3d::Zero();
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
};

}  // namespace hq::sim
