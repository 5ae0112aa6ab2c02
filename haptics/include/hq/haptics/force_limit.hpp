#pragma once
/// The device cap: the last step of the force path, after every term (law, passivity damper,
/// anything added later), so that nothing added before it can push the hand beyond the cap.

#include <Eigen/Core>

namespace hq::haptics {

/// What the device is commanded, with what the cap did to get there.
struct LimitedForce {
  Eigen::Vector3d F_D_n = Eigen::Vector3d::Zero();  ///< |F_D_n| <= max_force_n, always finite.
  bool saturated = false;  ///< The sum was longer than the cap: scaled, direction kept.
  bool finite = true;      ///< False: some term was NaN or infinite; F_D_n is zero.
};

/// Scales F_D_n down to max_force_n in magnitude, keeping its direction; a non-finite F_D_n (or
/// cap) gives zero force, flagged. Allocation-free, for the 1 kHz loop.
[[nodiscard]] LimitedForce limit_force(const Eigen::Vector3d& F_D_n, double max_force_n);

}  // namespace hq::haptics
