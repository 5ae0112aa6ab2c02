#include "hq/pipeline/onboard_chain.hpp"

#include "hq/base/monotonic_clock.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/estimator/complementary_filter.hpp"
#include "hq/geometry/lie.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>

namespace hq::pipeline {

void read_config(config::StrictMap& section, ChainConfig& out) {
  section.read_positive("camera_timeout_s", out.camera_timeout_s, 10.0);
  section.read("takeoff_height_m", out.takeoff_height_m, 0.0, 10.0);
  section.read("gyro_rotation_prior", out.gyro_rotation_prior);
  section.read_positive("gyro_prior_sigma_radps", out.gyro_prior_sigma_radps, 10.0);
  section.read("depth_colour_max_offset_s", out.depth_colour_max_offset_s, 0.0, 1.0);
  section.read("landed_height_m", out.landed_height_m, 0.0, 2.0);
  section.read_positive("safe_hover_land_s", out.safe_hover_land_s, 600.0);
  section.read("hold_on_inertial_coast", out.hold_on_inertial_coast);
  section.read("odom_yaw_drift_radps", out.odom.yaw_drift_radps, 0.0, 1.0);
  section.read("odom_velocity_error_fraction", out.odom.velocity_error_fraction, 0.0, 1.0);
  section.read("odom_velocity_error_correlation_s", out.odom.velocity_error_correlation_s, 0.0,
               60.0);
  section.read("odom_blind_drift_mps", out.odom.blind_drift_mps, 0.0, 10.0);
  section.finish();
}

const char* to_string(HeightSource source) {
  switch (source) {
    case HeightSource::kNone:
      return "none";
    case HeightSource::kDepth:
      return "depth";
    case HeightSource::kEstimate:
      return "estimate";
  }
  return "unknown";
}

OnboardConfig load_onboard_config(const std::string& path) {
  const YAML::Node node = config::load_yaml_file(path);
  config::StrictMap root(node, path);
  OnboardConfig out;
  config::StrictMap odometry = root.child("odometry");
  odometry::read_config(odometry, out.odometry);
  config::StrictMap estimator = root.child("estimator");
  estimator::read_config(estimator, out.estimator);
  config::StrictMap obstacles = root.child("obstacles");
  obstacles::read_config(obstacles, out.obstacles);
  config::StrictMap memory = root.child("memory");
  obstacle_memory::read_config(memory, out.memory);
  config::StrictMap seen_space = root.child("seen_space");
  seen_space::read_config(seen_space, out.seen_space);
  config::StrictMap control = root.child("control");
  control::read_config(control, out.control);
  config::StrictMap hover_thrust = root.child("hover_thrust");
  control::read_config(hover_thrust, out.hover_thrust);
  config::StrictMap modes = root.child("modes");
  modes::read_config(modes, out.modes);
  config::StrictMap chain = root.child("chain");
  read_config(chain, out.chain);
  config::StrictMap markers = root.child("markers");
  marker_modes::read_config(markers, out.markers);
  root.finish();
  return out;
}

std::int64_t stage_ns(const StageDurations& durations, int i) {
  switch (i) {
    case 0:
      return durations.odometry_ns;
    case 1:
      return durations.estimator_ns;
    case 2:
      return durations.memory_ns;
    case 3:
      return durations.obstacles_ns;
    case 4:
      return durations.control_ns;
    default:
      return durations.total_ns;
  }
}

OnboardChain::OnboardChain(const OnboardConfig& config, const VehicleConfig& vehicle,
                           const geometry::PinholeCamera& camera, const Clock* clock)
    : config_(config),
      clock_(clock),
      odometry_(config.odometry, camera),
      estimator_(config.estimator, vehicle.camera.R_B_C(), vehicle.camera.p_B_C_m()),
      memory_(config.memory, camera, vehicle.camera.R_B_C(), vehicle.camera.p_B_C_m()),
      obstacles_(config.obstacles, camera, vehicle.camera.R_B_C(), vehicle.camera.p_B_C_m()),
      seen_space_(config.seen_space, camera, vehicle.camera.R_B_C(), vehicle.camera.p_B_C_m(),
                  config.obstacles.vehicle_radius_m),
      modes_(config.modes, config.control, vehicle),
      hover_thrust_(config.hover_thrust, vehicle.mass_kg),
      R_B_C_(vehicle.camera.R_B_C()) {
  // A chain started in the air (config.modes.start_landed false) is past its take-off.
  takeoff_complete_ = !config.modes.start_landed;
  odom_pose_ = OdomPose(config.chain.odom);
  if (config.markers.enabled) {
    markers_ = std::make_unique<marker_modes::MarkerStage>(
        config.markers, camera, vehicle.camera.R_B_C(), vehicle.camera.p_B_C_m());
    modes_.register_provider(modes::Mode::kMarker, &markers_->marker_mode());
    modes_.register_provider(modes::Mode::kExplore, &markers_->explore());
  }
}

void OnboardChain::on_imu(std::int64_t t_ns, const Eigen::Vector3d& gyro_radps,
                          const Eigen::Vector3d& accel_mps2) {
  estimator_.update_imu(t_ns, gyro_radps, accel_mps2);
  hover_thrust_.on_specific_force(t_ns, accel_mps2.z(), thrust_measurable_);
  // The land detector's evidence of the floor (an impact, then the floor carrying the vehicle).
  const Eigen::Matrix3d R_H_B = R_H_B_from_tilt();
  modes_.set_specific_force_H(t_ns, R_H_B * accel_mps2);
  // The heading's turn since take-off, for the dead reckoning of the take-off point.
  if (t_yaw_ns_ >= 0 && t_ns > t_yaw_ns_) {
    const double dt_s = std::min(hq::to_seconds(t_ns - t_yaw_ns_), 0.1);
    const Eigen::Vector3d omega_H =
        R_H_B * (gyro_radps - estimator_.attitude().levelling_gyro_bias_radps());
    if (omega_H.allFinite()) yaw_since_takeoff_rad_ += omega_H.z() * dt_s;
  }
  t_yaw_ns_ = t_ns;
  // The whole bias, yaw's too (the odometry measures it): the odom yaw drifts with what is left.
  const Eigen::Vector3d omega_odom_H =
      R_H_B * (gyro_radps - estimator_.attitude().gyro_bias_radps());
  odom_pose_.on_yaw_rate(t_ns, omega_odom_H.z());
  if (config_.chain.gyro_rotation_prior) {
    // The body's rotation since the last frame, bias removed: R_Bprev_Bcur.
    if (t_last_imu_ns_ >= 0 && t_ns > t_last_imu_ns_) {
      const double dt_s = std::min(hq::to_seconds(t_ns - t_last_imu_ns_), 0.1);
      // Less the levelling's bias only: the rest is what the odometry itself estimates.
      const Eigen::Vector3d omega = gyro_radps - estimator_.attitude().levelling_gyro_bias_radps();
      R_prev_cur_B_ = R_prev_cur_B_ * geometry::exp_so3(omega * dt_s);
      gyro_since_frame_ = true;
      if (omega.allFinite()) omega_B_radps_ = omega;
    }
    t_last_imu_ns_ = t_ns;
  }
  if (markers_) markers_->on_imu(t_ns, gyro_radps, accel_mps2);
}

Eigen::Matrix3d OnboardChain::R_H_B_from_tilt() const {
  const estimator::ComplementaryFilter& attitude = estimator_.attitude();
  if (!attitude.initialized()) return Eigen::Matrix3d::Identity();
  return estimator::R_H_B_from_tilt(attitude.roll_rad(), attitude.pitch_rad());
}

odometry::OdometryResult OnboardChain::track_odometry(std::int64_t t_ns, std::int64_t depth_t_ns,
                                                      const cv::Mat& gray, const cv::Mat& depth_m) {
  odometry::RotationPrior gyro;
  gyro.information.setZero();  // no prior unless the gyro ran since the last frame
  // The depth's exposure to the colour's, at the latest rate (a few milliseconds).
  const double depth_lead_s = hq::to_seconds(t_ns - depth_t_ns);
  const bool align_depth = config_.chain.gyro_rotation_prior && t_last_imu_ns_ >= 0 &&
                           std::abs(depth_lead_s) <= config_.chain.depth_colour_max_offset_s;
  if (align_depth) {
    gyro.R_depth_colour =
        R_B_C_.transpose() * geometry::exp_so3(omega_B_radps_ * depth_lead_s) * R_B_C_;
  }
  const bool use_gyro = config_.chain.gyro_rotation_prior && gyro_since_frame_ && have_frame_;
  if (use_gyro) {
    // R_Cprev_Ccur = R_C_B R_Bprev_Bcur R_B_C.
    gyro.R_prev_cur = R_B_C_.transpose() * R_prev_cur_B_ * R_B_C_;
    const auto interval_ns = std::max<std::int64_t>(t_ns - t_last_frame_ns_, 1);
    const double sigma_rad = config_.chain.gyro_prior_sigma_radps * hq::to_seconds(interval_ns);
    gyro.information = Eigen::Matrix3d::Identity() / (sigma_rad * sigma_rad);
  }
  R_prev_cur_B_.setIdentity();
  gyro_since_frame_ = false;
  return odometry_.track(t_ns, gray, depth_m, use_gyro || align_depth ? &gyro : nullptr);
}

void OnboardChain::estimate_velocity(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m,
                                     const odometry::OdometryResult& odometry, ChainOutput& out) {
  // Fig. 4: odometry poses and IMU into v_H (eqs. 1-5).
  // Landed with motors idle the vehicle is at rest: a zero-velocity update, so that the take-off
  // can climb on the IMU until the floor is far enough for the depth camera.
  if (modes_.landed()) estimator_.hold_at_rest(t_ns);
  out.estimate = estimator_.update(t_ns, odometry);
  // Markers, map and the error-state filter (timed with the estimator). Low over the
  // target, the marker and explore modes hand the touchdown to Mode::kLand.
  if (markers_) {
    markers_->on_frame(t_ns, gray, depth_m, out.estimate, odometry.ok(), odometry.T_O_C);
    if (markers_->wants_land(modes_.mode())) {
      modes_.request_mode(modes::Mode::kLand, modes::RequestOrigin::kVehicle);
    }
  }
}

void OnboardChain::update_memory(std::int64_t t_ns, const cv::Mat& depth_m,
                                 const odometry::OdometryResult& odometry,
                                 const Eigen::Matrix3d& R_H_B, ChainOutput& out) {
  // The memory places this depth at the odometry pose and returns what it remembers
  // outside the view; without tracking there is no pose to place or recall it with.
  if (!config_.memory.enabled) {
    out.memory.reason = "memory disabled";
  } else if (!odometry.ok()) {
    out.memory.reason = "odometry not tracking";
    out.memory.map_size = memory_.size();
    out.memory.clear_count = memory_.clear_count();
  } else {
    // The field's d0 is a clearance (|p| minus the vehicle radius): recall out to its reach.
    out.memory =
        memory_.update(t_ns, depth_m, odometry.T_O_C, R_H_B,
                       config_.obstacles.influence_distance_m + config_.obstacles.vehicle_radius_m);
  }
}

void OnboardChain::sense_obstacles(std::int64_t t_ns, const cv::Mat& depth_m,
                                   const odometry::OdometryResult& odometry,
                                   const Eigen::Matrix3d& R_H_B, ChainOutput& out) {
  // §3.1: depth minima into the repulsive v_obs in H, with the attitude the estimator holds,
  // plus the remembered points outside the view under the same law.
  // The take-off ends once, at takeoff_height_m of climb; descending later does not restart it.
  if (modes_.landed()) {
    climb_since_takeoff_m_ = 0.0;
    takeoff_complete_ = false;
  } else if (!takeoff_complete_ && out.estimate.usable() && have_frame_) {
    climb_since_takeoff_m_ -= out.estimate.v_H_mps.z() * hq::to_seconds(t_ns - t_last_frame_ns_);
    takeoff_complete_ = climb_since_takeoff_m_ >= config_.chain.takeoff_height_m;
  }
  obstacles_.set_ground_phase(modes_.landed() || modes_.mode() == modes::Mode::kLand ||
                              !takeoff_complete_);
  out.obstacles = obstacles_.compute(depth_m, R_H_B, out.memory.remembered());
  update_height(t_ns, out.obstacles.floor_height_m, out);
  update_offset_from_takeoff(t_ns, out);
  // What this frame and the memory have seen limits the operator's command.
  v_est_for_limit_H_mps_ = usable_v_H_mps(out.estimate);
  velocity_from_odometry_ = out.estimate.ok();
  out.seen_space =
      seen_space_.update(t_ns, depth_m, odometry.ok() ? &odometry.T_O_C : nullptr, R_H_B);
  if (out.seen_space.updated && config_.memory.enabled && odometry.ok()) {
    memory_.for_each_point([this](const Eigen::Vector3f& p_O_m, std::int64_t t_seen_ns) {
      seen_space_.add_remembered_point(p_O_m, t_seen_ns);
    });
  }
  apply_operator_limit(&out);
}

std::optional<Eigen::Vector3d> OnboardChain::usable_v_H_mps(
    const estimator::VelocityEstimate& estimate) {
  if (!estimate.usable()) return std::nullopt;
  return estimate.v_H_mps;
}

ChainOutput OnboardChain::on_frame(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m) {
  return on_frame(t_ns, t_ns, gray, depth_m);
}

ChainOutput OnboardChain::on_frame(std::int64_t t_ns, std::int64_t depth_t_ns, const cv::Mat& gray,
                                   const cv::Mat& depth_m) {
  ChainOutput out;
  out.t_ns = t_ns;
  out.frame = true;
  const std::int64_t t_arrival_ns = now_ns();

  const odometry::OdometryResult odometry = track_odometry(t_ns, depth_t_ns, gray, depth_m);
  out.tracking = odometry.status;
  out.tracking_reason = odometry.reason;
  out.valid_ratio = odometry.valid_ratio;
  const std::int64_t t_odometry_ns = now_ns();

  estimate_velocity(t_ns, gray, depth_m, odometry, out);
  const std::int64_t t_estimator_ns = now_ns();

  const Eigen::Matrix3d R_H_B = R_H_B_from_tilt();
  update_memory(t_ns, depth_m, odometry, R_H_B, out);
  const std::int64_t t_memory_ns = now_ns();

  sense_obstacles(t_ns, depth_m, odometry, R_H_B, out);
  out.clearance_m = clearance_filter_.update(out.obstacles.min_clearance_m);
  const std::int64_t t_obstacles_ns = now_ns();

  // Without an estimate the PID gets none (nullopt): the velocity controller's safe-hover path
  // then commands a level hover (m g) and freezes its integral, which is what the vehicle can
  // do on IMU attitude alone.
  follow_hover_thrust();
  out.mode = modes_.step(t_ns, usable_v_H_mps(out.estimate), out.obstacles.v_obs_H_mps);
  finish_output(out);
  correct_thrust(out);
  const std::int64_t t_control_ns = now_ns();

  out.safe_hover = out.mode.control.safe_hover && !out.mode.landed && !out.mode.blind_descent;
  out.degraded = !out.estimate.ok();
  if (out.safe_hover) {
    out.safe_hover_reason = out.estimate.usable() ? out.mode.control.reason : out.estimate.reason;
  }
  escalate_safe_hover(out);
  have_frame_ = true;
  t_last_frame_ns_ = t_ns;

  out.durations.odometry_ns = t_odometry_ns - t_arrival_ns;
  out.durations.estimator_ns = t_estimator_ns - t_odometry_ns;
  out.durations.memory_ns = t_memory_ns - t_estimator_ns;
  out.durations.obstacles_ns = t_obstacles_ns - t_memory_ns;
  out.durations.control_ns = t_control_ns - t_obstacles_ns;
  out.durations.total_ns = t_control_ns - t_arrival_ns;
  return out;
}

std::optional<ChainOutput> OnboardChain::on_tick(std::int64_t t_ns) {
  if (!have_tick_) {
    have_tick_ = true;
    t_first_tick_ns_ = t_ns;
  }
  const std::int64_t since_ns = have_frame_ ? t_last_frame_ns_ : t_first_tick_ns_;
  const double silence_s = hq::to_seconds(t_ns - since_ns);
  if (!(silence_s > config_.chain.camera_timeout_s)) return std::nullopt;

  ChainOutput out;
  out.t_ns = t_ns;
  out.frame = false;
  out.tracking_reason = "no frame";
  out.camera_timed_out = true;
  if (modes_.landed()) estimator_.hold_at_rest(t_ns);
  // The inertial coast keeps the velocity loop closed for a bounded time; after it, the safe
  // hover (level, m g) is all the IMU can hold.
  out.estimate = estimator_.between_frames(t_ns, "camera timed out");
  out.estimate.unavailable_for_s = std::max(out.estimate.unavailable_for_s, silence_s);
  out.obstacles.reason = "no frame";
  // No new depth: the clearance stands at the last frames' (as the console's cloud does).
  out.clearance_m = clearance_filter_.clearance_m();
  // No frame: the seen space only ages (no pose to turn it with).
  v_est_for_limit_H_mps_ = usable_v_H_mps(out.estimate);
  velocity_from_odometry_ = out.estimate.ok();
  out.seen_space = seen_space_.update(t_ns, cv::Mat(), nullptr, R_H_B_from_tilt());
  apply_operator_limit(&out);
  update_height(t_ns, std::numeric_limits<double>::quiet_NaN(), out);
  update_offset_from_takeoff(t_ns, out);
  // No depth means no v_obs either: zero.
  follow_hover_thrust();
  out.mode = modes_.step(t_ns, usable_v_H_mps(out.estimate), Eigen::Vector3d::Zero());
  finish_output(out);
  correct_thrust(out);
  out.degraded = true;
  out.safe_hover = out.mode.control.safe_hover && !out.mode.landed && !out.mode.blind_descent;
  if (out.safe_hover) out.safe_hover_reason = "camera timed out: hover on IMU attitude only";
  escalate_safe_hover(out);
  return out;
}

void OnboardChain::update_height(std::int64_t t_ns, double floor_height_m, ChainOutput& out) {
  const double dt_s = height_known_ ? std::max(0.0, hq::to_seconds(t_ns - t_height_ns_)) : 0.0;
  t_height_ns_ = t_ns;
  if (std::isfinite(floor_height_m)) {
    // The floor in view is the measurement; the integrated climb carries on from it when the
    // floor leaves the view or comes nearer than the sensor's minimum range.
    height_m_ = floor_height_m;
    height_known_ = true;
    out.height_source = HeightSource::kDepth;
  } else if (modes_.landed()) {
    height_m_ = config_.chain.landed_height_m;
    height_known_ = true;
    out.height_source = HeightSource::kEstimate;
  } else if (height_known_ && out.estimate.usable()) {
    height_m_ -= out.estimate.v_H_mps.z() * dt_s;  // NED: climbing is -v_z
    out.height_source = HeightSource::kEstimate;
  } else {
    // No floor in view and no velocity to integrate: the height is not known any more.
    height_known_ = false;
    out.height_source = HeightSource::kNone;
  }
  out.height_m = out.height_source == HeightSource::kNone ? 0.0 : height_m_;
  modes_.set_height_m(out.height_source == HeightSource::kNone
                          ? std::numeric_limits<double>::quiet_NaN()
                          : height_m_);
}

void OnboardChain::update_offset_from_takeoff(std::int64_t t_ns, ChainOutput& out) {
  const double dt_s = t_offset_ns_ >= 0 ? std::max(0.0, hq::to_seconds(t_ns - t_offset_ns_)) : 0.0;
  t_offset_ns_ = t_ns;
  if (modes_.landed()) {
    // Where it lifts off is the take-off point, heading included.
    offset_T_m_.setZero();
    yaw_since_takeoff_rad_ = 0.0;
  } else if (out.estimate.usable()) {
    offset_T_m_ +=
        Eigen::Rotation2Dd(yaw_since_takeoff_rad_) * out.estimate.v_H_mps.head<2>() * dt_s;
  }
  // Without a usable estimate the vehicle holds a level hover: the offset stands still.
  out.offset_from_takeoff_H_m = Eigen::Rotation2Dd(-yaw_since_takeoff_rad_) * offset_T_m_;
  modes_.set_offset_from_takeoff_H_m(out.offset_from_takeoff_H_m);
  out.odom = odom_pose_.on_estimate(t_ns, out.estimate, modes_.landed());
}

void OnboardChain::finish_output(ChainOutput& out) const {
  out.flight_state = out.mode.flight_state;
  // Left the floor but not yet clear of it: still the take-off, whatever the mode.
  if (out.flight_state == modes::FlightState::kAirborne && !takeoff_complete_) {
    out.flight_state = modes::FlightState::kTakingOff;
  }
  // The operator feels the envelope's cut as the seen space's: the climb flown is what the
  // vehicle does, and the command-versus-estimate cue pushes back on the rest.
  if (out.mode.envelope_limited && out.mode.mode == modes::Mode::kTeleop && !out.mode.taking_off) {
    out.v_cmd_flown_H_mps.z() =
        std::max(out.v_cmd_flown_H_mps.z(), -out.mode.envelope_max_climb_mps);
    if (out.mode.envelope_horizontal_limited) {
      out.v_cmd_flown_H_mps.head<2>() = out.mode.envelope_v_xy_H_mps;
    }
    out.command_limited = true;
    out.command_envelope_limited = true;
  }
}

void OnboardChain::follow_hover_thrust() {
  const double gain = hover_thrust_.estimate().gain;
  if (gain == thrust_gain_applied_) return;
  modes_.rescale_thrust(gain / thrust_gain_applied_);
  thrust_gain_applied_ = gain;
}

void OnboardChain::correct_thrust(ChainOutput& out) {
  double& thrust_n = out.mode.control.setpoint.thrust_n;
  thrust_n = hover_thrust_.corrected_thrust_n(thrust_n);
  hover_thrust_.on_command(out.t_ns, thrust_n);
  // Only in free flight, and only while the camera confirms the motion: an inertial coast's
  // velocity is the PID's input but not evidence of what the rotors do.
  thrust_measurable_ =
      out.flight_state == modes::FlightState::kAirborne && !out.mode.landed && out.estimate.ok();
  out.hover_thrust = hover_thrust_.estimate();
  out.hover_thrust_n = hover_thrust_.hover_thrust_n();
}

void OnboardChain::apply_operator_limit(ChainOutput* out) {
  if (out != nullptr) {
    out->seen_space_bins = seen_space_.bins();
    seen_space_.heading_limits(out->seen_space_limits_mps);
  }
  if (!have_operator_command_) return;
  const seen_space::LimitedCommand limited =
      seen_space_.limit(operator_command_.v_H_mps, v_est_for_limit_H_mps_);
  modes::OperatorCommand flown = operator_command_;  // same stamp: the teleop timeout holds
  flown.v_H_mps = limited.v_H_mps;
  bool held = false;
  if (config_.chain.hold_on_inertial_coast && !velocity_from_odometry_ &&
      flown.v_H_mps.head<2>().squaredNorm() > 0.0) {
    flown.v_H_mps.head<2>().setZero();
    held = true;
  }
  modes_.set_operator_command(flown);
  if (out == nullptr) return;
  out->v_cmd_flown_H_mps = flown.v_H_mps;
  out->command_limited = limited.limited || held;
  out->command_unseen = limited.unseen;
}

void OnboardChain::escalate_safe_hover(ChainOutput& out) {
  if (out.estimate.usable()) lost_estimate_landing_ = false;
  if (!out.safe_hover) {
    in_safe_hover_ = false;
    return;
  }
  if (!in_safe_hover_) {
    in_safe_hover_ = true;
    t_safe_hover_start_ns_ = out.t_ns;
  }
  const double hover_s = hq::to_seconds(out.t_ns - t_safe_hover_start_ns_);
  if (hover_s >= config_.chain.safe_hover_land_s && modes_.mode() != modes::Mode::kLand) {
    modes_.request_mode(modes::Mode::kLand, modes::RequestOrigin::kVehicle);
    lost_estimate_landing_ = true;
    out.safe_hover_landing = true;
  }
}

void OnboardChain::set_operator_command(const modes::OperatorCommand& command) {
  if (!command.v_H_mps.allFinite() || !std::isfinite(command.yaw_rate_radps)) return;
  operator_command_ = command;
  have_operator_command_ = true;
  apply_operator_limit(nullptr);
}

modes::ModeSwitch OnboardChain::request_mode(modes::Mode mode, modes::RequestOrigin origin) {
  return request_mode(ModeRequest{mode, std::nullopt, false, origin});
}

modes::ModeSwitch OnboardChain::request_mode(const ModeRequest& request) {
  if (lost_estimate_landing_ && request.mode != modes::Mode::kLand) {
    return {false, "no velocity estimate: landing after the safe hover (chain.safe_hover_land_s)"};
  }
  if (request.marker) {
    if (request.marker->marker_id < 0) return {false, "marker target id is negative"};
    if (!markers_) {
      return {false, "marker task refused: the marker stage is off (markers.enabled: false)"};
    }
    markers_->marker_mode().set_task(request.marker->task, request.marker->marker_id);
  }
  return request.take_off ? modes_.request_takeoff(request.mode)
                          : modes_.request_mode(request.mode, request.origin);
}

}  // namespace hq::pipeline
