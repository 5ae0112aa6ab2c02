#pragma once
/// A blocking frame source (a camera driver waiting for its next frame pair) read on a thread of
/// its own, so that the vehicle's control loop never waits for a camera: next() returns the
/// newest frame not yet taken, or kNoFrame at once. Frames pass through a triple buffer
/// (lock-free: one atomic exchange per hand-over), so after the first frames neither side
/// allocates.
///
/// Stamps: a camera stamps frames on its own clock; they are mapped onto CLOCK_MONOTONIC, the
/// vehicle's clock, with the offset that makes the earliest-arriving frame's latency smallest
/// (receipt time minus device stamp, minimum kept), since transport delay is never negative.

#include "hq/frame_source/frame_source.hpp"

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

namespace hq::sources {

class ThreadedFrameSource final : public FrameSource {
 public:
  /// Starts reading `source` (owned) on a thread at once. restamp: map device stamps onto
  /// CLOCK_MONOTONIC (cameras); false keeps them (sources already on the host clock).
  explicit ThreadedFrameSource(std::unique_ptr<FrameSource> source, bool restamp = true);
  ~ThreadedFrameSource() override;
  ThreadedFrameSource(const ThreadedFrameSource&) = delete;
  ThreadedFrameSource& operator=(const ThreadedFrameSource&) = delete;

  /// The newest frame since the last call (older ones are counted in skipped()); kNoFrame with
  /// error() set while the camera delivers nothing; kEndOfStream once the source ended.
  FrameStatus next(RgbdFrame& frame) override;
  [[nodiscard]] geometry::PinholeCamera camera() const override { return camera_; }
  [[nodiscard]] std::string describe() const override { return description_; }
  [[nodiscard]] const std::string& error() const override;
  [[nodiscard]] std::optional<recording::AccelSample> accelerometer() const override;

  /// Frames the reader thread produced that the consumer never took (it was slower).
  [[nodiscard]] std::uint64_t skipped() const { return skipped_.load(); }

 private:
  void read_loop();

  std::unique_ptr<FrameSource> source_;
  bool restamp_;
  geometry::PinholeCamera camera_;
  std::string description_;
  RgbdFrame slots_[3];
  // Triple buffer: the reader writes slots_[back_], publishes by exchanging it with middle_
  // (kFresh flags a frame the consumer has not taken); the consumer swaps middle_ with front_.
  static constexpr int kFresh = 4;
  std::atomic<int> middle_{1};
  int back_ = 0;
  int front_ = 2;
  std::atomic<bool> stop_{false};
  std::atomic<bool> ended_{false};
  std::atomic<std::uint64_t> skipped_{0};
  std::int64_t offset_ns_ = 0;
  bool have_offset_ = false;
  // The device's error text changes only when it is lost or back: the consumer locks to copy it
  // only while the reader reports a failure, never on the per-frame path.
  std::atomic<bool> reader_failing_{false};
  mutable std::mutex error_mutex_;
  std::string reader_error_;
  // The accelerometer per component: a reading that mixes two consecutive samples is harmless.
  std::atomic<bool> have_accel_{false};
  std::atomic<std::int64_t> accel_t_ns_{0};
  std::atomic<double> accel_mps2_[3] = {0.0, 0.0, 0.0};
  std::thread thread_;
};

}  // namespace hq::sources
