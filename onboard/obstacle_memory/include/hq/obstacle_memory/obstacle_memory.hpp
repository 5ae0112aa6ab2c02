#pragma once
/// Short-term obstacle memory: the core paper's obstacle field (§3.1) sees only the
/// camera's view, so an obstacle that leaves it is forgotten. Each frame's valid depth becomes a
/// cloud in the odometry origin O (the odometry's camera pose T_O_C), is
/// down-sampled on a voxel grid, cleaned of speckle, and merged into a bounded local map that
/// forgets points by age (drift of the estimate) and by distance from the vehicle. Remembered
/// points outside the current view, min-pooled into azimuth sectors of H, feed the same
/// repulsive law as the view's depth minima.
///
/// Frames (hq/geometry/frames.hpp): O odometry origin, C camera (optical), B body FRD, H
/// horizontal. The "world" of the API names below (T_O_C(), p_O_m) is O. All buffers
/// are sized at construction; update() allocates nothing.

#include "hq/geometry/pinhole_camera.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace hq::config {
class StrictMap;
}

namespace hq::obstacle_memory {

/// Capacity of MemoryUpdate::p_H_m; config.max_points may not exceed it.
inline constexpr int kMaxRememberedPoints = 16;
/// Bound of the telemetry cloud (telemetry_cloud()).
inline constexpr int kMaxTelemetryPoints = 2048;

struct MemoryConfig {
  bool enabled = true;           ///< Off: the chain neither builds nor uses the memory.
  double leaf_m = 0.1;           ///< Voxel edge of the down-sampling and of the map.
  int pixel_stride = 2;          ///< Depth is sampled every n-th pixel in u and v.
  double min_range_m = 0.4;      ///< Nearer depth is not inserted (sensor minimum).
  double max_range_m = 4.0;      ///< Farther depth is not inserted (noise grows with z^2).
  int min_neighbors = 2;         ///< Speckle: a frame voxel needs this many of its 26 neighbours.
  double max_age_s = 10.0;       ///< Points not re-observed for longer are forgotten.
  double radius_m = 4.0;         ///< Points farther from the vehicle are forgotten.
  int capacity = 20000;          ///< Map size bound (points); the oldest go first.
  double max_pose_jump_m = 0.3;  ///< A larger pose step between frames clears the map.
  double max_pose_jump_rad = 0.35;  ///< Same for rotation (YAML max_pose_jump_deg).
  double vertical_band_m = 0.5;     ///< Only points with |z_H| below this push (no floor/ceiling).
  /// Depth on a surface whose normal is within this angle of vertical (a floor, a table top) is
  /// not remembered: horizontal motion cannot hit it, and the field handles it in view.
  double support_normal_max_rad = 0.436;  ///< 25 deg (YAML support_normal_max_deg).
  int sectors = 24;    ///< Azimuth sectors of H for min-pooling remembered points.
  int max_points = 4;  ///< Nearest sector minima handed to the field.
};

/// Names a config key in a message: "onboard.yaml: memory.leaf_m" from read_config(),
/// "memory.leaf_m" by default.
using ConfigKeyName = std::function<std::string(const std::string& key)>;

/// Checks every field's range and the fields against each other; throws hq::InputError
/// "<name(key)> = <value>, expected <range>". read_config() and ObstacleMemory's constructor both
/// call it, so a config is accepted or refused alike wherever it comes from.
void validate(const MemoryConfig& config, const ConfigKeyName& name = {});

/// Reads the `memory:` section strictly, then validate()s it.
void read_config(config::StrictMap& section, MemoryConfig& out);

/// One frame's memory outcome.
struct MemoryUpdate {
  bool updated = false;     ///< False if the frame or pose was unusable (nothing inserted).
  const char* reason = "";  ///< Static text when !updated.
  bool cleared = false;     ///< A pose jump cleared the map on this frame.
  int inserted = 0;         ///< Voxels of this frame merged into the map.
  int speckle_removed = 0;  ///< Frame voxels dropped as speckle.
  int map_size = 0;         ///< Points in the map after this frame.
  /// Remembered obstacle points outside the current view, in H from the body origin, nearest
  /// first: one per azimuth sector that is a local minimum, within the influence distance.
  std::array<Eigen::Vector3d, kMaxRememberedPoints> p_H_m{};
  int count = 0;
  std::int64_t clear_count = 0;  ///< Pose-jump clears since construction.

  [[nodiscard]] std::span<const Eigen::Vector3d> remembered() const {
    return {p_H_m.data(), static_cast<std::size_t>(count)};
  }
};

class ObstacleMemory {
 public:
  /// @param R_B_C, p_B_C_m  the camera's extrinsics in the body frame.
  /// @throws hq::InputError if the camera or extrinsics are unusable or the config fails
  ///         validate().
  ObstacleMemory(const MemoryConfig& config, const geometry::PinholeCamera& camera,
                 const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m);

  /// Merges one frame and returns the remembered points for the field.
  /// @param depth_m  CV_32FC1, camera size, metres; 0 / NaN / out of range = no depth.
  /// @param T_O_C  camera pose in the odometry origin; non-finite = nothing inserted.
  /// @param R_H_B  R_HB from the attitude estimate.
  /// @param influence_distance_m  d0 of the field: farther remembered points are not returned.
  [[nodiscard]] MemoryUpdate update(std::int64_t t_ns, const cv::Mat& depth_m,
                                    const Eigen::Isometry3d& T_O_C, const Eigen::Matrix3d& R_H_B,
                                    double influence_distance_m);

  /// Forgets every point (the pose reference is kept).
  void clear();

  [[nodiscard]] int size() const { return static_cast<int>(entries_.size()); }
  [[nodiscard]] std::int64_t clear_count() const { return clear_count_; }
  /// The camera pose of the last accepted update (what the map is relative to), if any.
  [[nodiscard]] std::optional<Eigen::Isometry3d> T_O_C() const {
    return have_pose_ ? std::optional<Eigen::Isometry3d>(T_O_C_prev_) : std::nullopt;
  }
  [[nodiscard]] const MemoryConfig& config() const { return config_; }

  /// Bytes held by the map and its buffers (constant after construction).
  [[nodiscard]] std::size_t memory_bytes() const;

  /// Down-sampled map for telemetry: at most min(out.size(), kMaxTelemetryPoints) points in O,
  /// evenly strided over the map. Returns the number written. Allocates nothing.
  int telemetry_cloud(std::span<Eigen::Vector3f> p_O_m) const;

  /// Calls visit(p_O_m, t_ns) (an Eigen::Vector3f in O, when last seen) for every point of
  /// the map, e.g. for the seen-space limiter. Allocates nothing.
  template <typename Visit>
  void for_each_point(Visit&& visit) const {
    for (const MapPoint& entry : entries_) visit(entry.p_O_m, entry.t_ns);
  }

  /// Writes the map as PCD (binary) or PLY (binary) by the path's extension (.pcd / .ply),
  /// points in O (m). @throws hq::InputError naming the path if it cannot be written.
  void save(const std::string& path) const;

 private:
  struct MapPoint {
    Eigen::Vector3f p_O_m;
    std::int64_t t_ns;
    std::uint64_t key;
  };
  struct FrameVoxel {
    std::uint64_t key;
    Eigen::Vector3f sum_m;
    int n;
  };

  /// Voxel key of a point in O; false if outside the key range.
  [[nodiscard]] bool key_of(const Eigen::Vector3f& p_O_m, std::uint64_t& key) const;
  /// Slot of key in the frame table (inserting it when absent and insert is set), or -1.
  int frame_slot(std::uint64_t key, bool insert);
  /// Index into entries_ of key, or -1.
  [[nodiscard]] int map_index(std::uint64_t key) const;
  void rebuild_map_table();

  // The stages of update(), in order.
  /// A pose step beyond max_pose_jump_* clears the map; remembers T_O_C either way.
  void forget_on_pose_jump(const Eigen::Isometry3d& T_O_C, MemoryUpdate& out);
  /// This frame's valid depth, support surfaces left out, averaged per voxel of O.
  void voxelise(const cv::Mat& depth_m, const Eigen::Isometry3d& T_O_C,
                const Eigen::Matrix3d& R_H_B);
  /// Keeps the frame voxels with enough occupied neighbours; returns how many it dropped.
  int remove_speckle(std::int64_t t_ns);
  /// Drops old, far and re-observed map points; pools the rest outside the view per sector.
  void age_and_pool(std::int64_t t_ns, const cv::Mat& depth_m, const Eigen::Isometry3d& T_O_C,
                    const Eigen::Matrix3d& R_H_B, double influence_distance_m);
  /// Merges the kept frame voxels into the map; returns how many.
  int merge_frame();
  /// The sectors' local minima, nearest first, into out.
  void pick_sector_minima(MemoryUpdate& out);

  MemoryConfig config_;
  geometry::PinholeCamera camera_;
  Eigen::Matrix3d R_B_C_;
  Eigen::Vector3d p_B_C_m_;
  float inv_leaf_ = 10.0f;
  std::vector<float> ray_x_;  // per column: x / z of its rays (PinholeCamera::ray)
  std::vector<float> ray_y_;  // per row: y / z

  std::vector<FrameVoxel> frame_table_;  // open addressing, key 0 = empty
  std::vector<int> frame_used_;          // occupied slots, to reset only those
  std::vector<MapPoint> kept_voxels_;    // this frame's voxels after speckle removal
  std::vector<MapPoint> entries_;        // the map, oldest insertions first
  std::vector<int> map_table_;           // open addressing into entries_, -1 = empty
  std::vector<float> sector_distance_m_;
  std::vector<Eigen::Vector3d> sector_point_;
  std::vector<int> sector_order_;

  bool have_pose_ = false;
  Eigen::Isometry3d T_O_C_prev_ = Eigen::Isometry3d::Identity();
  std::int64_t clear_count_ = 0;
};

}  // namespace hq::obstacle_memory
