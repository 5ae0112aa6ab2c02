#pragma once
/// Obstacle detection and repulsive velocity from one depth image, §3.1 of the core paper:
/// local minima of the depth image, a standard repulsive potential per minimum (Khatib 1986),
/// summed into v_obs, which is added to the desired velocity: v_des = v*_des + v_obs.
///
/// Frames (hq/geometry/frames.hpp): C camera (optical: z forward, x right, y down), B body FRD
/// (the core paper's Q), H horizontal (B with roll and pitch removed). All buffers are sized at
/// construction; compute() allocates nothing.

#include "hq/geometry/pinhole_camera.hpp"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace hq::config {
class StrictMap;
}

namespace hq::obstacles {

/// Capacity of ObstacleResult::points; config.max_points may not exceed it.
inline constexpr int kMaxObstaclePoints = 64;

struct ObstacleConfig {
  int cell_px = 16;                     ///< Side of the min-pool cells (pixels).
  int speckle_rank = 3;                 ///< A cell's value is its k-th smallest valid range.
  double suppression_radius_px = 48.0;  ///< Non-minimum suppression radius on the cell grid.
  /// The potential acts on the clearance d = |p| - vehicle_radius_m (surface to the vehicle's
  /// bounding sphere, propellers included), so the push grows without bound as the propellers,
  /// not the body centre, reach the surface.
  double vehicle_radius_m = 0.35;
  double influence_distance_m = 1.0;  ///< d0 (clearance): farther points exert nothing.
  /// |v_obs| saturates here; above the operator's speed envelope so that no command can push
  /// the vehicle through an obstacle it sees.
  double max_repulsive_speed_mps = 1.5;
  double gain = 0.05;  ///< eta of the potential (m^3/s): v = eta (1/d - 1/d0) / d^2.
  /// A minimum on a surface whose normal is within this angle of vertical, below the vehicle,
  /// is a support surface (the floor, a table top): it pushes only upwards, on the height
  /// above it, and only within support_influence_m, so the floor a down-looking camera always
  /// sees does not shove the vehicle sideways.
  double support_normal_max_deg = 25.0;
  double support_influence_m = 0.3;
  double min_range_m = 0.4;              ///< Sensor minimum range: nearer surfaces read invalid.
  double max_range_m = 8.0;              ///< Depth beyond this is ignored.
  double near_invalid_fraction = 0.6;    ///< Invalid fraction of the central window = hazard.
  double central_window_fraction = 0.4;  ///< Central window side / image side.
  int max_points = 16;                   ///< Nearest minima kept (<= kMaxObstaclePoints).
};

/// Reads the `obstacles:` section strictly.
void read_config(config::StrictMap& section, ObstacleConfig& out);

/// What the obstacle field and memory need of their camera: a positive image size and focal
/// length, R_B_C a rotation and p_B_C_m finite. @throws hq::InputError naming component.
void check_camera(const char* component, const geometry::PinholeCamera& camera,
                  const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m);

/// One obstacle point: a local depth minimum, or the near-range hazard.
struct ObstaclePoint {
  Eigen::Vector3d p_H_m = Eigen::Vector3d::Zero();  ///< In H, from the body origin.
  double distance_m = 0.0;                          ///< |p_H_m|.
  bool near_hazard = false;                         ///< Synthesised from invalid depth.
  bool remembered = false;  ///< From the obstacle memory, outside the current view.
};

struct ObstacleResult {
  bool valid = false;       ///< False if the image was unusable; v_obs is then zero.
  const char* reason = "";  ///< Static text when !valid.
  Eigen::Vector3d v_obs_H_mps = Eigen::Vector3d::Zero();   ///< Repulsive velocity in H.
  std::array<ObstaclePoint, kMaxObstaclePoints> points{};  ///< Nearest first.
  int count = 0;                                           ///< Valid entries in points.
  bool near_hazard = false;  ///< Central window too invalid: something is too close.
  double central_invalid_fraction = 0.0;
  /// Fraction of NaN pixels: a sensor returns 0 where it sees nothing; NaN is a corrupt frame,
  /// not evidence of a near surface.
  double nan_fraction = 0.0;
  /// Height of the body origin above the lowest near-horizontal surface seen below it (the
  /// floor), from the lower half of the image; NaN when no such surface is in view.
  double floor_height_m = std::numeric_limits<double>::quiet_NaN();
  /// This frame's clearance (ClearanceFilter's definition: |p| - vehicle_radius_m, >= 0) of
  /// the nearest obstacle point in view out to max_range_m (support surfaces excluded) or in
  /// the memory; -1 when there was none. Unfiltered: see ClearanceFilter.
  double min_clearance_m = -1.0;
};

class ObstacleField {
 public:
  /// @param R_B_C, p_B_C_m  the camera's extrinsics in the body frame.
  /// @throws hq::InputError if the camera or config are inconsistent.
  ObstacleField(const ObstacleConfig& config, const geometry::PinholeCamera& camera,
                const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m);

  /// @param depth_m  CV_32FC1, camera size, metres; 0 / NaN / out of range = no depth.
  /// @param R_H_B_from_tilt  R_HQ from the attitude estimate.
  /// @param remembered_p_H_m  obstacle points outside the view (in H from the body
  ///        origin, e.g. from hq::obstacle_memory, which keeps only points near the vehicle's
  ///        height): each stands for a column and pushes with the same law on its horizontal
  ///        offset; non-finite ones are skipped.
  [[nodiscard]] ObstacleResult compute(const cv::Mat& depth_m,
                                       const Eigen::Matrix3d& R_H_B_from_tilt,
                                       std::span<const Eigen::Vector3d> remembered_p_H_m = {});

  [[nodiscard]] const ObstacleConfig& config() const { return config_; }

  /// Take-off and landing: the floor is nearer than the sensor's minimum range and is meant to
  /// be touched, so the near-range hazard and support-surface pushes are suppressed.
  void set_ground_phase(bool ground_phase) { ground_phase_ = ground_phase; }
  [[nodiscard]] bool ground_phase() const { return ground_phase_; }

 private:
  struct Cell {
    float range_m;  // speckle_rank-th smallest valid range, or +inf
    int u;          // pixel of that range
    int v;
  };

  // The stages of compute(), in order.
  /// Each cell's speckle_rank-th smallest range into cells_.
  void min_pool(const cv::Mat& depth_m);
  /// Near-range hazard from the central window's invalid depth; false (with the reason) when
  /// the frame is mostly NaN.
  bool check_near_range(const cv::Mat& depth_m, const Eigen::Matrix3d& R_HC,
                        const Eigen::Vector3d& p_HC, ObstacleResult& result) const;
  /// The cells that are local minima within the suppression radius, nearest first.
  void find_minima();
  /// Each minimum's push: Khatib on an obstacle, upwards from a support surface.
  void push_from_minima(const cv::Mat& depth_m, const Eigen::Matrix3d& R_HC,
                        const Eigen::Vector3d& p_HC, ObstacleResult& result) const;
  /// Each remembered point's push, on its horizontal offset.
  void push_from_remembered(std::span<const Eigen::Vector3d> p_H_m, ObstacleResult& result) const;
  /// The point in C of a cell's nearest range.
  [[nodiscard]] Eigen::Vector3d cell_point_C(const Cell& cell) const;

  /// Adds the repulsive velocity of a point at p_H (Khatib: eta (1/d - 1/d0) / d^2 away).
  void add_point(ObstacleResult& result, const Eigen::Vector3d& p_H, bool hazard,
                 bool remembered = false) const;

  /// The support-surface term: upwards, Khatib on the height above it within
  /// support_influence_m; nothing in the ground phase.
  void add_support_push(ObstacleResult& result, double height_m) const;
  /// True when the minimum at pixel (u, v) lies on a near-horizontal surface below the vehicle.
  /// The floor's height below the body from the lower image half's support cells.
  [[nodiscard]] double floor_height(const cv::Mat& depth_m, const Eigen::Matrix3d& R_HC,
                                    const Eigen::Vector3d& p_HC);
  [[nodiscard]] bool on_support_surface(const cv::Mat& depth_m, int u, int v,
                                        const Eigen::Matrix3d& R_HC,
                                        const Eigen::Vector3d& p_H) const;

  ObstacleConfig config_;
  bool ground_phase_ = false;
  geometry::PinholeCamera camera_;
  Eigen::Matrix3d R_B_C_;
  Eigen::Vector3d p_B_C_m_;
  int cells_x_ = 0;
  int cells_y_ = 0;
  int radius_cells_ = 0;
  std::vector<float> ray_norm_;  // |K^-1 (u, v, 1)| per pixel: range = depth * ray_norm
  std::vector<Cell> cells_;
  std::vector<int> minima_;          // cell indices of local minima, capacity cells_
  std::vector<double> support_z_m_;  // floor candidates' heights, capacity cells_
};

}  // namespace hq::obstacles
