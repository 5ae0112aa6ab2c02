#pragma once
/// Velocity tracker of the core paper, §3.1 (after Lee et al. 2013): PID on the velocity error
/// in the horizontal frame H with gravity compensation, producing thrust, roll and pitch.
/// The integral is of the velocity error, as the paper notes; the derivative acts on the
/// measured velocity (no kick on setpoint steps); conditional integration stops windup while
/// the tilt or thrust limit is active.
///
/// NED throughout: z down, so climbing is v_z < 0 and thrust points along -z of the body.
/// Roll/pitch are the ZYX Euler angles, i.e. R_HQ = Ry(pitch) Rx(roll).

#include "hq/vehicle_config/vehicle_config.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <optional>

namespace hq::control {

inline constexpr double kGravityMps2 = 9.80665;

struct VelocityControllerConfig {
  double kp_xy_per_s = 3.0;   ///< Horizontal proportional gain (m/s^2 per m/s).
  double ki_xy_per_s2 = 2.0;  ///< Horizontal integral gain (m/s^2 per m).
  double kd_xy = 0.1;         ///< Horizontal derivative gain on measured acceleration.
  double kp_z_per_s = 4.0;
  double ki_z_per_s2 = 3.0;
  double kd_z = 0.1;
  double max_integral_m = 2.0;  ///< |integral of the velocity error| per axis.
  double d_cutoff_hz = 10.0;    ///< Low-pass on the measured acceleration of the D term.
  double max_dt_s = 0.1;        ///< Longer gaps skip the I and D updates for one step.
};

/// Reads the `control:` section strictly.
void read_config(config::StrictMap& section, VelocityControllerConfig& out);

/// Attitude-thrust command for the flight controller.
struct AttitudeSetpoint {
  double thrust_n = 0.0;
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  double yaw_rate_radps = 0.0;
};

struct ControlOutput {
  AttitudeSetpoint setpoint;
  bool safe_hover = false;  ///< Inputs were not finite: hover setpoint, state frozen.
  const char* reason = "";  ///< Static text when safe_hover.
  bool tilt_saturated = false;
  bool thrust_saturated = false;
  Eigen::Vector3d a_command_mps2 = Eigen::Vector3d::Zero();  ///< PID output in H.
};

class VelocityController {
 public:
  VelocityController(const VelocityControllerConfig& config, const VehicleConfig& vehicle);

  /// One control step. All vectors in H (z down). No estimate (nullopt) or non-finite input
  /// gives the safe hover setpoint, with the reason.
  ControlOutput update(std::int64_t t_ns, const Eigen::Vector3d& v_des_H_mps,
                       double yaw_rate_des_radps,
                       const std::optional<Eigen::Vector3d>& v_est_H_mps);

  /// Thrust m g, level, no yaw rate.
  [[nodiscard]] AttitudeSetpoint hover_setpoint() const;
  [[nodiscard]] const Eigen::Vector3d& integral_m() const { return integral_m_; }
  [[nodiscard]] const VehicleConfig& vehicle() const { return vehicle_; }
  void reset();
  /// The thrust this controller commands is about to be divided by a learnt gain `ratio` times
  /// the one it was divided by so far (HoverThrustEstimator). The vertical integral, which has
  /// been carrying the difference, is moved so the thrust actually sent does not jump: in a
  /// hover (g - a_z) becomes ratio (g - a_z). PX4's PositionControl::updateHoverThrust does
  /// the same for its hover thrust.
  void rescale_thrust(double ratio);

 private:
  VelocityControllerConfig config_;
  VehicleConfig vehicle_;
  Eigen::Vector3d kp_;
  Eigen::Vector3d ki_;
  Eigen::Vector3d kd_;
  Eigen::Vector3d integral_m_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_prev_mps_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_filtered_mps2_ = Eigen::Vector3d::Zero();
  bool have_previous_ = false;
  std::int64_t t_prev_ns_ = 0;
};

}  // namespace hq::control
