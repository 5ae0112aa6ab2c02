#pragma once
/// Writes frames from any FrameSource in the TUM RGB-D layout (Sturm et al., IROS 2012) so that
/// every tool of the project runs on a camera recording:
///   rgb/<t>.png (8-bit BGR), depth/<t>.png (uint16, 5000 units per metre, 0 = none),
///   rgb.txt, depth.txt, accelerometer.txt ("timestamp ax ay az", m/s^2, the sensor's axes) and
///   camera.yaml (calib/ layout: the source's undistorted intrinsics, no distortion).
/// Stamps are seconds with 6 decimals, as TUM writes them.

#include "hq/frame_source/frame_source.hpp"
#include "hq/geometry/pinhole_camera.hpp"
#include "hq/recording/tum_io.hpp"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>

namespace hq::sources {

/// How a recording is labelled and what it holds beyond TUM's images, lists and accelerometer.
struct TumRecordingOptions {
  std::string description;                ///< Every list's "# file: '<description>'" line.
  std::string camera_name = "hq_record";  ///< camera.yaml's camera_name.
  /// Write over a recording already in dir (a simulator rerun) instead of refusing.
  bool replace_existing = false;
  bool ground_truth = false;   ///< groundtruth.txt: the camera's true pose per frame.
  bool gyro = false;           ///< gyro.txt ("timestamp wx wy wz"), beyond TUM.
  std::string accel_note;      ///< Appended to the accelerometer's file line: frame and units.
  std::string gyro_note;       ///< Likewise for gyro.txt.
  std::string camera_comment;  ///< Comment lines appended to camera.yaml (e.g. the mount).
};

class TumRecorder {
 public:
  /// Creates dir (and rgb/, depth/), the list files and camera.yaml. Throws hq::InputError if
  /// dir already holds an rgb.txt (no silent overwrite) or cannot be written.
  TumRecorder(const std::string& dir, const geometry::PinholeCamera& camera,
              const std::string& description);
  /// The same with the lists and labels of options.
  TumRecorder(const std::string& dir, const geometry::PinholeCamera& camera,
              const TumRecordingOptions& options);

  /// Writes one frame; depth beyond 13.1 m (65535 / 5000) saturates. Throws hq::InputError if a
  /// PNG cannot be written.
  void write_frame(const RgbdFrame& frame);
  /// The same from an image (CV_8UC3 BGR or CV_8UC1) and depth (CV_32F metres) taken at t_ns.
  void write_frame(std::int64_t t_ns, const cv::Mat& image, const cv::Mat& depth_m);
  /// The same with the depth map's own exposure stamp (depth.txt lists it).
  void write_frame(std::int64_t t_ns, std::int64_t depth_t_ns, const cv::Mat& image,
                   const cv::Mat& depth_m);
  /// Appends one accelerometer line.
  void write_accel(const recording::AccelSample& sample);
  /// Appends one gyro.txt line. @pre options.gyro.
  void write_gyro(std::int64_t t_ns, const Eigen::Vector3d& omega_radps);
  /// Appends the camera's pose T_G_C at t_ns to groundtruth.txt ("timestamp tx ty tz
  /// qx qy qz qw", TUM's layout). @pre options.ground_truth.
  void write_ground_truth(std::int64_t t_ns, const Eigen::Isometry3d& T_G_C);
  /// Flushes the lists; throws hq::InputError if any write failed.
  void close();

  [[nodiscard]] std::size_t frames() const { return frames_; }
  /// "12.345678" from nanoseconds, rounded to microseconds in integers.
  static std::string stamp(std::int64_t t_ns);

 private:
  std::string dir_;
  std::ofstream rgb_, depth_, accelerometer_, gyro_, groundtruth_;
  cv::Mat depth_u16_;
  std::size_t frames_ = 0;
};

}  // namespace hq::sources
