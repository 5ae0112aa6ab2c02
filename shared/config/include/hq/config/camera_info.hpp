#pragma once
/// Camera calibration files in the OpenCV/ROS camera_info layout, and undistortion with a map
/// computed once.
///
/// calib/<sensor>.yaml:
///   image_width: 640
///   image_height: 480
///   camera_name: tum_fr1
///   camera_matrix: {rows: 3, cols: 3, data: [fx, 0, cx, 0, fy, cy, 0, 0, 1]}
///   distortion_model: plumb_bob
///   distortion_coefficients: {rows: 1, cols: 5, data: [k1, k2, p1, p2, k3]}
///   depth_scale_units_per_m: 5000     # required HaptiQuad extension (1000 for millimetres)

#include "hq/base/error.hpp"
#include "hq/geometry/pinhole_camera.hpp"

#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace hq::config {

/// Focal lengths with physical sense for the cameras this system flies (a few hundred px for
/// the Xtion and Kinect): camera files and simulated cameras outside [10, 10000] px are refused.
constexpr double kMinFocalPx = 10.0;
constexpr double kMaxFocalPx = 10000.0;

struct CameraInfo {
  std::string name;
  int width = 0;
  int height = 0;
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;
  std::string distortion_model = "plumb_bob";
  std::vector<double> distortion;  ///< k1 k2 p1 p2 k3 for plumb_bob; empty or zeros = none.
  double depth_scale_units_per_m = 5000.0;  ///< a file must state it; this is for cameras in code

  [[nodiscard]] bool has_distortion() const;
  /// Intrinsics of the undistorted image (same K: undistortion keeps the camera matrix).
  [[nodiscard]] geometry::PinholeCamera pinhole() const;
};

/// Loads and validates a camera file; throws hq::InputError naming the file and the key.
CameraInfo load_camera_info(const std::string& path);

/// Removes lens distortion with remap tables computed once at construction. Colour uses
/// bilinear interpolation; depth uses nearest neighbour so no depth is invented across edges.
class Undistorter {
 public:
  explicit Undistorter(const CameraInfo& camera);
  /// True when the camera has no distortion and apply_* just copies.
  [[nodiscard]] bool is_identity() const { return identity_; }
  /// @pre image is camera.width x camera.height; dst is (re)used without reallocation.
  void apply_color(const cv::Mat& src, cv::Mat& dst) const;
  void apply_depth(const cv::Mat& src, cv::Mat& dst) const;

 private:
  bool identity_ = true;
  cv::Mat map_x_, map_y_;  // fixed-point maps for bilinear colour
  cv::Mat map_x_nn_, map_y_nn_;
};

}  // namespace hq::config
