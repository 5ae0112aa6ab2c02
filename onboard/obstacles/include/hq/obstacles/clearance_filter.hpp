#pragma once
/// The vehicle's clearance, one definition for the state it sends (VehicleState.clearance_m),
/// its summaries, the console and hq-report: the distance from the vehicle's bounding sphere
/// (ObstacleConfig::vehicle_radius_m, propellers included) to the nearest obstacle point in the
/// current depth frame and the obstacle memory, |p| - radius, clamped at 0 (touching).
///
/// A per-frame nearest point is one bad frame away from a false figure: flying pixels at a
/// depth edge or a corrupt frame put a point 0.2 m away for a frame or two, and a flight's
/// "closest obstacle" became that (0.159 m in a report beside the summary's 0.414 m). Within a
/// frame the field already ranks each 16 px cell by its speckle_rank-th nearest pixel, so lone
/// pixels cannot make a cell near; across frames this filter reports the median of the last
/// kWindow per-frame clearances: up to (kWindow - 1) / 2 consecutive outlying frames (two at
/// kWindow 5) change nothing, and a real obstacle shows after (kWindow + 1) / 2 frames (three:
/// 100 ms at 30 Hz), while the repulsive field itself acts on every frame's raw points.
/// A frame that saw no obstacle point counts as infinitely clear. Pure, fixed size, no
/// allocation.

#include <array>
#include <cstddef>

namespace hq::obstacles {

class ClearanceFilter {
 public:
  /// Frames in the median (odd).
  static constexpr std::size_t kWindow = 5;

  /// One frame's nearest clearance (m, >= 0), or < 0 / NaN when it saw no obstacle point.
  /// Returns the filtered clearance: the median of the last kWindow frames (of those seen so
  /// far, the lower middle one, while fewer); -1 when that median saw no obstacle point.
  double update(double frame_clearance_m);
  /// The latest filtered clearance (-1: none, or no frame yet).
  [[nodiscard]] double clearance_m() const { return clearance_m_; }
  /// Forgets every frame (a new flight).
  void reset();

 private:
  std::array<double, kWindow> ring_{};
  std::size_t count_ = 0;
  std::size_t next_ = 0;
  double clearance_m_ = -1.0;
};

}  // namespace hq::obstacles
