#include "hq/closed_loop/closed_loop.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <limits>
#include <time.h>
#include <utility>

namespace hq::closed_loop {

/// The runtime's operator: the scripted player, a legacy OperatorSource or a vehicle operator
/// port, and the flight record of every output.
class ClosedLoop::Port final : public vehicle::OperatorPort {
 public:
  explicit Port(ClosedLoop& loop) : loop_(loop) { modes_.reserve(8); }

  modes::OperatorCommand poll(std::int64_t t_ns,
                              std::vector<pipeline::ModeRequest>& requests) override {
    const ClosedLoopOptions& o = loop_.options_;
    if (o.operator_port != nullptr) return o.operator_port->poll(t_ns, requests);
    modes_.clear();
    modes::OperatorCommand command;
    if (o.operator_source != nullptr) {
      command = o.operator_source->poll(t_ns, modes_);
    } else {
      loop_.player_.take_mode_requests(t_ns, modes_);
      command = loop_.player_.command(t_ns);
    }
    for (const modes::Mode mode : modes_) requests.push_back({mode, std::nullopt});
    return command;
  }

  void on_mode_result(std::int64_t t_ns, const pipeline::ModeRequest& request,
                      const modes::ModeSwitch& result) override {
    const ClosedLoopOptions& o = loop_.options_;
    if (o.operator_port != nullptr) o.operator_port->on_mode_result(t_ns, request, result);
    if (o.operator_source != nullptr) o.operator_source->on_mode_result(t_ns, request.mode, result);
    if (!result.accepted) {
      loop_.refusals_.push_back(std::to_string(hq::to_seconds(t_ns)) +
                                " s: " + modes::to_string(request.mode) + ": " + result.reason);
    }
  }

  void on_output(const pipeline::ChainOutput& out, const vehicle::VehicleStatus& status) override {
    if (out.frame && ++loop_.frames_processed_ > 1) {
      loop_.timing_.add(out.durations);  // the first frame sizes the buffers
    }
    loop_.record(out);
    const ClosedLoopOptions& o = loop_.options_;
    if (o.operator_port != nullptr) o.operator_port->on_output(out, status);
    if (o.operator_source != nullptr) o.operator_source->on_output(out, loop_.sim_->truth());
  }

  void on_frame(const sources::RgbdFrame& frame) override {
    if (loop_.options_.operator_port != nullptr) loop_.options_.operator_port->on_frame(frame);
  }

  void on_event(std::int64_t t_ns, vehicle::FcSeverity severity, std::string_view text) override {
    if (loop_.options_.operator_port != nullptr) {
      loop_.options_.operator_port->on_event(t_ns, severity, text);
    }
  }

 private:
  ClosedLoop& loop_;
  std::vector<modes::Mode> modes_;
};

ClosedLoop::ClosedLoop(const sim::SimConfig& sim_config, const sim::World& world,
                       const pipeline::OnboardConfig& onboard, const VehicleConfig& vehicle,
                       OperatorPlayer player, ClosedLoopOptions options)
    : sim_(std::make_unique<sim::Simulator>(sim_config, world)),
      chain_(std::make_unique<pipeline::OnboardChain>(onboard, vehicle, sim_config.camera.pinhole,
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
  if (options_.operator_port != nullptr && options_.operator_source != nullptr) {
    throw InputError("closed loop: give an operator_port or an operator_source, not both");
  }
  fc_ =
      std::make_unique<SimFlightController>(*sim_, std::llround(options_.processing_delay_s * 1e9));
  SimCamera::ImageObserver observer;
  if (options_.operator_source != nullptr) {
    observer = [source = options_.operator_source](std::int64_t t_ns, const cv::Mat& image) {
      source->on_camera(t_ns, image);
    };
  }
  camera_ = std::make_unique<SimCamera>(*sim_, options_.faults, std::move(observer));
  port_ = std::make_unique<Port>(*this);
  vehicle::RuntimeConfig runtime_config;
  runtime_config.control_period_ns = options_.control_period_ns;
  runtime_ = std::make_unique<vehicle::VehicleRuntime>(*chain_, *camera_, *fc_, port_.get(),
                                                       fc_.get(), runtime_config);
  samples_.reserve(static_cast<std::size_t>(
      std::max(1.0, player_.script().end_s * sim_config.camera.rate_hz * 1.1)));
}

ClosedLoop::~ClosedLoop() = default;

void ClosedLoop::run_until(double t_s) {
  const auto end_ns = static_cast<std::int64_t>(std::llround(t_s * 1e9));
  while (t_ns_ + options_.control_period_ns <= end_ns) {
    t_ns_ += options_.control_period_ns;
    if (options_.realtime) pace(t_ns_);
    const int hard_impacts_before = sim_->hard_floor_impacts();
    runtime_->step(t_ns_);
    const sim::TruthState& truth = sim_->truth();
    if (!truth.on_ground) {
      min_clearance_m_ = std::min(min_clearance_m_, truth.clearance_m);
      if (truth.collision) ++collision_ticks_;
    } else if (sim_->hard_floor_impacts() > hard_impacts_before) {
      ++collision_ticks_;  // a fall onto the floor, seen between two control ticks
    }
  }
}

void ClosedLoop::pace(std::int64_t t_ns) {
  // Absolute deadlines: a slow tick is not added to every later one.
  const std::int64_t now_ns = monotonic_now_ns();
  if (!have_wall_origin_) {
    wall_origin_ns_ = now_ns - t_ns;
    have_wall_origin_ = true;
  }
  const std::int64_t deadline_ns = wall_origin_ns_ + t_ns;
  if (now_ns >= deadline_ns) {
    max_lag_ns_ = std::max(max_lag_ns_, now_ns - deadline_ns);
    return;
  }
  sleep_until_monotonic_ns(deadline_ns);
}

void ClosedLoop::record(const pipeline::ChainOutput& out) {
  const sim::TruthState& truth = sim_->truth();
  FlightSample s;
  s.t_s = hq::to_seconds(out.t_ns);
  s.frame = out.frame;
  s.airborne = !truth.on_ground;
  s.estimate_ok = out.estimate.ok();
  s.safe_hover = out.safe_hover;
  s.degraded = out.degraded;
  s.landed = out.mode.landed;
  s.collision = truth.collision && !truth.on_ground;
  s.mode = out.mode.mode;
  s.v_est_mps = out.estimate.v_H_mps;
  s.v_true_mps = truth.v_H_mps;
  s.roll_pitch_est_rad = {out.estimate.roll_rad, out.estimate.pitch_rad};
  s.roll_pitch_true_rad = truth.euler_rad.head<2>();
  s.v_star_des_mps = out.mode.v_star_des_H_mps;
  s.v_des_mps = out.mode.v_des_H_mps;
  s.v_obs_mps = out.obstacles.v_obs_H_mps;
  s.yaw_rate_cmd_radps = out.mode.control.setpoint.yaw_rate_radps;
  s.yaw_rate_gyro_radps = out.estimate.omega_B_radps.z();
  s.yaw_rate_true_radps = truth.omega_B_radps.z();
  s.clearance_m = truth.clearance_m;
  s.clearance_sent_m = out.clearance_m;
  s.p_N_m = truth.T_N_B.translation();
  s.reason = out.safe_hover ? out.safe_hover_reason : "";
  s.flight_state = out.flight_state;
  s.height_m = out.height_m;
  s.height_source = out.height_source;
  s.hover_thrust_gain = out.hover_thrust.gain;
  s.odom = out.odom;
  const Eigen::Vector3d x_B_N = truth.T_N_B.linear().col(0);
  s.heading_true_ned_rad = std::atan2(-x_B_N.y(), x_B_N.x());  // N is NWU: y left
  samples_.push_back(s);
}

}  // namespace hq::closed_loop
