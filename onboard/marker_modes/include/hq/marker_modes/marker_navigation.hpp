#pragma once
/// The marker stage of the on-board chain: AprilTag detection on each frame, the
/// marker map built online, and the error-state filter (IMU predict, RGB-D velocity and marker
/// pose updates) whose pose the marker and explore modes fly on.
///
/// Frames: M a marker (ViSP tag frame, z out of the tag); the map frame is the first marker's
/// frame (z up for a floor tag). W is the filter's NED world: the map frame turned by Rx(pi), so
/// z points down and the floor markers lie in z = 0 (marker-EKF §IV-C: poses relative to one
/// chosen marker). H is W turned by the body yaw only (core paper §3).

#include "hq/geometry/pinhole_camera.hpp"
#include "hq/markers/marker_detector.hpp"
#include "hq/markers/marker_map.hpp"
#include "hq/navigation/navigation_filter.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

namespace hq::config {
class StrictMap;
}
namespace hq::estimator {
struct VelocityEstimate;
}

namespace hq::marker_modes {

/// The marker mode's gains and the landing sequence (section `markers: marker_mode:`).
struct MarkerModeConfig {
  int target_id = 0;               ///< Marker held, gone to or landed on.
  double hold_height_m = 1.0;      ///< Above the marker's plane.
  double kp_position_per_s = 0.8;  ///< v*_des = kp (p_target - p).
  double max_speed_mps = 0.4;
  double kp_yaw_per_s = 1.0;
  double max_yaw_rate_radps = 0.5;
  double search_yaw_rate_radps = 0.3;  ///< Turning in place while the target is not mapped.
  double face_target_beyond_m = 0.8;   ///< Going to a farther marker, the camera faces it.
  double land_align_m = 0.04;          ///< Horizontal error before the descent starts.
  double land_descent_mps = 0.25;
  /// Below this height the marker mode hands over to Mode::kLand (vertical touchdown): above
  /// the floor push of the obstacle field, which Mode::kLand switches off (ground phase).
  double land_handover_height_m = 0.6;
  // No max_marker_age_s: markers.navigation.position_max_age_s is the one limit (a file that
  // still sets it is refused, naming that key).
};

/// Exploration of a marker field (smartphone seed §III, its state machine).
struct ExploreConfig {
  double height_m = 1.0;
  double liftoff_climb_mps = 0.4;
  double liftoff_max_s = 6.0;
  double search_yaw_rate_radps = 0.3;  ///< Turning in place until the first marker.
  double cell_m = 0.6;                 ///< Coverage grid, aligned with the first marker.
  double view_distance_m = 1.4;        ///< Stand-off from a cell, camera facing it.
  double max_view_range_m = 2.6;       ///< A cell counts as seen within this range in view.
  double budget_s = 120.0;             ///< Exploration ends here at the latest.
  double goal_timeout_s = 10.0;        ///< A cell not seen within this is given up.
  double edge_timeout_s = 0.75;        ///< Seed: no marker for 750 ms near the edge.
  double edge_margin_m = 0.3;          ///< Beyond the mapped box by this: near the edge.
  double counter_steer_mps = 0.3;
  bool land_at_end = true;  ///< Navigate to the target marker and land on it.
};

struct MarkerModesConfig {
  bool enabled = false;  ///< Off: the chain runs no marker stage and registers no provider.
  /// Detector every this many frames (1 = all).
  int detect_every_frames = 1;
  double map_position_sigma_m = 0.01;  ///< Added to each marker pose's position noise.
  double map_rotation_sigma_rad = 0.01;
  markers::MarkerDetectorConfig detector;
  markers::MarkerMapConfig map;
  navigation::NavigationConfig navigation;
  MarkerModeConfig marker_mode;
  ExploreConfig explore;
};

/// Reads the chain's `markers:` section: enabled, detect_every_frames, map_position_sigma_m,
/// map_rotation_sigma_deg, and children detector (hq::markers), navigation (hq::navigation),
/// marker_mode and explore; strict, every error names the file and key.
void read_config(config::StrictMap& section, MarkerModesConfig& out);

/// "position lost (no marker for 3.2 s)" and the like, for an invalid check, in plain words
/// into `out` (hq::format_into: no allocation); "position valid" for a valid one. Returns out.
const char* describe_position(const navigation::PositionCheck& check,
                              const navigation::NavigationConfig& config, char* out,
                              std::size_t size);

/// R_W_map: the NED world from the map frame of a floor marker.
const Eigen::Matrix3d& R_W_map();

class MarkerNavigation {
 public:
  MarkerNavigation(const MarkerModesConfig& config, const geometry::PinholeCamera& camera,
                   const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m);

  /// IMU in the body frame (NED): initialises the filter level on the first sample, then predicts.
  void on_imu(std::int64_t t_ns, const Eigen::Vector3d& gyro_radps,
              const Eigen::Vector3d& accel_mps2);

  /// One frame: detection (unless hidden), the map, the velocity update from the chain's
  /// estimate, and a marker update per mapped detection. T_O_C: the odometry pose
  /// (valid only when odometry_ok).
  void on_frame(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m,
                const estimator::VelocityEstimate& estimate, bool odometry_ok,
                const Eigen::Isometry3d& T_O_C);

  /// Markers ignored (a camera fault on the detector, or a test hiding them).
  void set_markers_hidden(bool hidden) { hidden_ = hidden; }

  /// Whether the pose may be flown on at t_ns, with the reason and figures (hq::navigation).
  [[nodiscard]] navigation::PositionCheck position_check(std::int64_t t_ns) const {
    return filter_.check_position(t_ns);
  }
  /// The pose may be flown on at t_ns: position_check valid (a marker accepted within
  /// markers.navigation.position_max_age_s, the one limit on a marker's age, and the rest).
  [[nodiscard]] bool pose_usable(std::int64_t t_ns) const;
  [[nodiscard]] Eigen::Vector3d p_W_m() const { return filter_.state().p_W_m; }
  [[nodiscard]] double yaw_rad() const;
  /// Marker centre in W, if mapped.
  [[nodiscard]] std::optional<Eigen::Vector3d> p_W_M_m(int id) const;
  /// Seconds since a frame last had a detection (large before the first).
  [[nodiscard]] double time_since_detection_s(std::int64_t t_ns) const;
  /// Is p_W (a point in W) in the camera's view within range_m, at the filter's pose?
  [[nodiscard]] bool in_view(const Eigen::Vector3d& p_W_m, double range_m) const;
  /// The camera heading alpha (eq. 9): the yaw of the optical axis in the body frame.
  [[nodiscard]] double camera_heading_rad() const { return camera_heading_rad_; }

  [[nodiscard]] const navigation::NavigationFilter& filter() const { return filter_; }
  [[nodiscard]] markers::MarkerMap& map() { return map_; }
  [[nodiscard]] const markers::MarkerMap& map() const { return map_; }
  [[nodiscard]] const MarkerModesConfig& config() const { return config_; }
  [[nodiscard]] int detections_last_frame() const { return detections_last_frame_; }
  /// The markers detected in the last frame (empty when it was not searched or had none).
  [[nodiscard]] std::span<const markers::MarkerDetection> detections() const {
    return std::span<const markers::MarkerDetection>(detector_.detections())
        .first(static_cast<std::size_t>(detections_last_frame_));
  }
  /// Horizontal box (W) of the mapped markers, updated per frame; false before the first.
  bool map_box(Eigen::Vector2d& lo, Eigen::Vector2d& hi) const {
    lo = map_lo_m_;
    hi = map_hi_m_;
    return have_box_;
  }

 private:
  MarkerModesConfig config_;
  geometry::PinholeCamera camera_;
  Eigen::Isometry3d T_B_C_ = Eigen::Isometry3d::Identity();
  double camera_heading_rad_ = 0.0;
  markers::MarkerDetector detector_;
  markers::MarkerMap map_;
  navigation::NavigationFilter filter_;
  bool hidden_ = false;
  long frames_ = 0;
  bool have_detection_ = false;
  std::int64_t t_last_detection_ns_ = 0;
  int detections_last_frame_ = 0;
  bool have_box_ = false;
  Eigen::Vector2d map_lo_m_ = Eigen::Vector2d::Zero();
  Eigen::Vector2d map_hi_m_ = Eigen::Vector2d::Zero();
};

}  // namespace hq::marker_modes
