#pragma once
/// AprilTag detection and per-tag pose with ViSP (marker-EKF §IV: corners -> pose, eq. 1),
/// refined with the depth of the tag's plane where the RGB-D camera has it.
///
/// Marker frame M is ViSP's tag frame: origin at the tag centre, z out of the tag (towards a
/// viewer in front of it), x and y in the tag plane (y down the printed tag image). Covariances are
/// of the right perturbation xi = (v, omega) in M: T_camera_marker = T_hat * exp_se3(xi)
/// (hq/geometry/lie.hpp order).

#include "hq/geometry/lie.hpp"
#include "hq/geometry/pinhole_camera.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <array>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace hq::config {
class StrictMap;
}

namespace hq::markers {

/// Tag family names accepted in YAML (`family:`), as ViSP names them without `TAG_`.
const std::vector<std::string>& tag_families();

struct MarkerDetectorConfig {
  std::string family = "36h11";
  double tag_size_m = 0.2;  ///< side of the black border square.
  /// Per-id sizes that override tag_size_m: (id, size_m), ids unique.
  std::vector<std::pair<int, double>> tag_size_overrides_m;
  double quad_decimate = 1.0;  ///< AprilTag quad detection on an image downsampled by this.
  int threads = 1;
  bool refine_with_depth = true;
  /// Depth refinement only when at least this fraction of the tag's pixels has depth.
  double min_valid_depth_ratio = 0.5;
  /// Floor on the corner noise sigma used for the covariance: four corners give only two
  /// degrees of freedom of residual, so the sample estimate can be near zero by chance.
  double corner_sigma_floor_px = 0.3;
  /// Depth noise sigma_z = k z^2 (structured light, Khoshelham and Oude Elberink 2012), for
  /// weighting depth against corners in the plane refinement.
  double depth_sigma_per_m2 = 1.425e-3;
};

/// Fills `out` from a `markers:`-style section (keys: family, tag_size_m, tag_size_overrides
/// as a list of {id, size_m}, quad_decimate, threads, refine_with_depth,
/// min_valid_depth_ratio, corner_sigma_floor_px, depth_sigma_per_m2); strict, ranges checked.
void read_config(config::StrictMap& section, MarkerDetectorConfig& out);
/// Loads the `markers:` section of a YAML file. Throws hq::InputError naming file and key.
MarkerDetectorConfig load_marker_detector_config(const std::string& path);

struct MarkerDetection {
  int id = -1;
  double tag_size_m = 0.0;
  Eigen::Isometry3d T_camera_marker = Eigen::Isometry3d::Identity();
  geometry::Matrix6d covariance = geometry::Matrix6d::Identity();  ///< of xi (see top).
  std::array<Eigen::Vector2d, 4> corners_px{};                     ///< ViSP's corner order.
  double reprojection_rms_px = 0.0;  ///< of the 4 corners at the final pose.
  /// Pose refined jointly with the depth of the tag plane (else from the corners only).
  bool used_depth = false;
};

/// Outcome of one frame: ok, or the reason nothing could be detected (static text).
struct DetectionStatus {
  bool ok = true;
  const char* reason = "";
};

class MarkerDetector {
 public:
  /// Throws hq::InputError if the camera intrinsics are not positive and finite.
  MarkerDetector(const MarkerDetectorConfig& config, const geometry::PinholeCamera& camera);
  ~MarkerDetector();
  MarkerDetector(const MarkerDetector&) = delete;
  MarkerDetector& operator=(const MarkerDetector&) = delete;

  /// Detects tags in `image` (CV_8UC1 grey or CV_8UC3 BGR, the camera's size). `depth_m`:
  /// empty, or CV_32F metres of the same size registered to the image (0 or NaN = no depth).
  /// Detections are in `detections()` until the next call; on a bad input the status says why
  /// and the list is empty. The image conversion reuses its buffers after the first frame
  /// (the AprilTag library itself allocates per frame).
  DetectionStatus detect(const cv::Mat& image, const cv::Mat& depth_m = cv::Mat());

  [[nodiscard]] const std::vector<MarkerDetection>& detections() const { return detections_; }
  [[nodiscard]] const MarkerDetectorConfig& config() const { return config_; }
  /// Size of tag `id` (override or default), metres.
  [[nodiscard]] double tag_size_m(int id) const;

 private:
  bool refine_with_plane(MarkerDetection& d, const Eigen::Vector3d* p_C, int n_points) const;
  struct Impl;
  MarkerDetectorConfig config_;
  geometry::PinholeCamera camera_;
  std::unique_ptr<Impl> impl_;
  std::vector<MarkerDetection> detections_;
};

/// Reprojection of the tag corners at T_camera_marker and the 8x6 Jacobian of the pixel
/// residuals with respect to xi (right perturbation in M), for covariance and tests.
/// Returns the rms reprojection error (px) against corners_px.
double corner_reprojection(const geometry::PinholeCamera& camera,
                           const Eigen::Isometry3d& T_camera_marker, double tag_size_m,
                           const std::array<Eigen::Vector2d, 4>& corners_px,
                           Eigen::Matrix<double, 8, 6>* d_residual_d_xi);

/// Corners of a tag in M, in ViSP's corner order.
std::array<Eigen::Vector3d, 4> tag_corners_marker_m(double tag_size_m);

}  // namespace hq::markers
