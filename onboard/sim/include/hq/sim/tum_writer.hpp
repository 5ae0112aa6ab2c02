#pragma once
/// Writes a simulator run in the TUM RGB-D benchmark layout (Sturm et al., IROS 2012):
///   rgb/<t>.png (8-bit BGR), depth/<t>.png (uint16, 5000 units per metre, 0 = invalid),
///   rgb.txt, depth.txt ("timestamp filename"), groundtruth.txt ("timestamp tx ty tz qx qy qz
///   qw", the CAMERA in the world, as TUM gives it), accelerometer.txt ("timestamp ax ay az")
///   and, beyond TUM, gyro.txt ("timestamp wx wy wz"). Timestamps are seconds with 6 decimals.
///   IMU lines are in the body NED frame Q (TUM's accelerometer.txt uses the Kinect's frame).

#include "hq/geometry/pinhole_camera.hpp"
#include "hq/sim/imu.hpp"
#include "hq/sources/tum_recorder.hpp"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <cstdint>
#include <string>

namespace hq::sim {

/// hq-sim's recording: sources::TumRecorder with ground truth and gyro, labelled 'hq-sim'.
class TumWriter {
 public:
  /// Creates dir, dir/rgb, dir/depth and the list files with TUM's comment headers, plus
  /// camera.yaml (camera_info layout with T_B_C); a recording already in dir is
  /// written over. Throws hq::InputError if it cannot.
  TumWriter(const std::string& dir, const geometry::PinholeCamera& camera,
            const Eigen::Isometry3d& T_B_C);

  /// One RGB-D frame and the camera's true pose T_N_C (N: the simulator's NWU world) at t_ns.
  /// image: CV_8UC3 BGR or CV_8UC1; depth_m: CV_32F metres.
  void write_frame(std::int64_t t_ns, const cv::Mat& image, const cv::Mat& depth_m,
                   const Eigen::Isometry3d& T_N_C);
  void write_imu(const ImuSample& sample);
  /// Flushes the list files; throws hq::InputError if any write failed.
  void close() { recorder_.close(); }

  /// "12.345678": TUM's seconds with 6 decimals from nanoseconds.
  static std::string stamp(std::int64_t t_ns) { return sources::TumRecorder::stamp(t_ns); }

 private:
  sources::TumRecorder recorder_;
};

}  // namespace hq::sim
