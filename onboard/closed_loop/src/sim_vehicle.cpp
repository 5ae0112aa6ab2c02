#include "hq/closed_loop/sim_vehicle.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <limits>
#include <string>
#include <utility>

namespace hq::closed_loop {

SimFlightController::SimFlightController(sim::Simulator& sim, std::int64_t link_delay_ns)
    : sim_(sim), link_delay_ns_(link_delay_ns) {
  if (link_delay_ns < 0 || link_delay_ns >= 1'000'000'000) {
    throw InputError("simulated flight controller: link delay " + std::to_string(link_delay_ns) +
                     " ns, expected in [0, 1 s)");
  }
  imu_.resize(static_cast<std::size_t>(std::ceil(sim.config().imu.rate_hz)) + 16);
}

void SimFlightController::poll(std::int64_t t_ns, vehicle::FcSink& sink) {
  // Physics up to t, each setpoint switched in at its own time, not the step's.
  while (count_ > 0 && queue_[head_].apply_ns <= t_ns) {
    sim_.step_to(queue_[head_].apply_ns);
    sim_.set_command(queue_[head_].command);
    head_ = (head_ + 1) % kQueue;
    --count_;
  }
  sim_.step_to(t_ns);
  const std::size_t n = sim_.take_imu(imu_.data(), imu_.size());
  for (std::size_t i = 0; i < n; ++i) {
    sink.on_imu({imu_[i].t_ns, imu_[i].omega_B_radps, imu_[i].f_B_mps2});
  }
  counters_.imu_samples += n;
  counters_.messages_received += n;
}

void SimFlightController::send_setpoint(std::int64_t t_ns,
                                        const control::AttitudeSetpoint& setpoint) {
  const sim::AttitudeCommand command{setpoint.thrust_n, setpoint.roll_rad, setpoint.pitch_rad,
                                     setpoint.yaw_rate_radps};
  const std::int64_t apply_ns = t_ns + link_delay_ns_;
  if (count_ == kQueue) {  // never at 200 Hz with a delay < 1 s; the oldest gives way
    head_ = (head_ + 1) % kQueue;
    --count_;
  }
  // A later-produced setpoint never takes effect before an earlier one.
  const std::size_t tail = (head_ + count_) % kQueue;
  const std::int64_t after_ns =
      count_ > 0 ? queue_[(head_ + count_ - 1) % kQueue].apply_ns : apply_ns;
  queue_[tail] = {std::max(apply_ns, after_ns), command};
  ++count_;
  ++counters_.setpoints_sent;
  ++counters_.messages_sent;
}

vehicle::FcStatus SimFlightController::status(std::int64_t /*t_ns*/) const {
  vehicle::FcStatus s;
  s.connected = true;
  s.armed = true;
  s.offboard = true;
  s.heartbeat_age_ns = 0;
  return s;
}

std::optional<vehicle::TruthSample> SimFlightController::truth() const {
  const sim::TruthState& t = sim_.truth();
  return vehicle::TruthSample{t.v_H_mps, t.T_N_B.translation(), t.on_ground};
}

SimCamera::SimCamera(sim::Simulator& sim, std::vector<CameraFault> faults, ImageObserver observer)
    : sim_(sim), faults_(std::move(faults)), observer_(std::move(observer)) {}

const CameraFault* SimCamera::active_fault(std::int64_t t_ns) const {
  const double t_s = hq::to_seconds(t_ns);
  for (const CameraFault& fault : faults_) {
    if (t_s >= fault.start_s && t_s < fault.start_s + fault.duration_s) return &fault;
  }
  return nullptr;
}

sources::FrameStatus SimCamera::next(sources::RgbdFrame& frame) {
  if (!sim_.camera_due()) {
    error_ = "no frame due";
    return sources::FrameStatus::kNoFrame;
  }
  frame.t_ns = sim_.camera_t_ns();
  frame.depth_t_ns = frame.t_ns;  // rendered together
  sim_.render_camera(image_, frame.depth_m);
  if (observer_) observer_(frame.t_ns, image_);
  const CameraFault* fault = active_fault(frame.t_ns);
  if (fault != nullptr && fault->kind == CameraFault::Kind::kDrop) {
    error_ = "frame dropped (scheduled fault)";
    return sources::FrameStatus::kNoFrame;
  }
  if (fault != nullptr && fault->kind == CameraFault::Kind::kNanDepth) {
    frame.depth_m.setTo(std::numeric_limits<float>::quiet_NaN());
  }
  if (image_.channels() == 3) {
    frame.bgr = image_;
    cv::cvtColor(image_, frame.gray, cv::COLOR_BGR2GRAY);
  } else {
    frame.gray = image_;
    frame.bgr = image_;
  }
  return sources::FrameStatus::kFrame;
}

geometry::PinholeCamera SimCamera::camera() const { return sim_.config().camera.pinhole; }

}  // namespace hq::closed_loop
