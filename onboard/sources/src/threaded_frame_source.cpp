#include "hq/sources/threaded_frame_source.hpp"

#include "hq/base/monotonic_clock.hpp"

#include <algorithm>
#include <utility>

namespace hq::sources {
ThreadedFrameSource::ThreadedFrameSource(std::unique_ptr<FrameSource> source, bool restamp)
    : source_(std::move(source)),
      restamp_(restamp),
      camera_(source_->camera()),
      description_(source_->describe()) {
  thread_ = std::thread([this] { read_loop(); });
}

ThreadedFrameSource::~ThreadedFrameSource() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void ThreadedFrameSource::read_loop() {
  while (!stop_) {
    RgbdFrame& frame = slots_[back_];
    const FrameStatus status = source_->next(frame);
    const bool failing = status == FrameStatus::kNoFrame;
    if (failing) {
      const std::lock_guard<std::mutex> lock(error_mutex_);
      reader_error_ = source_->error();
    }
    reader_failing_ = failing;
    if (const auto accel = source_->accelerometer()) {
      for (int i = 0; i < 3; ++i) accel_mps2_[i] = accel->accel_mps2[i];
      accel_t_ns_ = accel->t_ns;
      have_accel_ = true;
    }
    if (status == FrameStatus::kEndOfStream) {
      ended_ = true;
      return;
    }
    if (status != FrameStatus::kFrame) continue;  // the source paces its own retries
    if (restamp_) {
      const std::int64_t receipt_offset_ns = monotonic_now_ns() - frame.t_ns;
      offset_ns_ = have_offset_ ? std::min(offset_ns_, receipt_offset_ns) : receipt_offset_ns;
      have_offset_ = true;
      frame.t_ns += offset_ns_;
    }
    const int previous = middle_.exchange(back_ | kFresh);
    if ((previous & kFresh) != 0) ++skipped_;
    back_ = previous & ~kFresh;
  }
}

FrameStatus ThreadedFrameSource::next(RgbdFrame& frame) {
  if ((middle_.load() & kFresh) == 0) {
    if (ended_) return FrameStatus::kEndOfStream;
    if (reader_failing_) {
      const std::lock_guard<std::mutex> lock(error_mutex_);
      error_ = reader_error_;
    } else {
      error_ = "no new frame";  // short enough for the string's own buffer: no allocation
    }
    return FrameStatus::kNoFrame;
  }
  front_ = middle_.exchange(front_) & ~kFresh;
  const RgbdFrame& taken = slots_[front_];
  frame.t_ns = taken.t_ns;
  frame.depth_t_ns = taken.depth_t_ns;
  taken.bgr.copyTo(frame.bgr);
  taken.gray.copyTo(frame.gray);
  taken.depth_m.copyTo(frame.depth_m);
  return FrameStatus::kFrame;
}

const std::string& ThreadedFrameSource::error() const { return error_; }

std::optional<recording::AccelSample> ThreadedFrameSource::accelerometer() const {
  if (!have_accel_) return std::nullopt;
  recording::AccelSample sample;
  sample.t_ns = accel_t_ns_;
  for (int i = 0; i < 3; ++i) sample.accel_mps2[i] = accel_mps2_[i];
  return sample;
}

}  // namespace hq::sources
