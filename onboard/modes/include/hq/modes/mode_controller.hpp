#pragma once
/// Flight modes feeding the velocity tracker (core paper §3.1): each mode gives v*_des in H and
/// a yaw rate; the obstacle term is always added, v_des = v*_des + v_obs, and the
/// VelocityController turns it into an attitude-thrust setpoint.
///
/// Switching is bumpless: after a mode change (or a teleop timeout) v*_des and the yaw rate ramp
/// from their values at the switch, rate-limited, so thrust and tilt have no step.

#include "hq/control/velocity_controller.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <limits>
#include <optional>

namespace hq::config {
class StrictMap;
}

namespace hq::modes {

enum class Mode { kTeleop, kHover, kLand, kMarker, kExplore };
const char* to_string(Mode mode);

/// Who asks for a mode change. Operators (the haptic station, ground stations) are held to the
/// hysteresis below (a minimum dwell per mode and a rate limit), so that requests toggled faster
/// than the vehicle can act on them cannot ratchet it down (issue 39: hover <-> land every 0.5 s
/// sank it into the room's clutter). The vehicle's own requests (land on a lost estimate, the
/// flight controller's failsafes, the marker stage's hand-over to land) are never delayed.
enum class RequestOrigin { kOperator, kVehicle };

/// Where the vehicle is in its flight: on the floor with motors idle, climbing to its take-off
/// height, flying, or descending in land mode until touchdown.
enum class FlightState { kLanded, kTakingOff, kAirborne, kLanding };
const char* to_string(FlightState state);

struct ModesConfig {
  double teleop_timeout_s = 0.5;             ///< Older operator commands fall back to hover.
  double land_speed_mps = 0.3;               ///< Descent speed in land (NED: +z).
  double max_switch_accel_mps2 = 1.0;        ///< Ramp rate of v*_des after a switch.
  double max_switch_yaw_accel_radps2 = 2.0;  ///< Ramp rate of the yaw rate after a switch.
  /// The vehicle starts on the ground, motors idle; it takes off when its mode asks to climb
  /// faster than this (NED: v*_des z < -takeoff_climb_mps), e.g. the operator pulling up.
  bool start_landed = true;
  double takeoff_climb_mps = 0.1;
  /// In land: sinking slower than touchdown_speed_mps for touchdown_s means the floor holds the
  /// vehicle: motors go idle (landed).
  double touchdown_speed_mps = 0.08;
  double touchdown_s = 1.0;
  /// In land without a usable estimate (the blind descent), level: with the accelerometer
  /// (set_specific_force_H, fresh within 0.2 s) the thrust holds a descent of
  /// blind_descent_speed_mps on the vertical velocity the IMU integrates from the last estimate,
  /// between blind_descent_thrust_ratio and 2 - that of m g; without it, the thrust is that
  /// fraction of m g (which sinks faster and faster, the more so the worse the mass is known).
  /// Landed only on evidence of the floor (as PX4's land detector), never from the estimate's
  /// loss alone: after at least blind_descent_s, either a known height below
  /// touchdown_max_height_m, or an impact (specific force above impact_specific_force_mps2)
  /// followed by touchdown_s of stillness (specific force within still_specific_force_mps2 of
  /// g: the floor, not the thrust, carries the vehicle).
  double blind_descent_thrust_ratio = 0.9;
  double blind_descent_speed_mps = 0.5;
  double blind_descent_s = 3.0;
  /// A touchdown needs the height, when known, below this (m above the floor).
  double touchdown_max_height_m = 0.4;
  double impact_specific_force_mps2 = 14.0;
  double still_specific_force_mps2 = 0.4;
  /// The flight envelope's ceiling (m above the floor): climbs slow down over the last
  /// ceiling_slowdown_m and stop at it, and with the height unknown (floor beyond the depth
  /// sensor's range and no velocity to integrate) nothing climbs.
  double max_height_m = 2.0;
  double ceiling_slowdown_m = 0.5;
  /// The envelope's horizontal bound (as PX4's GF_MAX_HOR_DIST): the distance from the take-off
  /// point, dead-reckoned by the chain (set_offset_from_takeoff_H_m). Moving away from it slows
  /// over the last horizontal_slowdown_m and stops at it; along and back towards it is free.
  double max_distance_from_takeoff_m = 10.0;
  double horizontal_slowdown_m = 1.0;
  /// An explicit take-off (request_takeoff) climbs at takeoff_speed_mps to this height above
  /// the floor, slowing down over the last takeoff_slowdown_m so that it does not overshoot,
  /// then flies the mode asked for.
  double takeoff_target_height_m = 1.0;
  double takeoff_speed_mps = 0.5;
  double takeoff_slowdown_m = 0.3;
  /// Operator mode changes in flight: refused until the current mode, when an operator chose it,
  /// has been flown for min_mode_dwell_s (0: no dwell), and, except to hover, beyond
  /// operator_mode_change_burst changes at once, refilled at operator_mode_changes_per_min.
  double min_mode_dwell_s = 1.5;
  double operator_mode_changes_per_min = 10.0;
  int operator_mode_change_burst = 3;
  /// Land -> hover below this height (m above the floor) climbs back to it before hovering,
  /// as PX4's landing abort climbs to MIS_LND_ABRT_ALT.
  double land_abort_min_height_m = 0.8;
};

/// Reads the `modes:` section strictly.
void read_config(config::StrictMap& section, ModesConfig& out);

/// The operator's latest command (from the haptic mapping, eqs. 6-10), in H.
struct OperatorCommand {
  std::int64_t t_ns = 0;
  Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();
  double yaw_rate_radps = 0.0;
};

/// What a mode wants: v*_des in H and a yaw rate, or invalid with a reason.
struct ModeCommand {
  bool valid = false;
  const char* reason = "";
  Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();
  double yaw_rate_radps = 0.0;
};

/// Supplies the marker and explore modes (implemented elsewhere). Called once per step; must
/// not allocate.
class VelocityProvider {
 public:
  virtual ~VelocityProvider() = default;
  virtual ModeCommand desired(std::int64_t t_ns) = 0;
};

struct ModeSwitch {
  bool accepted = false;
  const char* reason = "";  ///< When refused: valid until the next request.
};

struct ModeOutput {
  Mode mode = Mode::kHover;
  Eigen::Vector3d v_star_des_H_mps = Eigen::Vector3d::Zero();  ///< After the ramp.
  double yaw_rate_des_radps = 0.0;
  Eigen::Vector3d v_des_H_mps = Eigen::Vector3d::Zero();  ///< v*_des + v_obs.
  bool teleop_timed_out = false;  ///< In teleop, the command was stale: hovering.
  bool provider_failed = false;   ///< Marker/explore provider gave no command: hovering.
  bool ramping = false;           ///< A switch ramp is in progress.
  bool landed = false;            ///< On the ground, motors idle (setpoint thrust 0).
  bool blind_descent = false;     ///< Landing without a velocity estimate.
  /// The blind descent holds its rate on the IMU (else: the fixed thrust ratio).
  bool blind_descent_rate_held = false;
  double blind_descent_v_z_mps = 0.0;  ///< The IMU's vertical velocity it holds (NED, down +).
  bool taking_off = false;  ///< Climbing to takeoff_target_height_m after request_takeoff().
  /// Climbing back to land_abort_min_height_m after land -> hover low down (also taking_off).
  bool land_abort_climb = false;
  /// The command was limited by the envelope: its climb (ceiling, or the height unknown) or its
  /// horizontal part (the bound around the take-off point).
  bool envelope_limited = false;
  double envelope_max_climb_mps = 0.0;  ///< The climb allowed (NED: -z); all asked if not cut.
  bool envelope_horizontal_limited = false;
  /// The horizontal command after the bound (x, y in H), when envelope_horizontal_limited.
  Eigen::Vector2d envelope_v_xy_H_mps = Eigen::Vector2d::Zero();
  const char* envelope_reason = "";  ///< Static text when limited.
  FlightState flight_state = FlightState::kLanded;
  /// The operator's command is not flown this step (landed, taking off, or not in teleop).
  bool operator_ignored = false;
  control::ControlOutput control;  ///< The attitude-thrust setpoint and its flags.
};

class ModeController {
 public:
  /// Starts in hover.
  ModeController(const ModesConfig& config, const control::VelocityControllerConfig& control,
                 const VehicleConfig& vehicle);

  /// Registers the provider of kMarker or kExplore (not owned; must outlive this object).
  /// @return false for other modes.
  bool register_provider(Mode mode, VelocityProvider* provider);

  /// Requests a mode; refused (with a reason) for marker/explore without a provider, and, from an
  /// operator in flight, within min_mode_dwell_s of the last change or (except to hover) beyond
  /// the rate limit (the reason is valid until the next request). Land -> hover below
  /// land_abort_min_height_m first climbs back to it. Allocates nothing.
  ModeSwitch request_mode(Mode mode, RequestOrigin origin);

  void set_operator_command(const OperatorCommand& command);

  /// Take-off: from the floor (or in the air, a climb) to takeoff_target_height_m at
  /// takeoff_speed_mps, then `then` (request_mode's rules for an operator apply to it; refused
  /// otherwise).
  ModeSwitch request_takeoff(Mode then);
  /// See control::VelocityController::rescale_thrust.
  void rescale_thrust(double ratio) { controller_.rescale_thrust(ratio); }

  /// Height of the body above the floor (m) for the take-off's climb; NaN when unknown, in
  /// which case a take-off climbs on until a height is known again.
  void set_height_m(double height_m) { height_m_ = height_m; }

  /// The body's horizontal offset from the take-off point, in H (m); NaN when unknown, in
  /// which case the horizontal bound is not enforced (nothing to measure it by).
  void set_offset_from_takeoff_H_m(const Eigen::Vector2d& offset_H_m) {
    offset_from_takeoff_H_m_ = offset_H_m;
  }

  /// The accelerometer's specific force in H (NED; at rest (0, 0, -g)) at t_ns, for the land
  /// detector and the blind descent's vertical velocity. Non-finite samples are ignored.
  void set_specific_force_H(std::int64_t t_ns, const Eigen::Vector3d& f_H_mps2);

  /// One control step. v_est and v_obs in H; no v_est (nullopt: no usable estimate) gives the
  /// velocity controller's safe hover, and in land the blind descent. Allocates nothing.
  ModeOutput step(std::int64_t t_ns, const std::optional<Eigen::Vector3d>& v_est_H_mps,
                  const Eigen::Vector3d& v_obs_H_mps);

  [[nodiscard]] Mode mode() const { return mode_; }
  /// On the ground with motors idle (before take-off and after touchdown).
  [[nodiscard]] bool landed() const { return landed_; }
  /// An explicit take-off is climbing.
  [[nodiscard]] bool taking_off() const { return takeoff_active_; }

 private:
  enum class Source { kOperator, kHover, kLand, kProvider, kTakeoff };
  /// What the current mode (or the take-off) asks for, before the ramp: v*_des in H.
  struct Target {
    Source source = Source::kHover;
    Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();
    double yaw_rate_radps = 0.0;
  };
  /// The mode's own command at t_ns; ends the take-off at its height, sets out.teleop_timed_out
  /// and out.provider_failed.
  Target target(std::int64_t t_ns, ModeOutput& out);
  /// Touchdown detection and the blind descent of Mode::kLand.
  void land_step(std::int64_t t_ns, double dt_s, const std::optional<Eigen::Vector3d>& v_est_H_mps,
                 ModeOutput& out);
  /// The blind descent's thrust as a fraction of m g: the IMU's rate loop, or the fixed ratio.
  double blind_descent_thrust_ratio(std::int64_t t_ns, double dt_s, ModeOutput& out);
  /// Limits the target to the envelope: its climb (ceiling; none with the height unknown) and
  /// its motion away from the take-off point.
  void limit_to_envelope(Target& wanted, ModeOutput& out) const;
  void limit_climb(Target& wanted, ModeOutput& out) const;
  void limit_horizontal(Target& wanted, ModeOutput& out) const;
  /// The blind descent's evidence of the floor: an impact, then stillness for touchdown_s.
  [[nodiscard]] bool floor_evidence(double dt_s);
  /// The operator hysteresis for a change to `to`: a refusal with its reason, or accepted (and
  /// the change counted against the rate limit).
  ModeSwitch operator_may_change(Mode to);

  ModesConfig config_;
  control::VelocityController controller_;
  Mode mode_ = Mode::kHover;
  VelocityProvider* marker_ = nullptr;
  VelocityProvider* explore_ = nullptr;
  OperatorCommand operator_command_;
  bool have_operator_command_ = false;
  Source last_source_ = Source::kHover;
  bool ramping_ = false;
  Eigen::Vector3d v_star_mps_ = Eigen::Vector3d::Zero();
  double yaw_rate_radps_ = 0.0;
  bool have_previous_ = false;
  std::int64_t t_prev_ns_ = 0;
  bool landed_ = true;
  double touchdown_timer_s_ = 0.0;
  double blind_descent_timer_s_ = 0.0;
  bool takeoff_active_ = false;
  Mode takeoff_then_ = Mode::kHover;
  double height_m_ = std::numeric_limits<double>::quiet_NaN();
  Eigen::Vector2d offset_from_takeoff_H_m_ =
      Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
  Eigen::Vector3d f_H_mps2_ = Eigen::Vector3d(0.0, 0.0, -control::kGravityMps2);
  bool impact_seen_ = false;  // during this blind descent
  // The IMU's vertical velocity (NED), anchored to each usable estimate; its sample clock; and
  // the blind descent's integral term.
  double v_z_inertial_mps_ = 0.0;
  std::int64_t t_imu_ns_ = -1;
  double blind_descent_integral_mps_ = 0.0;
  double still_timer_s_ = 0.0;
  double climb_target_height_m_ = 0.0;  // of the take-off or the land abort's climb
  bool land_abort_climb_ = false;
  // The step time of the operator's change into the current mode; none when the start or the
  // vehicle chose it.
  std::optional<std::int64_t> mode_entered_ns_;
  double operator_changes_left_ = 0.0;  // token bucket of the rate limit
  std::int64_t changes_refilled_ns_ = 0;
  char refusal_[128] = {};
};

}  // namespace hq::modes
