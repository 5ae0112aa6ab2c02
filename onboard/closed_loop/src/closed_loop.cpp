#include "hq/closed_loop/closed_loop.hpp"

#include "hq/base/error.hpp"

#include <opencv2/imgproc.hpp>

#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <limits>
#include <utility>

namespace hq::closed_loop {

ClosedLoop::ClosedLoop(const sim::SimConfig& sim_config, const sim::World& world,
                       const pipeline::OnboardConfig& onboard,
                       const control::VehicleConfig& vehicle, OperatorPlayer player,
                       ClosedLoopOptions options)
    : sim_(std::make_unique<sim::Simulator>(sim_config, world)),
      chain_(std::make_unique<pipeline::OnboardChain>(onboard, vehicle,
                                                      sim_config.camera.pinhole,
                                                      options.clock)),
      player_(std::move(player)),
      options_(std::move(options)) {
  if (options_.control_period_ns <= 0) {
    throw InputError("closed loop: control_period_ns = " +
                     std::to_string(options_.control_period_ns) + ", expected > 0");
  }
  if (!(options_.processing_delay_s >= 0.0 && options_.processing_delay_s < 1.0)) {
    throw InputError("closed loop: processing_delay_s = " +
                     std::to_string(options_.processing_delay_s) + ", expected in [0, 1) s");
  }
  processing_delay_ns_ = std::llround(options_.processing_delay_s * 1e9);
  imu_.resize(static_cast<std::size_t>(std::ceil(sim_config.imu.rate_hz)) + 16);
  mode_requests_.reserve(8);
  samples_.reserve(static_cast<std::size_t>(
      std::max(1.0, player_.script().end_s * sim_config.camera.rate_hz * 1.1)));
}

ClosedLoop::~ClosedLoop() = default;

const CameraFault* ClosedLoop::active_fault(std::int64_t t_ns) const {
  const double t_s = 1e-9 * static_cast<double>(t_ns);
  for (const CameraFault& fault : options_.faults) {
    if (t_s >= fault.start_s && t_s < fault.start_s + fault.duration_s) return &fault;
  }
  return nullptr;
}

void ClosedLoop::run_until(double t_s) {
  const auto end_ns = static_cast<std::int64_t>(std::llround(t_s * 1e9));
  while (t_ns_ + options_.control_period_ns <= end_ns) {
    t_ns_ += options_.control_period_ns;
    if (options_.realtime) pace(t_ns_);
    control_tick(t_ns_);
  }
}

void ClosedLoop::pace(std::int64_t t_ns) {
  // Absolute deadlines: a slow tick is not added to every later one.
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  const std::int64_t now_ns = now.tv_sec * 1'000'000'000LL + now.tv_nsec;
  if (!have_wall_origin_) {
    wall_origin_ns_ = now_ns - t_ns;
    have_wall_origin_ = true;
  }
  const std::int64_t deadline_ns = wall_origin_ns_ + t_ns;
  if (now_ns >= deadline_ns) {
    max_lag_ns_ = std::max(max_lag_ns_, now_ns - deadline_ns);
    return;
  }
  timespec deadline{};
  deadline.tv_sec = deadline_ns / 1'000'000'000LL;
  deadline.tv_nsec = deadline_ns % 1'000'000'000LL;
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, nullptr) == EINTR) {
  }
}

void ClosedLoop::feed_imu_until(std::int64_t t_ns) {
  while (imu_next_ < imu_count_ && imu_[imu_next_].t_ns <= t_ns) {
    const sim::ImuSample& s = imu_[imu_next_++];
    chain_->on_imu(s.t_ns, s.omega_body_radps, s.f_body_mps2);
  }
}

void ClosedLoop::control_tick(std::int64_t t_ns) {
  // The operator's hand: mode requests as they fall due, and the held command, refreshed at the
  // device's rate as a streaming haptic link would.
  mode_requests_.clear();
  OperatorSource* source = options_.operator_source;
  modes::OperatorCommand command;
  if (source != nullptr) {
    command = source->poll(t_ns, mode_requests_);
  } else {
    player_.take_mode_requests(t_ns, mode_requests_);
    command = player_.command(t_ns);
  }
  for (const modes::Mode mode : mode_requests_) {
    const modes::ModeSwitch result = chain_->request_mode(mode);
    if (source != nullptr) source->on_mode_result(t_ns, mode, result);
    if (!result.accepted) {
      refusals_.push_back(std::to_string(1e-9 * static_cast<double>(t_ns)) + " s: " +
                          modes::to_string(mode) + ": " + result.reason);
    }
  }
  chain_->set_operator_command(command);

  // Physics up to t, with the setpoint switched at its own time, not the tick's.
  if (pending_ && pending_apply_ns_ <= t_ns) {
    sim_->step_to(pending_apply_ns_);
    sim_->set_command(pending_command_);
    pending_ = false;
  }
  sim_->step_to(t_ns);
  imu_count_ = sim_->take_imu(imu_.data(), imu_.size());
  imu_next_ = 0;

  const sim::TruthState& truth = sim_->truth();
  if (!truth.on_ground) {
    min_clearance_m_ = std::min(min_clearance_m_, truth.clearance_m);
    if (truth.collision) ++collision_ticks_;
  }

  if (sim_->camera_due()) {
    feed_imu_until(sim_->camera_t_ns());
    process_frame();
  }
  feed_imu_until(std::numeric_limits<std::int64_t>::max());

  if (const auto held = chain_->on_tick(t_ns)) {
    const control::AttitudeSetpoint& s = held->mode.control.setpoint;
    sim_->set_command({s.thrust_n, s.roll_rad, s.pitch_rad, s.yaw_rate_radps});
    pending_ = false;
    record(*held);
  }
}

void ClosedLoop::process_frame() {
  const std::int64_t t_frame_ns = sim_->camera_t_ns();
  sim_->render_camera(image_, depth_m_);
  if (options_.operator_source != nullptr) options_.operator_source->on_camera(t_frame_ns, image_);
  const CameraFault* fault = active_fault(t_frame_ns);
  if (fault && fault->kind == CameraFault::Kind::kDrop) return;
  if (fault && fault->kind == CameraFault::Kind::kNanDepth) {
    depth_m_.setTo(std::numeric_limits<float>::quiet_NaN());
  }
  if (image_.channels() == 3) {
    cv::cvtColor(image_, gray_, cv::COLOR_BGR2GRAY);
  } else {
    gray_ = image_;
  }
  const pipeline::ChainOutput out = chain_->on_frame(t_frame_ns, gray_, depth_m_);
  if (++frames_processed_ > 1) timing_.add(out.durations);  // the first sizes the buffers
  const control::AttitudeSetpoint& s = out.mode.control.setpoint;
  pending_command_ = {s.thrust_n, s.roll_rad, s.pitch_rad, s.yaw_rate_radps};
  pending_apply_ns_ = t_frame_ns + processing_delay_ns_;
  pending_ = true;
  record(out);
}

void ClosedLoop::record(const pipeline::ChainOutput& out) {
  const sim::TruthState& truth = sim_->truth();
  FlightSample s;
  s.t_s = 1e-9 * static_cast<double>(out.t_ns);
  s.frame = out.frame;
  s.airborne = !truth.on_ground;
  s.estimate_ok = out.estimate.ok();
  s.safe_hover = out.safe_hover;
  s.degraded = out.degraded;
  s.landed = out.mode.landed;
  s.collision = truth.collision && !truth.on_ground;
  s.mode = out.mode.mode;
  s.v_est_mps = out.estimate.v_horizontal_mps;
  s.v_true_mps = truth.v_horizontal_mps;
  s.v_star_des_mps = out.mode.v_star_des_horizontal_mps;
  s.v_des_mps = out.mode.v_des_horizontal_mps;
  s.v_obs_mps = out.obstacles.v_obs_horizontal_mps;
  s.yaw_rate_cmd_radps = out.mode.control.setpoint.yaw_rate_radps;
  s.yaw_rate_gyro_radps = out.estimate.omega_body_radps.z();
  s.yaw_rate_true_radps = truth.omega_body_radps.z();
  s.clearance_m = truth.clearance_m;
  s.p_world_m = truth.T_world_body.translation();
  s.reason = out.safe_hover ? out.safe_hover_reason : "";
  samples_.push_back(s);
  if (options_.operator_source != nullptr) options_.operator_source->on_output(out, truth);
}

}  // namespace hq::closed_loop
