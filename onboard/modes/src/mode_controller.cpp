#include "hq/modes/mode_controller.hpp"

#include "hq/base/format_into.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/config/strict_yaml.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace hq::modes {

namespace {
constexpr double kTouchdownThrustRatio = 0.9;
/// The blind descent's rate loop on the IMU's vertical velocity: a PI whose bandwidth (about
/// 0.3 Hz) stays well below the attitude loop's and above the accelerometer bias's drift.
constexpr double kBlindDescentGainPerS = 2.0;
constexpr double kBlindDescentIntegralGainPerS2 = 1.0;
/// The IMU counts as present while its last sample is at most this old.
constexpr std::int64_t kImuFreshNs = 200'000'000;
/// The take-off's climb ends this near its target height (the slow final approach covers it).
constexpr double kTakeoffReachedM = 0.02;
}  // namespace

const char* to_string(Mode mode) {
  switch (mode) {
    case Mode::kTeleop:
      return "teleop";
    case Mode::kHover:
      return "hover";
    case Mode::kLand:
      return "land";
    case Mode::kMarker:
      return "marker";
    case Mode::kExplore:
      return "explore";
  }
  return "unknown";
}

const char* to_string(FlightState state) {
  switch (state) {
    case FlightState::kLanded:
      return "landed";
    case FlightState::kTakingOff:
      return "taking off";
    case FlightState::kAirborne:
      return "airborne";
    case FlightState::kLanding:
      return "landing";
  }
  return "unknown";
}

void read_config(config::StrictMap& section, ModesConfig& out) {
  section.read_positive("teleop_timeout_s", out.teleop_timeout_s, 10.0);
  section.read_positive("land_speed_mps", out.land_speed_mps, 2.0);
  section.read_positive("max_switch_accel_mps2", out.max_switch_accel_mps2, 100.0);
  section.read_positive("max_switch_yaw_accel_radps2", out.max_switch_yaw_accel_radps2, 100.0);
  section.read("start_landed", out.start_landed);
  section.read_positive("takeoff_climb_mps", out.takeoff_climb_mps, 5.0);
  section.read_positive("touchdown_speed_mps", out.touchdown_speed_mps, 1.0);
  section.read_positive("touchdown_s", out.touchdown_s, 10.0);
  section.read("blind_descent_thrust_ratio", out.blind_descent_thrust_ratio, 0.5, 1.0);
  section.read_positive("blind_descent_speed_mps", out.blind_descent_speed_mps, 2.0);
  section.read_positive("blind_descent_s", out.blind_descent_s, 30.0);
  section.read_positive("touchdown_max_height_m", out.touchdown_max_height_m, 5.0);
  section.read("impact_specific_force_mps2", out.impact_specific_force_mps2, 10.0, 100.0);
  section.read_positive("still_specific_force_mps2", out.still_specific_force_mps2, 5.0);
  section.read_positive("max_height_m", out.max_height_m, 100.0);
  section.read_positive("ceiling_slowdown_m", out.ceiling_slowdown_m, 10.0);
  section.read_positive("max_distance_from_takeoff_m", out.max_distance_from_takeoff_m, 1000.0);
  section.read_positive("horizontal_slowdown_m", out.horizontal_slowdown_m, 100.0);
  section.read_positive("takeoff_target_height_m", out.takeoff_target_height_m, 10.0);
  section.read_positive("takeoff_speed_mps", out.takeoff_speed_mps, 2.0);
  section.read_positive("takeoff_slowdown_m", out.takeoff_slowdown_m, 5.0);
  section.read("min_mode_dwell_s", out.min_mode_dwell_s, 0.0, 10.0);
  section.read_positive("operator_mode_changes_per_min", out.operator_mode_changes_per_min, 600.0);
  section.read("operator_mode_change_burst", out.operator_mode_change_burst, 1, 100);
  section.read_positive("land_abort_min_height_m", out.land_abort_min_height_m, 10.0);
  section.finish();
}

ModeController::ModeController(const ModesConfig& config,
                               const control::VelocityControllerConfig& control,
                               const VehicleConfig& vehicle)
    : config_(config),
      controller_(control, vehicle),
      landed_(config.start_landed),
      climb_target_height_m_(config.takeoff_target_height_m),
      operator_changes_left_(static_cast<double>(config.operator_mode_change_burst)) {}

bool ModeController::register_provider(Mode mode, VelocityProvider* provider) {
  if (mode == Mode::kMarker) {
    marker_ = provider;
    return true;
  }
  if (mode == Mode::kExplore) {
    explore_ = provider;
    return true;
  }
  return false;
}

ModeSwitch ModeController::request_mode(Mode mode, RequestOrigin origin) {
  if (mode == Mode::kMarker && marker_ == nullptr) {
    // The operator reads this in the console: what is off and where to turn it on.
    return {false, "marker mode is off on this vehicle (markers.enabled: false in its config)"};
  }
  if (mode == Mode::kExplore && explore_ == nullptr) {
    return {false, "explore mode is off on this vehicle (markers.enabled: false in its config)"};
  }
  if (mode == mode_) return {true, ""};  // nothing changes: no dwell, no rate, the climb goes on
  if (origin == RequestOrigin::kOperator) {
    const ModeSwitch verdict = operator_may_change(mode);
    if (!verdict.accepted) return verdict;
  }
  // A change of mode ends a take-off's climb where it is ...
  takeoff_active_ = false;
  land_abort_climb_ = false;
  // ... except land -> hover low down, which climbs back to land_abort_min_height_m first. PX4
  // either finishes the landing or, aborting it, climbs to a safe altitude (MIS_LND_ABRT_ALT).
  // We climb: the operator asked to hover, so finishing the landing would refuse them, and a
  // hover held where the descent stopped keeps every land -> hover -> land cycle's descent, the
  // ratchet that sank the vehicle in issue 39, low in the ground effect and the clutter. After
  // the climb no toggling sinks it below this height less one dwell's descent.
  const bool low = std::isfinite(height_m_) && height_m_ < config_.land_abort_min_height_m;
  if (mode_ == Mode::kLand && mode == Mode::kHover && !landed_ && low) {
    takeoff_active_ = true;
    land_abort_climb_ = true;
    climb_target_height_m_ = config_.land_abort_min_height_m;
  }
  mode_ = mode;
  // The dwell holds an operator to their own choice. A mode the vehicle chose (a failsafe, the
  // marker hand-over) the operator may answer at once, e.g. asking to fly again after the FC
  // disarmed, or to hover out of a marker landing.
  if (origin == RequestOrigin::kOperator) {
    mode_entered_ns_ = have_previous_ ? t_prev_ns_ : 0;
  } else {
    mode_entered_ns_.reset();
  }
  ramping_ = true;
  return {true, ""};
}

ModeSwitch ModeController::operator_may_change(Mode to) {
  // On the floor with the motors idle a change moves nothing; before the first step there is
  // no time to measure a dwell by.
  if (landed_ || !have_previous_) return {true, ""};
  const double in_mode_s = mode_entered_ns_ ? hq::to_seconds(t_prev_ns_ - *mode_entered_ns_) : 0.0;
  if (mode_entered_ns_ && in_mode_s < config_.min_mode_dwell_s) {
    hq::format_into(refusal_,
                    "mode change refused: minimum dwell in {} {:.1f} s, {:.1f} s so far "
                    "(modes.min_mode_dwell_s)",
                    to_string(mode_), config_.min_mode_dwell_s, in_mode_s);
    return {false, refusal_};
  }
  // Hover, the safe state, is held to the dwell only: were the rate limit to refuse it, an
  // operator could not leave land (and its descent) or a mode flying somewhere unwanted.
  if (to == Mode::kHover) return {true, ""};
  // Token bucket: operator_mode_change_burst changes at once, refilled at the sustained rate.
  const double since_refill_s = hq::to_seconds(t_prev_ns_ - changes_refilled_ns_);
  operator_changes_left_ =
      std::min(static_cast<double>(config_.operator_mode_change_burst),
               operator_changes_left_ +
                   std::max(0.0, since_refill_s) * config_.operator_mode_changes_per_min / 60.0);
  changes_refilled_ns_ = t_prev_ns_;
  if (operator_changes_left_ < 1.0) {
    hq::format_into(refusal_,
                    "mode change refused: operator mode changes limited to {} at once and {:.0f} "
                    "per minute (modes.operator_mode_changes_per_min)",
                    config_.operator_mode_change_burst, config_.operator_mode_changes_per_min);
    return {false, refusal_};
  }
  operator_changes_left_ -= 1.0;
  return {true, ""};
}

ModeSwitch ModeController::request_takeoff(Mode then) {
  if (then == Mode::kLand) return {false, "take-off refused: the mode after it is land"};
  const ModeSwitch verdict = request_mode(then, RequestOrigin::kOperator);
  if (!verdict.accepted) return verdict;
  takeoff_active_ = true;
  land_abort_climb_ = false;
  climb_target_height_m_ = config_.takeoff_target_height_m;
  takeoff_then_ = then;
  ramping_ = true;
  return verdict;
}

void ModeController::set_specific_force_H(std::int64_t t_ns, const Eigen::Vector3d& f_H_mps2) {
  if (!f_H_mps2.allFinite()) return;
  if (t_imu_ns_ >= 0 && t_ns > t_imu_ns_) {
    // NED: the acceleration is f + g e_z; its bias drifts this by ~0.05 m/s per second of
    // blind flight for a consumer MEMS part, which the estimate re-anchors when it returns.
    const double dt_s = std::min(hq::to_seconds(t_ns - t_imu_ns_), 0.1);
    v_z_inertial_mps_ += (f_H_mps2.z() + control::kGravityMps2) * dt_s;
  }
  t_imu_ns_ = t_ns;
  f_H_mps2_ = f_H_mps2;
  if (f_H_mps2.norm() > config_.impact_specific_force_mps2) impact_seen_ = true;
}

void ModeController::limit_to_envelope(Target& wanted, ModeOutput& out) const {
  out.envelope_max_climb_mps = -wanted.v_H_mps.z();
  if (landed_) return;
  limit_horizontal(wanted, out);
  limit_climb(wanted, out);
}

void ModeController::limit_horizontal(Target& wanted, ModeOutput& out) const {
  const double distance_m = offset_from_takeoff_H_m_.norm();
  const double free_within_m = config_.max_distance_from_takeoff_m - config_.horizontal_slowdown_m;
  if (!std::isfinite(distance_m) || distance_m <= free_within_m || distance_m <= 0.0) return;
  const Eigen::Vector2d away = offset_from_takeoff_H_m_ / distance_m;
  const Eigen::Vector2d v_xy = wanted.v_H_mps.head<2>();
  const double outward_mps = v_xy.dot(away);
  if (outward_mps <= 0.0) return;
  // The outward speed allowed falls linearly to zero at the bound, as the ceiling's climb.
  const double left_m = config_.max_distance_from_takeoff_m - distance_m;
  const double max_outward_mps =
      outward_mps * std::clamp(left_m / config_.horizontal_slowdown_m, 0.0, 1.0);
  const Eigen::Vector2d limited = v_xy - (outward_mps - max_outward_mps) * away;
  wanted.v_H_mps.head<2>() = limited;
  out.envelope_limited = true;
  out.envelope_horizontal_limited = true;
  out.envelope_v_xy_H_mps = limited;
  out.envelope_reason = "horizontal bound (modes.max_distance_from_takeoff_m)";
}

void ModeController::limit_climb(Target& wanted, ModeOutput& out) const {
  const double climb_mps = -wanted.v_H_mps.z();  // NED
  if (climb_mps <= 0.0) return;
  double max_climb_mps = climb_mps;
  const char* reason = "";
  if (!std::isfinite(height_m_)) {
    // The take-off climbs on until the floor (or the integrated climb) gives a height.
    if (wanted.source == Source::kTakeoff) return;
    max_climb_mps = 0.0;
    reason = "height unknown: no climb";
  } else {
    const double to_ceiling_m = config_.max_height_m - height_m_;
    max_climb_mps =
        std::max(0.0, climb_mps * std::min(1.0, to_ceiling_m / config_.ceiling_slowdown_m));
    reason = "ceiling (modes.max_height_m)";
  }
  if (max_climb_mps >= climb_mps) return;
  out.envelope_reason = reason;
  wanted.v_H_mps.z() = -max_climb_mps;
  out.envelope_limited = true;
  out.envelope_max_climb_mps = max_climb_mps;
}

void ModeController::set_operator_command(const OperatorCommand& command) {
  if (!command.v_H_mps.allFinite() || !std::isfinite(command.yaw_rate_radps)) return;
  operator_command_ = command;
  have_operator_command_ = true;
}

// The mode's own command (v*_des before the ramp).
ModeController::Target ModeController::target(std::int64_t t_ns, ModeOutput& out) {
  Target wanted;
  if (takeoff_active_ && std::isfinite(height_m_) &&
      height_m_ >= climb_target_height_m_ - kTakeoffReachedM) {
    // At the take-off height: the requested mode takes over (ramping from the slow final climb).
    takeoff_active_ = false;
    land_abort_climb_ = false;
  }
  switch (takeoff_active_ ? Mode::kHover : mode_) {
    case Mode::kTeleop: {
      const double age_s = hq::to_seconds(t_ns - operator_command_.t_ns);
      if (have_operator_command_ && age_s <= config_.teleop_timeout_s) {
        wanted.source = Source::kOperator;
        wanted.v_H_mps = operator_command_.v_H_mps;
        wanted.yaw_rate_radps = operator_command_.yaw_rate_radps;
      } else {
        out.teleop_timed_out = true;
      }
      break;
    }
    case Mode::kHover:
      if (takeoff_active_) {
        // Climb at takeoff_speed_mps, proportionally slower over the last takeoff_slowdown_m
        // (a first-order approach, so no overshoot); without a height, climb slowly on.
        const double to_go_m = std::isfinite(height_m_) ? climb_target_height_m_ - height_m_
                                                        : config_.takeoff_slowdown_m;
        const double climb_mps =
            std::clamp(config_.takeoff_speed_mps * to_go_m / config_.takeoff_slowdown_m,
                       std::min(2.0 * config_.takeoff_climb_mps, config_.takeoff_speed_mps),
                       config_.takeoff_speed_mps);
        wanted.source = Source::kTakeoff;
        wanted.v_H_mps = Eigen::Vector3d(0.0, 0.0, -climb_mps);
      }
      break;
    case Mode::kLand:
      wanted.source = Source::kLand;
      wanted.v_H_mps = Eigen::Vector3d(0.0, 0.0, config_.land_speed_mps);
      break;
    case Mode::kMarker:
    case Mode::kExplore: {
      VelocityProvider* provider = (mode_ == Mode::kMarker) ? marker_ : explore_;
      const ModeCommand command = provider->desired(t_ns);
      if (command.valid && command.v_H_mps.allFinite() && std::isfinite(command.yaw_rate_radps)) {
        wanted.source = Source::kProvider;
        wanted.v_H_mps = command.v_H_mps;
        wanted.yaw_rate_radps = command.yaw_rate_radps;
      } else {
        out.provider_failed = true;
      }
      break;
    }
  }
  return wanted;
}

ModeOutput ModeController::step(std::int64_t t_ns,
                                const std::optional<Eigen::Vector3d>& v_est_H_mps,
                                const Eigen::Vector3d& v_obs_H_mps) {
  ModeOutput out;
  out.mode = mode_;
  if (v_est_H_mps && std::isfinite(v_est_H_mps->z())) v_z_inertial_mps_ = v_est_H_mps->z();

  Target wanted = target(t_ns, out);
  limit_to_envelope(wanted, out);
  const Source source = wanted.source;
  const Eigen::Vector3d& v_target = wanted.v_H_mps;
  const double yaw_target = wanted.yaw_rate_radps;
  // A change of source inside a mode (teleop timing out, a provider failing) ramps too.
  if (source != last_source_) ramping_ = true;
  last_source_ = source;

  out.taking_off = takeoff_active_;
  out.land_abort_climb = land_abort_climb_;
  out.operator_ignored = takeoff_active_ || mode_ != Mode::kTeleop || landed_;
  if (landed_) {
    // On the ground only a climb request starts the motors; until then the PID is held reset
    // so no integral winds up against the floor.
    if (v_target.z() < -config_.takeoff_climb_mps) {
      landed_ = false;
      ramping_ = true;
      touchdown_timer_s_ = 0.0;
      blind_descent_timer_s_ = 0.0;
      controller_.reset();
    } else {
      v_star_mps_.setZero();
      yaw_rate_radps_ = 0.0;
      ramping_ = false;
      controller_.reset();
      have_previous_ = true;
      t_prev_ns_ = t_ns;
      out.landed = true;
      out.flight_state = FlightState::kLanded;
      out.control.setpoint = control::AttitudeSetpoint{};
      return out;
    }
  }
  const double dt_s = have_previous_ ? std::max(0.0, hq::to_seconds(t_ns - t_prev_ns_)) : 0.0;
  have_previous_ = true;
  t_prev_ns_ = t_ns;
  if (ramping_) {
    // Rate-limited from the value at the switch: |dv*| <= a_max dt per step.
    const Eigen::Vector3d dv = v_target - v_star_mps_;
    const double max_dv = config_.max_switch_accel_mps2 * dt_s;
    v_star_mps_ += (dv.norm() > max_dv) ? Eigen::Vector3d(dv * (max_dv / dv.norm())) : dv;
    const double max_dyaw = config_.max_switch_yaw_accel_radps2 * dt_s;
    yaw_rate_radps_ += std::clamp(yaw_target - yaw_rate_radps_, -max_dyaw, max_dyaw);
    ramping_ = !(v_star_mps_ == v_target && yaw_rate_radps_ == yaw_target);
  } else {
    v_star_mps_ = v_target;
    yaw_rate_radps_ = yaw_target;
  }
  out.ramping = ramping_;
  out.v_star_des_H_mps = v_star_mps_;
  out.yaw_rate_des_radps = yaw_rate_radps_;
  // Core paper §3.1: the obstacle term is added in every mode.
  const Eigen::Vector3d v_obs = v_obs_H_mps.allFinite() ? v_obs_H_mps : Eigen::Vector3d::Zero();
  out.v_des_H_mps = v_star_mps_ + v_obs;
  out.control = controller_.update(t_ns, out.v_des_H_mps, yaw_rate_radps_, v_est_H_mps);
  if (mode_ == Mode::kLand) land_step(t_ns, dt_s, v_est_H_mps, out);
  out.flight_state = out.landed             ? FlightState::kLanded
                     : mode_ == Mode::kLand ? FlightState::kLanding
                     : takeoff_active_      ? FlightState::kTakingOff
                                            : FlightState::kAirborne;
  return out;
}

bool ModeController::floor_evidence(double dt_s) {
  // Still on the floor: the floor and the thrust together carry exactly m g, so the specific
  // force is g, while the thrust alone (blind_descent_thrust_ratio m g) would give less.
  const bool still =
      std::abs(f_H_mps2_.norm() - control::kGravityMps2) < config_.still_specific_force_mps2;
  still_timer_s_ = impact_seen_ && still ? still_timer_s_ + dt_s : 0.0;
  return still_timer_s_ >= config_.touchdown_s;
}

double ModeController::blind_descent_thrust_ratio(std::int64_t t_ns, double dt_s, ModeOutput& out) {
  const bool imu_fresh = t_imu_ns_ >= 0 && t_ns - t_imu_ns_ <= kImuFreshNs;
  if (!imu_fresh) return config_.blind_descent_thrust_ratio;
  // NED: sinking slower than wanted (v_z below the target) asks for less thrust.
  const double error_mps = config_.blind_descent_speed_mps - v_z_inertial_mps_;
  const double low = config_.blind_descent_thrust_ratio;
  const double high = 2.0 - config_.blind_descent_thrust_ratio;
  const double unclamped = 1.0 - (kBlindDescentGainPerS * error_mps +
                                  kBlindDescentIntegralGainPerS2 * blind_descent_integral_mps_) /
                                     control::kGravityMps2;
  // Anti-windup: the integral moves only while the thrust is not at a bound it pushes on.
  const bool pushing_low = unclamped <= low && error_mps > 0.0;
  const bool pushing_high = unclamped >= high && error_mps < 0.0;
  if (!pushing_low && !pushing_high) blind_descent_integral_mps_ += error_mps * dt_s;
  out.blind_descent_rate_held = true;
  out.blind_descent_v_z_mps = v_z_inertial_mps_;
  return std::clamp(unclamped, low, high);
}

void ModeController::land_step(std::int64_t t_ns, double dt_s,
                               const std::optional<Eigen::Vector3d>& v_est_H_mps, ModeOutput& out) {
  if (!v_est_H_mps || !v_est_H_mps->allFinite()) {
    // No velocity estimate to close the loop on: sink level, on the IMU's vertical velocity if
    // there is one, else at a fixed fraction of hover thrust; the floor ends it.
    if (blind_descent_timer_s_ == 0.0) {  // a new blind descent: only impacts from now count
      impact_seen_ = false;
      still_timer_s_ = 0.0;
      blind_descent_integral_mps_ = 0.0;
    }
    out.blind_descent = true;
    out.control.setpoint = controller_.hover_setpoint();
    out.control.setpoint.thrust_n *= blind_descent_thrust_ratio(t_ns, dt_s, out);
    blind_descent_timer_s_ += dt_s;
    // The loss of the estimate is no evidence of the floor: a vehicle high up that idled its
    // motors here would fall (issue 39: from 11.8 m at 11-13 m/s).
    const bool near_floor = std::isfinite(height_m_) && height_m_ <= config_.touchdown_max_height_m;
    const bool evidence = floor_evidence(dt_s) || near_floor;
    if (blind_descent_timer_s_ >= config_.blind_descent_s && evidence) landed_ = true;
  } else {
    blind_descent_timer_s_ = 0.0;
    impact_seen_ = false;
    still_timer_s_ = 0.0;
    // Held by the floor: not sinking although the PID, its integral winding against the floor,
    // asks for well under hover thrust (a hover in mid-air keeps it near m g).
    const bool held_by_floor = v_est_H_mps->z() < config_.touchdown_speed_mps &&
                               out.control.setpoint.thrust_n <
                                   kTouchdownThrustRatio * controller_.hover_setpoint().thrust_n;
    const bool height_says_floor =
        !std::isfinite(height_m_) || height_m_ <= config_.touchdown_max_height_m;
    touchdown_timer_s_ = held_by_floor && height_says_floor ? touchdown_timer_s_ + dt_s : 0.0;
    if (touchdown_timer_s_ >= config_.touchdown_s) landed_ = true;
  }
  if (landed_) {
    controller_.reset();
    out.landed = true;
    out.control.setpoint = control::AttitudeSetpoint{};
  }
}

}  // namespace hq::modes
