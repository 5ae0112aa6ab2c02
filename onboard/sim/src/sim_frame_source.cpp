#include "hq/sim/sim_frame_source.hpp"

#include "hq/base/error.hpp"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <string>
#include <utility>

namespace hq::sim {

SimFrameSource::SimFrameSource(Simulator& sim, std::int64_t end_ns, Controller controller,
                               std::int64_t control_period_ns)
    : sim_(sim),
      end_ns_(end_ns),
      controller_(std::move(controller)),
      control_period_ns_(control_period_ns),
      step_ns_(std::llround(1e9 / sim.config().dynamics_rate_hz)),
      imu_(static_cast<std::size_t>(std::ceil(sim.config().imu.rate_hz))) {
  if (control_period_ns_ <= 0) {
    throw InputError("SimFrameSource: control_period_ns = " + std::to_string(control_period_ns) +
                     ", expected > 0");
  }
  // The first tick is the first multiple of the period not before the simulator's time.
  next_control_ns_ =
      (sim_.t_ns() + control_period_ns_ - 1) / control_period_ns_ * control_period_ns_;
}

sources::FrameStatus SimFrameSource::next(sources::RgbdFrame& frame) {
  imu_count_ = 0;
  // One physics step at a time, so the frame is rendered at its own step and the IMU samples
  // taken with it end exactly at its stamp.
  while (!sim_.camera_due()) {
    if (sim_.t_ns() + step_ns_ > end_ns_) return sources::FrameStatus::kEndOfStream;
    if (controller_ && sim_.t_ns() >= next_control_ns_) {
      controller_(sim_, sim_.t_ns());
      next_control_ns_ += control_period_ns_;
    }
    sim_.step_to(sim_.t_ns() + step_ns_);
    // Drained at every step: never more than the buffer, whatever the frame period.
    imu_count_ += sim_.take_imu(imu_.data() + imu_count_, imu_.size() - imu_count_);
  }
  if (sim_.camera_t_ns() > end_ns_) return sources::FrameStatus::kEndOfStream;
  imu_count_ += sim_.take_imu(imu_.data() + imu_count_, imu_.size() - imu_count_);

  frame.t_ns = sim_.camera_t_ns();
  frame.depth_t_ns = frame.t_ns;  // rendered together
  T_N_C_ = sim_.camera_T_N_C();
  if (sim_.config().camera.gray) {
    sim_.render_camera(frame.gray, frame.depth_m);
    cv::cvtColor(frame.gray, frame.bgr, cv::COLOR_GRAY2BGR);
  } else {
    sim_.render_camera(frame.bgr, frame.depth_m);
    cv::cvtColor(frame.bgr, frame.gray, cv::COLOR_BGR2GRAY);
  }
  return sources::FrameStatus::kFrame;
}

geometry::PinholeCamera SimFrameSource::camera() const { return sim_.config().camera.pinhole; }

std::string SimFrameSource::describe() const {
  const geometry::PinholeCamera& c = sim_.config().camera.pinhole;
  return "simulator: world " + sim_.world().name + ", " + std::to_string(c.width) + "x" +
         std::to_string(c.height) + " at " +
         std::to_string(std::lround(sim_.config().camera.rate_hz)) + " Hz, seed " +
         std::to_string(sim_.config().seed);
}

}  // namespace hq::sim
