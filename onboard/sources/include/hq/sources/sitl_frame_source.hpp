#pragma once
/// Frames from a simulator running as a separate SITL process (hq-sim --sitl), read from its
/// shared-memory frame channel. Stamps are the host's CLOCK_MONOTONIC at exposure, as a camera
/// driver gives them, so the vehicle process runs on SITL frames as on a real camera.

#include "hq/frame_channel/frame_channel.hpp"
#include "hq/frame_source/frame_source.hpp"

#include <optional>
#include <string>

namespace hq::sources {

class SitlFrameSource final : public FrameSource {
 public:
  /// Opens /hq-<channel_name>. Throws hq::InputError when the channel is absent or bad (see
  /// FrameChannelReader) or carries no intrinsics.
  explicit SitlFrameSource(const std::string& channel_name = frame_channel::kDefaultChannelName,
                           const frame_channel::ReaderOptions& options = {});

  /// Never blocks: kFrame with the newest frame not delivered yet (gray and depth_m; bgr too
  /// when the channel is colour), else kNoFrame with error() "no new frame" or "SITL writer
  /// gone". Never kEndOfStream: a restarted hq-sim is picked up. Allocates nothing once the
  /// frame's buffers are sized.
  FrameStatus next(RgbdFrame& frame) override;
  /// The intrinsics hq-sim published in the channel header.
  [[nodiscard]] geometry::PinholeCamera camera() const override;
  [[nodiscard]] std::string describe() const override;
  /// Simulator truth of the last delivered frame, if the writer sent it.
  [[nodiscard]] std::optional<frame_channel::SitlTruth> truth() const;
  /// CLOCK_MONOTONIC of hq-sim's simulated t = 0, the boot of the flight controller it plays:
  /// its MAVLink time_usec is at t_ns = fc_time_origin_ns() + 1000 * time_usec. 0: not set yet.
  [[nodiscard]] std::int64_t fc_time_origin_ns() const { return reader_.time_origin_ns(); }
  [[nodiscard]] const frame_channel::FrameChannelReader& reader() const { return reader_; }

 private:
  frame_channel::FrameChannelReader reader_;
  frame_channel::FrameInfo info_;
  bool delivered_ = false;
};

}  // namespace hq::sources
