#pragma once
/// Marker map: poses T_map_marker of fiducial markers in one map frame, built online from the
/// detections of each frame and the odometry between frames, and optimised as a pose graph
/// (marker-EKF §IV-C: a map is a set of marker poses relative to one chosen marker).
///
/// Nodes: every marker, and every keyframe camera (a frame with detections). Edges: camera ->
/// marker from each detection (co-visible markers are tied through their shared camera), and
/// camera -> camera from the odometry accumulated between keyframes. Ceres, quaternion manifold
/// plus translation, Huber loss on the whitened residuals, gauge fixed on the first marker.

#include "hq/geometry/lie.hpp"
#include "hq/markers/marker_detector.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace hq::markers {

struct MarkerMapConfig {
  /// Huber threshold on the whitened residual norm (units of sigma).
  double huber_sigma = 2.0;
  /// Incremental optimisation: every this many keyframes, at most this many iterations.
  int optimise_every_keyframes = 10;
  int incremental_iterations = 5;
  int full_iterations = 100;
  /// A frame with detections becomes a keyframe only after the camera moved this far (or a
  /// new marker appears), which bounds the graph while hovering.
  double keyframe_min_translation_m = 0.05;
  double keyframe_min_rotation_rad = 0.05;
  /// Floors on the detection standard deviations (the reprojection covariance of a sharp
  /// simulated tag can be unrealistically small): position m, rotation rad.
  double detection_sigma_floor_m = 0.002;
  double detection_sigma_floor_rad = 0.002;
};

/// One optimisation's outcome.
struct MapOptimisation {
  int iterations = 0;
  double initial_cost = 0.0;
  double final_cost = 0.0;
  bool converged = false;
};

class MarkerMap {
 public:
  explicit MarkerMap(const MarkerMapConfig& config = MarkerMapConfig{});
  ~MarkerMap();
  MarkerMap(MarkerMap&&) noexcept;
  MarkerMap& operator=(MarkerMap&&) noexcept;
  MarkerMap(const MarkerMap&) = delete;
  MarkerMap& operator=(const MarkerMap&) = delete;

  /// One camera frame: its detections and the odometry pose of the camera T_O_C with
  /// the covariance of the motion since the previous frame (right perturbation, (v, omega)).
  /// The first marker ever seen defines the map frame. New markers are placed by chaining
  /// (through a known marker of the same frame, else through odometry); every
  /// optimise_every_keyframes keyframes a bounded optimisation runs. Throws hq::InputError on a
  /// non-finite pose or covariance.
  void add_frame(std::int64_t t_ns, const std::vector<MarkerDetection>& detections,
                 const Eigen::Isometry3d& T_O_C, const geometry::Matrix6d& motion_covariance);

  /// Full optimisation (up to `max_iterations`, config.full_iterations if <= 0).
  MapOptimisation optimise(int max_iterations = 0);

  [[nodiscard]] bool contains(int id) const;
  /// T_map_marker of a mapped marker, nullopt if unknown.
  [[nodiscard]] std::optional<Eigen::Isometry3d> T_map_marker(int id) const;
  /// Mapped marker ids in the order they were first seen (the first is the gauge).
  [[nodiscard]] std::vector<int> ids() const;
  [[nodiscard]] int keyframes() const;
  /// Pose of the camera at the last keyframe in the map frame.
  [[nodiscard]] std::optional<Eigen::Isometry3d> T_map_camera_last() const;

  /// Writes `markers: [{id, p_map_marker_m: [x, y, z], q_map_marker_xyzw: [x, y, z, w]}]`.
  /// Throws hq::InputError if the file cannot be written.
  void save(const std::string& path) const;
  /// Reads a saved map (strict: unknown keys, missing keys, non-finite or non-unit quaternions,
  /// duplicate ids are hq::InputError naming the file and key). Markers keep their poses as
  /// initial values; the first one is the gauge.
  static MarkerMap load(const std::string& path, const MarkerMapConfig& config = MarkerMapConfig{});

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hq::markers
