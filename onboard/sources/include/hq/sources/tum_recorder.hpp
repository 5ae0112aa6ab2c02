#pragma once
/// Writes frames from any FrameSource in the TUM RGB-D layout (Sturm et al., IROS 2012) so that
/// every tool of the project runs on a camera recording:
///   rgb/<t>.png (8-bit BGR), depth/<t>.png (uint16, 5000 units per metre, 0 = none),
///   rgb.txt, depth.txt, accelerometer.txt ("timestamp ax ay az", m/s^2, the sensor's axes) and
///   camera.yaml (calib/ layout: the source's undistorted intrinsics, no distortion).
/// Stamps are seconds with 6 decimals, as TUM writes them.

#include "hq/geometry/pinhole_camera.hpp"
#include "hq/recording/tum_io.hpp"
#include "hq/sources/frame_source.hpp"

#include <opencv2/core.hpp>

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>

namespace hq::sources {

class TumRecorder {
 public:
  /// Creates dir (and rgb/, depth/), the list files and camera.yaml. Throws hq::InputError if
  /// dir already holds an rgb.txt (no silent overwrite) or cannot be written.
  TumRecorder(const std::string& dir, const geometry::PinholeCamera& camera,
              const std::string& description);

  /// Writes one frame; depth beyond 13.1 m (65535 / 5000) saturates. Throws hq::InputError if a
  /// PNG cannot be written.
  void write_frame(const RgbdFrame& frame);
  /// Appends one accelerometer line.
  void write_accel(const recording::AccelSample& sample);
  /// Flushes the lists; throws hq::InputError if any write failed.
  void close();

  [[nodiscard]] std::size_t frames() const { return frames_; }
  /// "12.345678" from nanoseconds, rounded to microseconds in integers.
  static std::string stamp(std::int64_t t_ns);

 private:
  std::string dir_;
  std::ofstream rgb_, depth_, accelerometer_;
  cv::Mat depth_u16_;
  std::size_t frames_ = 0;
};

}  // namespace hq::sources
