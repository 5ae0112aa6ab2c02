#include "hq/vehicle/vehicle_runtime.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/estimator/complementary_filter.hpp"
#include "hq/marker_modes/marker_providers.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>

namespace hq::vehicle {
namespace {

bool flying_mode(modes::Mode mode) {
  return mode == modes::Mode::kTeleop || mode == modes::Mode::kMarker ||
         mode == modes::Mode::kExplore;
}

}  // namespace

const char* to_string(StopAction action) { return action == StopAction::kLand ? "land" : "hold"; }

VehicleRuntime::VehicleRuntime(pipeline::OnboardChain& chain, sources::FrameSource& source,
                               FlightController& fc, OperatorPort* op, const TruthSource* truth,
                               const RuntimeConfig& config)
    : chain_(chain), source_(source), fc_(fc), op_(op), truth_(truth), config_(config) {
  if (config_.control_period_ns <= 0 || config_.control_period_ns > 100'000'000) {
    throw InputError("vehicle runtime: control_period_ns = " +
                     std::to_string(config_.control_period_ns) + ", expected in (0, 1e8] ns");
  }
  if (config_.imu_capacity < 16 || config_.imu_capacity > 100'000) {
    throw InputError("vehicle runtime: imu_capacity = " + std::to_string(config_.imu_capacity) +
                     ", expected in [16, 100000]");
  }
  if (!(config_.velocity_variance_m2ps2 > 0.0 && config_.velocity_variance_m2ps2 < 100.0)) {
    throw InputError("vehicle runtime: velocity_variance_m2ps2 = " +
                     std::to_string(config_.velocity_variance_m2ps2) + ", expected in (0, 100)");
  }
  imu_.resize(static_cast<std::size_t>(config_.imu_capacity));
  requests_.reserve(16);
}

std::optional<std::int64_t> VehicleRuntime::pending_frame_t_ns() const {
  if (!have_pending_) return std::nullopt;
  return frame_.t_ns;
}

void VehicleRuntime::on_imu(const FcImuSample& sample) {
  if (imu_count_ == config_.imu_capacity) {
    ++counters_.imu_overflow;
    return;
  }
  imu_[static_cast<std::size_t>(imu_count_++)] = sample;
}

void VehicleRuntime::on_fc_event(FcSeverity severity, std::string_view text) {
  event(t_now_ns_, severity, text);
}

void VehicleRuntime::event(std::int64_t t_ns, FcSeverity severity, std::string_view text) {
  if (op_ != nullptr) op_->on_event(t_ns, severity, text);
}

bool VehicleRuntime::step(std::int64_t t_ns) {
  t_now_ns_ = t_ns;
  ++counters_.steps;
  imu_count_ = 0;
  imu_next_ = 0;
  fc_.poll(t_ns, *this);
  counters_.imu_samples += static_cast<std::uint64_t>(imu_count_);
  supervise_fc(t_ns);
  take_operator(t_ns);
  request_arm_when_ready(t_ns);

  if (!have_pending_ && !ended_) {
    switch (source_.next(frame_)) {
      case sources::FrameStatus::kFrame:
        have_pending_ = true;
        break;
      case sources::FrameStatus::kEndOfStream:
        ended_ = true;
        break;
      case sources::FrameStatus::kNoFrame:
        break;
    }
  }
  if (have_pending_ && frame_.t_ns <= t_ns) {
    have_pending_ = false;
    if (have_frame_ && frame_.t_ns <= t_last_frame_ns_) {
      ++counters_.frames_out_of_order;
    } else {
      // IMU up to the exposure first, so the chain's attitude is the frame's.
      feed_imu_until(frame_.t_ns);
      have_frame_ = true;
      t_last_frame_ns_ = frame_.t_ns;
      ++counters_.frames;
      const pipeline::ChainOutput out =
          chain_.on_frame(frame_.t_ns, frame_.depth_exposure_ns(), frame_.gray, frame_.depth_m);
      if (op_ != nullptr) op_->on_frame(frame_);
      deliver(out);
    }
  }
  feed_imu_until(std::numeric_limits<std::int64_t>::max());
  if (t_ns >= next_tick_ns_) {
    next_tick_ns_ = t_ns + config_.control_period_ns;
    if (const std::optional<pipeline::ChainOutput> held = chain_.on_tick(t_ns)) {
      ++counters_.ticks;
      deliver(*held);
    }
  }
  return !ended();
}

void VehicleRuntime::feed_imu_until(std::int64_t t_ns) {
  while (imu_next_ < imu_count_ && imu_[static_cast<std::size_t>(imu_next_)].t_ns <= t_ns) {
    const FcImuSample& s = imu_[static_cast<std::size_t>(imu_next_++)];
    chain_.on_imu(s.t_ns, s.omega_B_radps, s.f_B_mps2);
  }
}

void VehicleRuntime::begin_stop(std::int64_t t_ns, StopAction action) {
  if (stopping_) return;
  stopping_ = true;
  stop_action_ = action;
  arm_wanted_ = false;
  chain_.set_operator_command({});
  if (landed()) {
    event(t_ns, FcSeverity::kInfo, "vehicle stopping: landed, motors idle");
    return;
  }
  if (status_.fc_lost) {
    event(t_ns, FcSeverity::kWarning,
          "vehicle stopping: the flight controller is lost, nothing left to land through");
    return;
  }
  const bool land = action == StopAction::kLand;
  chain_.request_mode(land ? modes::Mode::kLand : modes::Mode::kHover,
                      modes::RequestOrigin::kVehicle);
  event(t_ns, FcSeverity::kWarning,
        land ? "vehicle stopping: landing before the run ends"
             : "vehicle stopping: holding; the flight controller's failsafe takes over at the end");
}

bool VehicleRuntime::stop_complete() const {
  if (!stopping_) return false;
  if (landed() || status_.fc_lost) return true;
  return stop_action_ == StopAction::kHold && last_ && last_->mode.mode == modes::Mode::kHover;
}

void VehicleRuntime::take_operator(std::int64_t t_ns) {
  if (op_ == nullptr) return;
  requests_.clear();
  const modes::OperatorCommand polled = op_->poll(t_ns, requests_);
  // Stopping: the port is polled (heartbeats, fail-safes) but the operator no longer flies.
  if (stopping_) return;
  const modes::OperatorCommand& command = polled;
  for (const pipeline::ModeRequest& request : requests_) {
    const modes::ModeSwitch result = chain_.request_mode(request);
    op_->on_mode_result(t_ns, request, result);
    // Arming is the operator's act: a request to fly while the FC is not flying our setpoints
    // asks it to arm, now or as soon as it is heard and the stream runs (a few tries). A request
    // for hover or land withdraws it. The runtime never asks on its own initiative.
    if (result.accepted) {
      arm_wanted_ = (flying_mode(request.mode) || request.take_off) &&
                    !(status_.fc.armed && status_.fc.offboard);
      arm_attempts_ = 0;
      next_arm_attempt_ns_ = t_ns;
    }
  }
  chain_.set_operator_command(command);
}

void VehicleRuntime::request_arm_when_ready(std::int64_t t_ns) {
  const FcStatus& fc = status_.fc;
  if (!arm_wanted_) return;
  if (fc.armed && fc.offboard) {
    arm_wanted_ = false;
    return;
  }
  if (!fc.connected || !status_.streaming || t_ns < next_arm_attempt_ns_) return;
  if (arm_attempts_ == kMaxArmAttempts) {
    arm_wanted_ = false;
    event(t_ns, FcSeverity::kWarning,
          "the FC did not arm and enter offboard after 5 requests: ask to fly again to retry");
    return;
  }
  fc_.request_arm_offboard(t_ns);
  ++counters_.arm_requests;
  ++arm_attempts_;
  next_arm_attempt_ns_ = t_ns + kArmRetryNs;
  if (arm_attempts_ == 1) {
    event(t_ns, FcSeverity::kInfo,
          "operator asked to fly: requesting the FC to arm and enter offboard");
  }
}

void VehicleRuntime::supervise_fc(std::int64_t t_ns) {
  status_.fc = fc_.status(t_ns);
  const FcStatus& fc = status_.fc;
  char text[160];
  if (fc.connected) {
    if (status_.fc_lost) event(t_ns, FcSeverity::kInfo, "flight controller heard again");
    ever_connected_ = true;
    status_.fc_lost = false;
  } else if (ever_connected_ && !status_.fc_lost) {
    status_.fc_lost = true;
    hq::format_into(text,
                    "flight controller lost: nothing heard for {:.0f} ms; holding, link degraded",
                    1e-6 * static_cast<double>(fc.heartbeat_age_ns));
    event(t_ns, FcSeverity::kError, text);
    arm_wanted_ = false;
    if (!landed()) chain_.request_mode(modes::Mode::kHover, modes::RequestOrigin::kVehicle);
  }
  const bool flying_offboard = fc.connected && fc.armed && fc.offboard;
  if (was_flying_offboard_ && !flying_offboard && fc.connected) {
    status_.fc_override = true;
    arm_wanted_ = false;
    if (!fc.armed) {
      event(
          t_ns, FcSeverity::kError,
          "flight controller disarmed (its failsafe, the pilot or a GCS): landing, not re-arming");
      if (!landed()) chain_.request_mode(modes::Mode::kLand, modes::RequestOrigin::kVehicle);
    } else {
      event(t_ns, FcSeverity::kError,
            "flight controller left offboard (its failsafe, the pilot's RC or a GCS): our "
            "setpoints "
            "are not flown; holding, not re-entering offboard");
      if (!landed()) chain_.request_mode(modes::Mode::kHover, modes::RequestOrigin::kVehicle);
    }
  }
  if (flying_offboard) status_.fc_override = false;
  was_flying_offboard_ = flying_offboard;
}

void VehicleRuntime::deliver(const pipeline::ChainOutput& out) {
  // Landed, the chain knows the state without odometry (at rest, motors idle): its idle
  // setpoints are safe to stream, and PX4 needs the stream before it enters offboard.
  if (!status_.streaming && (out.estimate.ok() || out.mode.landed)) {
    status_.streaming = true;
    event(out.t_ns, FcSeverity::kInfo,
          out.mode.landed ? "landed and at rest: setpoint stream to the FC started"
                          : "first estimate: setpoint stream to the FC started");
  }
  if (out.frame) report_velocity(out);
  if (status_.streaming) {
    fc_.send_setpoint(out.t_ns, out.mode.control.setpoint);
    ++counters_.setpoints;
  } else {
    ++counters_.setpoints_withheld;
  }
  announce_hover_thrust(out);
  announce_marker_position(out);
  status_.truth = truth_ != nullptr ? truth_->truth() : std::nullopt;
  last_ = out;
  if (op_ != nullptr) op_->on_output(out, status_);
}

void VehicleRuntime::announce_hover_thrust(const pipeline::ChainOutput& out) {
  // Once per flight the operator hears what the vehicle really needs: a gain far from 1 means
  // the mass or the FC's maximum thrust in the config is off, worth fixing before the next one.
  if (out.hover_thrust.converged == said_hover_thrust_) return;
  said_hover_thrust_ = out.hover_thrust.converged;
  if (!said_hover_thrust_) return;
  char text[160];
  hq::format_into(
      text,
      "hover thrust learnt: the rotors give {:.0f} % of the thrust commanded; hovering on {:.1f} N",
      100.0 * out.hover_thrust.gain, out.hover_thrust_n);
  const bool far_off = std::abs(out.hover_thrust.gain - 1.0) > 0.15;
  event(out.t_ns, far_off ? FcSeverity::kWarning : FcSeverity::kInfo, text);
}

void VehicleRuntime::announce_marker_position(const pipeline::ChainOutput& out) {
  marker_modes::MarkerStage* markers = chain_.markers();
  if (markers == nullptr) return;
  if (const char* text = markers->position_event(out.mode.mode, out.t_ns)) {
    event(out.t_ns, markers->holding_for_position() ? FcSeverity::kWarning : FcSeverity::kInfo,
          text);
  }
}

void VehicleRuntime::report_velocity(const pipeline::ChainOutput& out) {
  const estimator::VelocityEstimate& estimate = out.estimate;
  if (!estimate.usable()) {
    velocity_interrupted_ = velocity_reported_;
    return;
  }
  // Keyframe changes of the odometry do not count: the fused velocity is continuous across
  // them. Only a restart of the estimator's filter (after it was unavailable, or reset) is.
  if (velocity_interrupted_) {
    ++velocity_reset_counter_;
    ++counters_.velocity_resets;
    velocity_interrupted_ = false;
  }
  VelocityReport report;
  report.t_ns = out.t_ns;
  report.v_H_mps = estimate.v_H_mps;
  report.roll_rad = estimate.roll_rad;
  report.pitch_rad = estimate.pitch_rad;
  report.source = estimate.ok() ? VelocitySource::kOdometry : VelocitySource::kInertialCoast;
  report.reset_counter = velocity_reset_counter_;
  const double floor_m2ps2 = config_.velocity_variance_m2ps2;
  const Eigen::Matrix3d& covariance = estimate.v_H_covariance;
  if (covariance.allFinite() && covariance.diagonal().minCoeff() > 0.0) {
    report.covariance_H_m2ps2 = covariance;
    for (int i = 0; i < 3; ++i) {
      report.covariance_H_m2ps2(i, i) = std::max(covariance(i, i), floor_m2ps2);
    }
  } else {
    report.covariance_H_m2ps2 = floor_m2ps2 * Eigen::Matrix3d::Identity();
  }
  fc_.send_velocity(report);
  velocity_reported_ = true;
  ++counters_.velocity_reports;
}

NoFlightController::NoFlightController(std::vector<FcImuSample> recorded)
    : recorded_(std::move(recorded)) {}

void NoFlightController::set_tilt_source(const sources::FrameSource* tilt_source,
                                         const Eigen::Matrix3d& R_B_sensor, double rate_hz) {
  if (!(rate_hz >= 1.0 && rate_hz <= 10'000.0)) {
    throw InputError("fc none: IMU rate_hz = " + std::to_string(rate_hz) +
                     ", expected in [1, 10000]");
  }
  tilt_source_ = tilt_source;
  R_B_sensor_ = R_B_sensor;
  imu_period_ns_ = std::llround(1e9 / rate_hz);
  synthesise_ = true;
}

void NoFlightController::poll(std::int64_t t_ns, FcSink& sink) {
  while (next_recorded_ < recorded_.size() && recorded_[next_recorded_].t_ns <= t_ns) {
    sink.on_imu(recorded_[next_recorded_++]);
    ++counters_.imu_samples;
  }
  if (!synthesise_) return;
  if (next_imu_ns_ < 0) next_imu_ns_ = t_ns;
  Eigen::Vector3d f_B_mps2(0.0, 0.0, -estimator::kGravityMps2);
  if (tilt_source_ != nullptr) {
    if (const auto accel = tilt_source_->accelerometer()) {
      if (accel->accel_mps2.allFinite()) f_B_mps2 = R_B_sensor_ * accel->accel_mps2;
    }
  }
  for (; next_imu_ns_ <= t_ns; next_imu_ns_ += imu_period_ns_) {
    sink.on_imu({next_imu_ns_, Eigen::Vector3d::Zero(), f_B_mps2});
    ++counters_.imu_samples;
  }
}

void NoFlightController::send_setpoint(std::int64_t /*t_ns*/,
                                       const control::AttitudeSetpoint& setpoint) {
  last_setpoint_ = setpoint;
  ++counters_.setpoints_sent;
}

FcStatus NoFlightController::status(std::int64_t /*t_ns*/) const {
  // Nothing to lose: never connected, so the runtime raises no FC alarm.
  return {};
}

std::string NoFlightController::describe() const {
  if (!recorded_.empty()) return "no flight controller (recorded IMU, setpoints logged only)";
  return synthesise_ ? "no flight controller (no gyro; tilt from the accelerometer or level)"
                     : "no flight controller (setpoints logged only)";
}

}  // namespace hq::vehicle
