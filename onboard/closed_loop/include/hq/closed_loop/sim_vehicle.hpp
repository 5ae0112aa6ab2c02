#pragma once
/// The in-process simulator as the vehicle runtime's flight controller and camera, for the
/// lock-step campaigns: SimFlightController steps the physics to the runtime's time and hands
/// over the IMU; a setpoint takes effect a link delay after it was produced (frame processing and
/// the serial link to a flight controller); SimCamera renders each frame as it falls due, with
/// scheduled faults. Both share one Simulator, which nothing else may step.

#include "hq/frame_source/frame_source.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/vehicle/flight_controller.hpp"
#include "hq/vehicle/vehicle_runtime.hpp"

#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

namespace hq::closed_loop {

struct CameraFault {
  enum class Kind { kDrop, kNanDepth };
  Kind kind = Kind::kDrop;
  double start_s = 0.0;
  double duration_s = 0.0;
};

class SimFlightController final : public vehicle::FlightController, public vehicle::TruthSource {
 public:
  /// @param link_delay_ns  from a setpoint's stamp to its effect, >= 0.
  /// Throws hq::InputError for a negative delay.
  SimFlightController(sim::Simulator& sim, std::int64_t link_delay_ns);

  void poll(std::int64_t t_ns, vehicle::FcSink& sink) override;
  void send_setpoint(std::int64_t t_ns, const control::AttitudeSetpoint& setpoint) override;
  /// Always connected, armed and in offboard: the simulated vehicle flies what it is sent.
  [[nodiscard]] vehicle::FcStatus status(std::int64_t t_ns) const override;
  [[nodiscard]] vehicle::FcCounters counters() const override { return counters_; }
  [[nodiscard]] std::string describe() const override { return "in-process simulator"; }
  [[nodiscard]] std::optional<vehicle::TruthSample> truth() const override;

 private:
  struct Pending {
    std::int64_t apply_ns = 0;
    sim::AttitudeCommand command;
  };
  static constexpr std::size_t kQueue = 64;

  sim::Simulator& sim_;
  std::int64_t link_delay_ns_;
  std::array<Pending, kQueue> queue_{};
  std::size_t head_ = 0;
  std::size_t count_ = 0;
  std::vector<sim::ImuSample> imu_;
  vehicle::FcCounters counters_;
};

class SimCamera final : public sources::FrameSource {
 public:
  /// Called with every rendered image (as rendered: BGR or gray), dropped ones included.
  using ImageObserver = std::function<void(std::int64_t t_ns, const cv::Mat& image)>;
  SimCamera(sim::Simulator& sim, std::vector<CameraFault> faults, ImageObserver observer = {});

  /// kFrame when a frame fell due since the last call (rendered now, faults applied), else
  /// kNoFrame. A frame dropped by a fault is kNoFrame.
  sources::FrameStatus next(sources::RgbdFrame& frame) override;
  [[nodiscard]] geometry::PinholeCamera camera() const override;
  [[nodiscard]] std::string describe() const override { return "in-process simulator camera"; }

 private:
  [[nodiscard]] const CameraFault* active_fault(std::int64_t t_ns) const;

  sim::Simulator& sim_;
  std::vector<CameraFault> faults_;
  ImageObserver observer_;
  cv::Mat image_;
};

}  // namespace hq::closed_loop
