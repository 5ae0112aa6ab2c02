#include "hq/sources/sitl_frame_source.hpp"

#include "hq/base/error.hpp"

#include <opencv2/imgproc.hpp>

namespace hq::sources {

SitlFrameSource::SitlFrameSource(const std::string& channel_name,
                                 const frame_channel::ReaderOptions& options)
    : reader_(channel_name, options) {
  const frame_channel::ChannelGeometry& g = reader_.geometry();
  if (!(g.fx > 0.0 && g.fy > 0.0)) {
    throw InputError("frame channel " + reader_.name() +
                     ": carries no intrinsics (fx, fy = 0), expected a camera's");
  }
}

FrameStatus SitlFrameSource::next(RgbdFrame& frame) {
  const bool colour = reader_.geometry().channels == 3;
  if (!reader_.take_latest(colour ? frame.bgr : frame.gray, frame.depth_m, info_)) {
    error_ = reader_.writer_alive() ? "no new frame" : "SITL writer gone";
    return FrameStatus::kNoFrame;
  }
  if (colour) cv::cvtColor(frame.bgr, frame.gray, cv::COLOR_BGR2GRAY);
  frame.t_ns = info_.t_ns;
  frame.depth_t_ns = info_.t_ns;  // rendered together
  delivered_ = true;
  error_.clear();
  return FrameStatus::kFrame;
}

geometry::PinholeCamera SitlFrameSource::camera() const {
  const frame_channel::ChannelGeometry& g = reader_.geometry();
  geometry::PinholeCamera c;
  c.fx = g.fx;
  c.fy = g.fy;
  c.cx = g.cx;
  c.cy = g.cy;
  c.width = g.width;
  c.height = g.height;
  return c;
}

std::string SitlFrameSource::describe() const {
  const frame_channel::ChannelGeometry& g = reader_.geometry();
  return "sitl:" + reader_.name() + " (" + std::to_string(g.width) + "x" +
         std::to_string(g.height) + (g.channels == 3 ? " BGR" : " gray") + "-D, writer pid " +
         std::to_string(reader_.writer_pid()) + ")";
}

std::optional<frame_channel::SitlTruth> SitlFrameSource::truth() const {
  if (!delivered_ || !info_.has_truth) return std::nullopt;
  return info_.truth;
}

}  // namespace hq::sources
