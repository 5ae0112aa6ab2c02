#include "hq/config/camera_info.hpp"

#include "hq/config/strict_yaml.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <sstream>

namespace hq::config {

bool CameraInfo::has_distortion() const {
  for (double d : distortion) {
    if (d != 0.0) return true;
  }
  return false;
}

geometry::PinholeCamera CameraInfo::pinhole() const {
  return geometry::PinholeCamera{fx, fy, cx, cy, width, height};
}

namespace {
// camera_info matrices are {rows, cols, data}; checks the shape against what the key needs.
void read_matrix(StrictMap& root, const std::string& key, int rows, int cols, double* out,
                 bool required) {
  if (!root.has(key)) {
    if (required) throw InputError(root.describe(key) + " is missing");
    return;
  }
  StrictMap m = root.child(key);
  int r = rows;
  int c = cols;
  m.require("rows", r, 1, 16);
  m.require("cols", c, 1, 16);
  if (r != rows || c != cols) {
    throw InputError(m.describe("rows") + " x cols = " + std::to_string(r) + "x" +
                     std::to_string(c) + ", expected " + std::to_string(rows) + "x" +
                     std::to_string(cols));
  }
  m.require_list("data", out, rows * cols);
  m.finish();
}
}  // namespace

CameraInfo load_camera_info(const std::string& path) {
  const YAML::Node node = load_yaml_file(path);
  StrictMap root(node, path);
  CameraInfo info;
  root.require("image_width", info.width, 8, 8192);
  root.require("image_height", info.height, 8, 8192);
  root.read("camera_name", info.name, {});
  double K[9];
  read_matrix(root, "camera_matrix", 3, 3, K, true);
  if (!(K[0] > 0.0) || !(K[4] > 0.0)) {
    throw InputError(root.describe("camera_matrix") + ": fx and fy must be > 0");
  }
  // Depth cameras and webcams have focal lengths of a few hundred to a few thousand pixels; a
  // value outside 10-10000 px is a typo or another unit (fx = 1e-300 passed before).
  for (const int i : {0, 4}) {
    if (!(K[i] >= kMinFocalPx && K[i] <= kMaxFocalPx)) {
      std::ostringstream message;
      message << root.describe("camera_matrix") << ": " << (i == 0 ? "fx" : "fy") << " = " << K[i]
              << ", expected in [" << kMinFocalPx << ", " << kMaxFocalPx << "] px";
      throw InputError(message.str());
    }
  }
  if (K[1] != 0.0 || K[3] != 0.0 || K[6] != 0.0 || K[7] != 0.0 || K[8] != 1.0) {
    throw InputError(root.describe("camera_matrix") +
                     ": expected [fx 0 cx; 0 fy cy; 0 0 1] (no skew)");
  }
  info.fx = K[0];
  info.fy = K[4];
  info.cx = K[2];
  info.cy = K[5];
  // Strictly inside: a principal point on the border (cx = 0) is a value left out, not a lens.
  if (!(info.cx > 0.0 && info.cx < info.width && info.cy > 0.0 && info.cy < info.height)) {
    std::ostringstream message;
    message << root.describe("camera_matrix") << ": principal point (" << info.cx << ", " << info.cy
            << "), expected 0 < cx < " << info.width << " and 0 < cy < " << info.height;
    throw InputError(message.str());
  }
  root.read("distortion_model", info.distortion_model, {"plumb_bob", "none"});
  if (root.has("distortion_coefficients")) {
    double D[5];
    read_matrix(root, "distortion_coefficients", 1, 5, D, true);
    info.distortion.assign(D, D + 5);
  } else {
    root.skip("distortion_coefficients");
  }
  if (info.distortion_model == "none") info.distortion.clear();
  // Required: TUM's PNGs hold 5000 units per metre, OpenNI2 and libfreenect millimetres (1000);
  // a default fits one and scales the other's every depth by 5 without a word.
  if (!root.has("depth_scale_units_per_m")) {
    throw InputError(root.describe("depth_scale_units_per_m") +
                     " is missing, expected the depth image's units per metre (1000 for "
                     "OpenNI2 and libfreenect millimetres, 5000 for TUM RGB-D)");
  }
  root.read_positive("depth_scale_units_per_m", info.depth_scale_units_per_m, 1e6);
  // Keys of the ROS layout that carry no extra information for a monocular camera.
  for (const char* ignored : {"rectification_matrix", "projection_matrix"}) {
    root.skip(ignored);
  }
  root.finish();
  return info;
}

Undistorter::Undistorter(const CameraInfo& camera) : identity_(!camera.has_distortion()) {
  if (identity_) return;
  const cv::Matx33d K(camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
  const cv::Mat D(camera.distortion, true);
  const cv::Size size(camera.width, camera.height);
  cv::initUndistortRectifyMap(K, D, cv::noArray(), K, size, CV_16SC2, map_x_, map_y_);
  cv::initUndistortRectifyMap(K, D, cv::noArray(), K, size, CV_32FC1, map_x_nn_, map_y_nn_);
}

void Undistorter::apply_color(const cv::Mat& src, cv::Mat& dst) const {
  if (identity_) {
    src.copyTo(dst);
    return;
  }
  cv::remap(src, dst, map_x_, map_y_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
}

void Undistorter::apply_depth(const cv::Mat& src, cv::Mat& dst) const {
  if (identity_) {
    src.copyTo(dst);
    return;
  }
  cv::remap(src, dst, map_x_nn_, map_y_nn_, cv::INTER_NEAREST, cv::BORDER_CONSTANT);
}

}  // namespace hq::config
