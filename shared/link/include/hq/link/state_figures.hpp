#pragma once
// Figures derived from a VehicleState that more than one reader needs (the CSV recorder's
// closest_obstacle_m, the console's replay row): one definition, so they cannot disagree.

#include "hq/link/messages.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hq::link {

/// Distance from the body origin to the closest point of the state's down-sampled obstacle
/// cloud (m); NaN when the state carries no cloud.
inline double closest_cloud_point_m(const VehicleState& s) {
  double best_sq = std::numeric_limits<double>::infinity();
  for (std::uint32_t i = 0; i < s.obstacle_points_B_m._length; ++i) {
    const hq_msgs_Vector3f& p = s.obstacle_points_B_m._buffer[i];
    const auto x = static_cast<double>(p.x);
    const auto y = static_cast<double>(p.y);
    const auto z = static_cast<double>(p.z);
    best_sq = std::min(best_sq, x * x + y * y + z * z);
  }
  return std::isfinite(best_sq) ? std::sqrt(best_sq) : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace hq::link
