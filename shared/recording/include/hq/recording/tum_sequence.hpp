#pragma once
/// A TUM RGB-D sequence directory: associated colour/depth frames, optional ground truth and
/// accelerometer samples, and PNG loading into caller-owned images.

#include "hq/recording/tum_io.hpp"

#include <opencv2/core.hpp>

#include <cstddef>
#include <string>
#include <vector>

namespace hq::recording {

class TumSequence {
 public:
  /// Reads dir/rgb.txt and dir/depth.txt (required), dir/groundtruth.txt and
  /// dir/accelerometer.txt (optional), associates frames within max_dt_s, and decodes frame 0
  /// to learn the sequence's image size. Throws hq::InputError naming the offending file.
  explicit TumSequence(const std::string& dir, double max_dt_s = 0.02);

  const std::string& directory() const;
  /// Number of associated colour/depth frames (at least 1).
  std::size_t size() const;
  /// @pre i < size(); throws std::out_of_range otherwise.
  const RgbdFrameFiles& frame(std::size_t i) const;

  bool has_ground_truth() const;
  /// T_G_C of the sequence (empty without groundtruth.txt).
  const std::vector<StampedPose>& ground_truth() const;
  bool has_accelerometer() const;
  /// Accelerometer samples (empty without accelerometer.txt).
  const std::vector<AccelSample>& accelerometer() const;
  /// Size of every frame, as decoded from frame 0.
  cv::Size image_size() const;

  /// Loads frame i into caller-owned images whose buffers are reused when already of the right
  /// size and type: bgr CV_8UC3, depth_u16 CV_16UC1 (raw units, 0 = no data). Throws
  /// hq::InputError naming the file for a missing, unreadable or corrupt PNG, a depth image that
  /// is not 16-bit single-channel, a colour image that is not 8-bit 3-channel, or a size that
  /// differs between colour and depth or from frame 0. @pre i < size().
  void load(std::size_t i, cv::Mat& bgr, cv::Mat& depth_u16) const;

 private:
  std::string directory_;
  std::vector<RgbdFrameFiles> frames_;
  std::vector<StampedPose> ground_truth_;
  std::vector<AccelSample> accelerometer_;
  cv::Size image_size_;
};

/// depth_u16 / units_per_m as CV_32FC1 metres into a reused depth_m; 0 (no data) stays 0.
/// TUM depth uses 5000 units per metre. Throws hq::InputError unless depth_u16 is CV_16UC1 and
/// units_per_m is finite and > 0.
void depth_to_metres(const cv::Mat& depth_u16, double units_per_m, cv::Mat& depth_m);

}  // namespace hq::recording
