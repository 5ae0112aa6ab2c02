#include "hq/haptics/force_limit.hpp"

#include <cmath>

namespace hq::haptics {

LimitedForce limit_force(const Eigen::Vector3d& F_D_n, double max_force_n) {
  LimitedForce out;
  if (!F_D_n.allFinite() || !std::isfinite(max_force_n) || max_force_n < 0.0) {
    out.finite = false;
    return out;
  }
  // stableNorm: a finite but huge sum (1e200 N) would overflow norm() to inf and scale to zero,
  // losing the direction the cap is meant to keep.
  const double magnitude_n = F_D_n.stableNorm();
  out.F_D_n = F_D_n;
  if (magnitude_n > max_force_n) {
    out.F_D_n *= max_force_n / magnitude_n;
    out.saturated = true;
  }
  return out;
}

}  // namespace hq::haptics
