#pragma once
/// The simulator as an on-board frame source: next() advances a Simulator in lock-step, one
/// physics step at a time, to the next camera frame and renders it into the caller's frame, so
/// the on-board chain runs on simulated frames exactly as on a recording or a camera. Time is
/// the simulator's, never the wall clock.

#include "hq/frame_source/frame_source.hpp"
#include "hq/sim/imu.hpp"
#include "hq/sim/simulator.hpp"

#include <cstdint>
#include <functional>
#include <limits>
#include <span>
#include <string>
#include <vector>

namespace hq::sim {

class SimFrameSource final : public sources::FrameSource {
 public:
  /// Called with the simulator at every control tick (t_ns multiple of the control period),
  /// before the physics steps after it, typically to set_command (zero-order hold).
  using Controller = std::function<void(Simulator& sim, std::int64_t t_ns)>;

  /// @param sim     driven by this source; must outlive it. Nothing else may step it.
  /// @param end_ns  simulated time after which next() reports kEndOfStream.
  /// @param controller  optional; without it the last command holds.
  /// @param control_period_ns  > 0: ticks of the controller.
  /// Throws hq::InputError for a non-positive control period.
  explicit SimFrameSource(Simulator& sim,
                          std::int64_t end_ns = std::numeric_limits<std::int64_t>::max(),
                          Controller controller = {},
                          std::int64_t control_period_ns = kDefaultControlPeriodNs);

  /// Steps to the next camera frame (the first call delivers the frame due at t = 0) and fills
  /// frame.bgr, frame.gray (whichever the camera does not render is converted) and
  /// frame.depth_m. kEndOfStream once the frame would fall after end_ns. Allocates nothing once
  /// the frame's buffers are sized (after the first call).
  sources::FrameStatus next(sources::RgbdFrame& frame) override;
  [[nodiscard]] geometry::PinholeCamera camera() const override;
  [[nodiscard]] std::string describe() const override;

  /// IMU samples stamped after the previous frame and at or before the last delivered frame,
  /// oldest first (for the first frame: those up to t = 0). Valid until the next next().
  [[nodiscard]] std::span<const ImuSample> imu() const { return {imu_.data(), imu_count_}; }
  /// True camera pose at the last delivered frame's stamp.
  [[nodiscard]] const Eigen::Isometry3d& T_N_C() const { return T_N_C_; }

  /// 200 Hz, as a flight computer commands (the scripted flights' rate).
  static constexpr std::int64_t kDefaultControlPeriodNs = 5'000'000;

 private:
  Simulator& sim_;
  std::int64_t end_ns_;
  Controller controller_;
  std::int64_t control_period_ns_;
  std::int64_t next_control_ns_ = 0;
  std::int64_t step_ns_;
  std::vector<ImuSample> imu_;  ///< sized once: the simulator's 1 s of IMU samples.
  std::size_t imu_count_ = 0;
  Eigen::Isometry3d T_N_C_ = Eigen::Isometry3d::Identity();
};

}  // namespace hq::sim
