#include "hq/sources/tum_frame_source.hpp"

#include <opencv2/imgproc.hpp>

namespace hq::sources {

TumFrameSource::TumFrameSource(const std::string& sequence_dir, const config::CameraInfo& camera)
    : sequence_(sequence_dir), camera_(camera), undistorter_(camera) {
  const cv::Size size = sequence_.image_size();
  if (size.width != camera.width || size.height != camera.height) {
    throw InputError(sequence_dir + ": images are " + std::to_string(size.width) + "x" +
                     std::to_string(size.height) + " but the camera file says " +
                     std::to_string(camera.width) + "x" + std::to_string(camera.height));
  }
}

FrameStatus TumFrameSource::next(RgbdFrame& frame) {
  if (next_index_ >= sequence_.size()) return FrameStatus::kEndOfStream;
  const std::size_t i = next_index_++;
  sequence_.load(i, raw_bgr_, raw_depth_u16_);
  recording::depth_to_metres(raw_depth_u16_, camera_.depth_scale_units_per_m, raw_depth_m_);
  undistorter_.apply_color(raw_bgr_, frame.bgr);
  undistorter_.apply_depth(raw_depth_m_, frame.depth_m);
  cv::cvtColor(frame.bgr, frame.gray, cv::COLOR_BGR2GRAY);
  frame.t_ns = sequence_.frame(i).t_ns;
  frame.depth_t_ns = sequence_.frame(i).depth_t_ns;
  return FrameStatus::kFrame;
}

geometry::PinholeCamera TumFrameSource::camera() const { return camera_.pinhole(); }

std::string TumFrameSource::describe() const {
  return "TUM sequence " + sequence_.directory() + " (" + std::to_string(sequence_.size()) +
         " frames)";
}

}  // namespace hq::sources
