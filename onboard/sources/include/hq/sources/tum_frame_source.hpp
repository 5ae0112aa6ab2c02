#pragma once
/// Frames from a recorded sequence in the TUM RGB-D layout.

#include "hq/config/camera_info.hpp"
#include "hq/frame_source/frame_source.hpp"
#include "hq/recording/tum_sequence.hpp"

#include <cstddef>
#include <string>

namespace hq::sources {

class TumFrameSource final : public FrameSource {
 public:
  /// Throws hq::InputError if the sequence or camera file is unreadable or their image sizes
  /// disagree.
  TumFrameSource(const std::string& sequence_dir, const config::CameraInfo& camera);

  FrameStatus next(RgbdFrame& frame) override;
  [[nodiscard]] geometry::PinholeCamera camera() const override;
  [[nodiscard]] std::string describe() const override;

  [[nodiscard]] const recording::TumSequence& sequence() const { return sequence_; }
  [[nodiscard]] std::size_t position() const { return next_index_; }

 private:
  recording::TumSequence sequence_;
  config::CameraInfo camera_;
  config::Undistorter undistorter_;
  std::size_t next_index_ = 0;
  cv::Mat raw_bgr_, raw_depth_u16_, raw_depth_m_;
};

}  // namespace hq::sources
