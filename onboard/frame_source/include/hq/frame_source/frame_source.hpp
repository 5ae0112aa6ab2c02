#pragma once
/// Where RGB-D frames come from (recording, simulator, camera): the on-board chain's input port.
/// Header-only and owned by its consumer (the vehicle runtime), so that the flight chain links
/// no camera driver; the implementations are in hq::sources (recordings, OpenNI2, libfreenect,
/// the SITL frame channel) and hq::sim, whose namespace the interface keeps.

#include "hq/geometry/pinhole_camera.hpp"
#include "hq/recording/tum_io.hpp"

#include <opencv2/core.hpp>

#include <cstdint>
#include <optional>
#include <string>

namespace hq::sources {

/// One registered RGB-D frame, undistorted, ready for the odometry.
struct RgbdFrame {
  std::int64_t t_ns = 0;  ///< colour exposure stamp
  cv::Mat bgr;            ///< CV_8UC3
  cv::Mat gray;           ///< CV_8UC1
  cv::Mat depth_m;        ///< CV_32FC1 metres, 0 = no depth
  /// Depth exposure stamp, same clock. Cameras without a shared trigger (Kinect v1) take the
  /// two a few milliseconds apart; 0 means taken with the colour (t_ns).
  std::int64_t depth_t_ns = 0;

  [[nodiscard]] std::int64_t depth_exposure_ns() const {
    return depth_t_ns != 0 ? depth_t_ns : t_ns;
  }
};

enum class FrameStatus { kFrame, kEndOfStream, kNoFrame };

/// A source fills a caller-owned frame (buffers reused after the first call).
class FrameSource {
 public:
  virtual ~FrameSource() = default;
  /// kFrame on success; kEndOfStream when a recording is exhausted; kNoFrame when a live source
  /// has nothing (then `error` says why, e.g. a device was unplugged).
  virtual FrameStatus next(RgbdFrame& frame) = 0;
  /// Intrinsics of the frames this source delivers (after undistortion).
  [[nodiscard]] virtual geometry::PinholeCamera camera() const = 0;
  [[nodiscard]] virtual std::string describe() const = 0;
  [[nodiscard]] virtual const std::string& error() const { return error_; }
  /// The latest accelerometer sample (specific force in the sensor's own axes, m/s^2), for
  /// devices that have one (Kinect v1); nullopt otherwise or before the first sample.
  [[nodiscard]] virtual std::optional<recording::AccelSample> accelerometer() const {
    return std::nullopt;
  }

 protected:
  std::string error_;
};

}  // namespace hq::sources
