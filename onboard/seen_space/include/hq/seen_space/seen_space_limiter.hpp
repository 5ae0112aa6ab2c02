#pragma once
/// No motion into unseen space: the operator's horizontal command is limited, per
/// direction in H, to the speed from which the vehicle can stop within the space it has seen.
/// The idea is PX4's collision prevention (a horizontal bin histogram of free distances, bins
/// without data refuse motion: CP_GO_NO_DATA = 0); the obstacle field (§3.1 of the core paper)
/// only knows what the camera sees now, so a command 45 deg off the camera axis flies blind.
///
/// "Seen": a bin of azimuth (config.bins around the vertical, world-fixed) holds the free
/// distance known in that direction, from the body origin, horizontally:
///  - from the current depth frame: every sampled pixel becomes a point in H; a point within
///    +-vertical_band_m of the vehicle's height is an obstacle at its horizontal range; a point
///    above or below the band proves the ray free until it left the band. A bin the camera
///    covers gets the nearest obstacle, else the farthest proven-free range (<= max_range_m);
///    a covered bin with too few valid pixels (0, NaN, nearer than min_range_m) and no obstacle
///    is no data (near surfaces read invalid on RGB-D sensors).
///  - kept from earlier frames: bins turn with the vehicle's yaw (the odometry pose), and a
///    bin's distance shrinks by the horizontal distance travelled since (the distance to what
///    was seen cannot shrink faster); a bin not seen for max_age_s goes back to no data. A
///    frame without a pose (tracking lost) breaks the chain of poses: the yaw turned meanwhile
///    is unknown, so every kept bin is forgotten when the pose comes back.
///  - from the obstacle memory (onboard/obstacle_memory): every remembered point in the band
///    bounds its bin's distance, whether that bin is otherwise seen or not; points last seen
///    before a tracking loss are not trusted (their place relative to the vehicle is not).
///
/// Braking model: with reaction time t_r (frame latency, the velocity loop's lag) and
/// deceleration a, a vehicle at speed v needs v t_r + v^2 / (2 a) to stop; with the free
/// distance d minus vehicle_radius_m and margin_m that gives
///   v_max(d) = a (-t_r + sqrt(t_r^2 + 2 (d - radius - margin) / a)).
/// When the current velocity estimate is known, the reaction distance is flown at the
/// vehicle's own speed towards the bin, v_par (as PX4 does): v_max = sqrt(2 a (d - radius -
/// margin - v_par t_r)), so a vehicle faster than its command (the loop lags) gets a lower
/// command, and the velocity loop brakes harder.
/// A bin holding an obstacle (a surface in the band, or a remembered point) at angle theta from
/// the command direction (|theta| < 90 deg) limits the command's component towards it:
/// |v| cos(theta) <= v_max(d) (PX4 projects the same way, so sliding along a wall stays
/// possible). Within no_data_half_angle_deg of the command, a bin with no data allows
/// creep_speed_mps only, and a bin seen free only up to d (no surface) allows
/// max(creep, v_max(d)): beyond d nothing is known.
///
/// Vertical: not limited here; the obstacle field's support push keeps the vehicle off the
/// floor and the modes' land handles touchdown (docs/flight-safety.md).
///
/// Pure core: data and time in, limit out; buffers are fixed arrays, nothing allocates.
/// Frames (hq/geometry/frames.hpp): O the odometry origin (the obstacle memory's world), C camera
/// (optical), B body FRD (the core paper's Q), H horizontal (z down).

#include "hq/geometry/pinhole_camera.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <optional>

namespace hq::config {
class StrictMap;
}

namespace hq::seen_space {

/// Capacity of the histogram; config.bins may not exceed it.
inline constexpr int kMaxBins = 120;

struct SeenSpaceConfig {
  bool enabled = true;       ///< Off: commands pass unchanged (to compare).
  int bins = 72;             ///< Azimuth bins over 360 deg (72: 5 deg, as PX4).
  int pixel_stride = 4;      ///< Depth sampled every n-th pixel in u and v.
  double min_range_m = 0.4;  ///< Nearer depth is invalid (sensor minimum).
  double max_range_m = 4.0;  ///< Free space is never claimed farther than this.
  /// Points within this height of the body origin are obstacles (vehicle_radius plus a little:
  /// lower or higher surfaces cannot touch the sphere in horizontal motion).
  double vertical_band_m = 0.45;
  double min_valid_fraction = 0.3;  ///< Of a covered bin's sampled pixels, else no data.
  double max_age_s = 5.0;           ///< A bin not seen again for longer is no data.
  double max_pose_jump_m = 0.3;     ///< A larger step between frames forgets every bin.
  double margin_m = 0.2;            ///< Kept beyond the vehicle radius.
  double brake_accel_mps2 = 1.5;    ///< Deceleration the braking model assumes.
  double reaction_s = 0.35;         ///< Frame latency plus the velocity loop's lag.
  /// Speed allowed towards a direction with no data. PX4's CP_GO_NO_DATA = 0 refuses it; we
  /// keep 0: a creep into space nobody has seen is what hits the wall 45 deg off the camera.
  double creep_speed_mps = 0.0;
  /// Bins with no data this near the command direction limit it to the creep speed: the
  /// vehicle's sphere at 2 m subtends +-10 deg.
  double no_data_half_angle_deg = 10.0;
};

/// Reads the `seen_space:` section strictly (every key above, with range checks).
void read_config(config::StrictMap& section, SeenSpaceConfig& out);

/// One bin: the free distance in its direction, or no data.
struct Bin {
  bool seen = false;
  float free_m = 0.0f;  ///< Horizontal free distance from the body origin (when seen).
  /// free_m ends at a surface; otherwise it is where the evidence of free space ends (rays
  /// that left the band, max range), which says nothing about what lies beyond.
  bool obstacle = false;
  std::int64_t t_seen_ns = 0;  ///< Last frame that covered it.
};

/// What the frame update did.
struct SeenSpaceUpdate {
  bool updated = false;     ///< A pose and depth were used.
  const char* reason = "";  ///< Static text when !updated.
  int covered_bins = 0;     ///< Bins the current frame covered with data.
  int seen_bins = 0;        ///< Bins with data after the update (view, kept and memory).
};

/// The command after the limit, and why.
struct LimitedCommand {
  Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();  ///< As flown (z unchanged).
  bool limited = false;                               ///< The horizontal speed was reduced.
  bool unseen = false;                                ///< ... by a bin with no data (creep).
  double v_max_mps = 0.0;  ///< Allowed horizontal speed in the command's direction.
};

class SeenSpaceLimiter {
 public:
  /// @param R_B_C, p_B_C_m  extrinsics R_B_C, p_B_C (the paper's R_QC, Q_p_C).
  /// @param vehicle_radius_m  the obstacle field's bounding sphere (obstacles.vehicle_radius_m).
  /// @throws hq::InputError if config or camera are inconsistent.
  SeenSpaceLimiter(const SeenSpaceConfig& config, const geometry::PinholeCamera& camera,
                   const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m,
                   double vehicle_radius_m);

  /// Ages the bins, turns and shrinks them with the pose change, and writes the bins this
  /// depth frame covers. Without a pose (tracking lost) only ageing happens.
  /// @param depth_m  CV_32FC1 camera-sized, metres; 0 / NaN / out of range = no depth.
  /// @param T_O_C  the odometry pose of the camera; null = not tracking.
  /// @param R_H_B  from the attitude estimate (the paper's R_HQ).
  SeenSpaceUpdate update(std::int64_t t_ns, const cv::Mat& depth_m, const Eigen::Isometry3d* T_O_C,
                         const Eigen::Matrix3d& R_H_B);

  /// After update(): a remembered obstacle point in O (the memory's map), last seen at
  /// t_seen_ns, bounds its bin. Points outside the vertical band or beyond max_range_m, and
  /// points seen before the last tracking loss, are ignored.
  void add_remembered_point(const Eigen::Vector3f& p_O_m, std::int64_t t_seen_ns);

  /// Limits the horizontal part of a command in H (current heading). Non-finite input gives
  /// zero. v_est_H_mps, when there is an estimate (and it is finite), is the vehicle's velocity
  /// now (H): the reaction distance uses it. Allocates nothing.
  [[nodiscard]] LimitedCommand limit(
      const Eigen::Vector3d& v_H_mps,
      const std::optional<Eigen::Vector3d>& v_est_H_mps = std::nullopt) const;

  /// Braking model: the largest speed that stops within free distance free_m.
  [[nodiscard]] double max_speed_mps(double free_m) const;
  /// The same with the reaction distance flown at v_now_mps (>= 0) towards the obstacle.
  [[nodiscard]] double max_speed_mps(double free_m, double v_now_mps) const;

  /// Bin b's free distance including remembered points, or a negative value for no data.
  /// obstacle (optional) tells whether that distance ends at a surface.
  [[nodiscard]] double free_distance_m(int b, bool* obstacle = nullptr) const;
  /// The bin an azimuth in H (rad, NED: clockwise from the heading) falls in now.
  [[nodiscard]] int bin_of_heading_azimuth(double azimuth_H_rad) const;
  /// Per-bin speed limits in H order (bin 0 = along the current heading, clockwise), m/s;
  /// creep_speed_mps where there is no data. Writes min(out.size(), bins) values.
  void heading_limits(std::array<float, kMaxBins>& out_mps) const;
  [[nodiscard]] int bins() const { return config_.bins; }
  [[nodiscard]] const SeenSpaceConfig& config() const { return config_; }
  /// Heading of H in the histogram's fixed frame (rad).
  [[nodiscard]] double yaw_rad() const { return yaw_rad_; }

 private:
  [[nodiscard]] int bin_of_fixed_azimuth(double azimuth_rad) const;
  /// This frame's nearest obstacle, free distance and pixel counts per bin (the frame_ scratch)
  /// from every pixel_stride-th depth pixel; R_HC rotates camera rays into H, o_H is the camera
  /// centre from the body origin in H.
  void scan_depth(const cv::Mat& depth_m, const Eigen::Matrix3d& R_HC, const Eigen::Vector3d& o_H);

  SeenSpaceConfig config_;
  geometry::PinholeCamera camera_;
  Eigen::Matrix3d R_B_C_;
  Eigen::Vector3d p_B_C_m_;
  double vehicle_radius_m_;
  double bin_width_rad_;
  std::array<Bin, kMaxBins> bins_{};
  std::array<float, kMaxBins> memory_m_{};  ///< Nearest remembered point per bin, this frame.
  // Per-frame scratch, fixed size.
  std::array<float, kMaxBins> frame_obstacle_m_{};
  std::array<float, kMaxBins> frame_free_m_{};
  std::array<int, kMaxBins> frame_valid_{};
  std::array<int, kMaxBins> frame_total_{};

  bool have_pose_ = false;
  bool pose_chain_broken_ = false;    ///< An update without a pose since the last one with.
  std::int64_t t_pose_since_ns_ = 0;  ///< First pose after the last tracking loss.
  Eigen::Matrix3d R_H_O_prev_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_O_B_prev_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R_H_O_ = Eigen::Matrix3d::Identity();  ///< Of the last update with a pose.
  Eigen::Vector3d p_O_B_ = Eigen::Vector3d::Zero();
  double yaw_rad_ = 0.0;  ///< Heading of H in the fixed frame of the bins.
  std::int64_t t_now_ns_ = 0;
};

}  // namespace hq::seen_space
