#include "hq/haptics/passivity_observer.hpp"

#include <algorithm>
#include <cmath>

namespace hq::haptics {

void PassivityObserver::update(const Eigen::Vector3d& F_D_n, const Eigen::Vector3d& v_D_mps,
                               double dt_s) {
  if (!F_D_n.allFinite() || !v_D_mps.allFinite() || !std::isfinite(dt_s) || dt_s <= 0.0) return;
  const double absorbed_j = -F_D_n.dot(v_D_mps) * dt_s;
  energy_j_ += absorbed_j;
  if (absorbed_j < 0.0) injected_j_ -= absorbed_j;
  min_energy_j_ = std::min(min_energy_j_, energy_j_);
}

void PassivityObserver::reset() {
  energy_j_ = 0.0;
  min_energy_j_ = 0.0;
  injected_j_ = 0.0;
}

}  // namespace hq::haptics
