#include "hq/haptics/passivity_controller.hpp"

#include <algorithm>
#include <cmath>

namespace hq::haptics {
namespace {

bool usable(const Eigen::Vector3d& F_D_n, const Eigen::Vector3d& v_D_mps, double dt_s) {
  return F_D_n.allFinite() && v_D_mps.allFinite() && std::isfinite(dt_s) && dt_s > 0.0;
}

}  // namespace

PassivityController::PassivityController(double max_damping_ns_per_m, bool enabled)
    : max_damping_ns_per_m_(max_damping_ns_per_m), enabled_(enabled) {}

Eigen::Vector3d PassivityController::apply(const Eigen::Vector3d& F_law_D_n,
                                           const Eigen::Vector3d& v_D_mps, double dt_s) {
  Eigen::Vector3d F_D_n = Eigen::Vector3d::Zero();
  if (usable(F_law_D_n, v_D_mps, dt_s)) F_D_n = F_law_D_n + damping_force(F_law_D_n, v_D_mps, dt_s);
  hold(F_D_n);
  return F_D_n;
}

Eigen::Vector3d PassivityController::damping_force(const Eigen::Vector3d& F_law_D_n,
                                                   const Eigen::Vector3d& v_D_mps, double dt_s) {
  alpha_ns_per_m_ = 0.0;
  if (!usable(F_law_D_n, v_D_mps, dt_s)) return Eigen::Vector3d::Zero();
  // The force displayed last tick was held over the interval just measured: its work is exact.
  energy_j_ -= last_F_D_n_.dot(v_D_mps) * dt_s;
  min_energy_j_ = std::min(min_energy_j_, energy_j_);
  // The new force will be held over the next interval, predicted to move at v as well.
  const double predicted_j = energy_j_ - F_law_D_n.dot(v_D_mps) * dt_s;
  const double v_squared = v_D_mps.squaredNorm();
  // Below 1e-12 (m/s)^2 the effector is at rest: no damper can dissipate, nothing flows.
  if (!enabled_ || predicted_j >= 0.0 || v_squared <= 1e-12) return Eigen::Vector3d::Zero();
  alpha_ns_per_m_ = std::min(-predicted_j / (v_squared * dt_s), max_damping_ns_per_m_);
  dissipated_j_ += alpha_ns_per_m_ * v_squared * dt_s;
  return -alpha_ns_per_m_ * v_D_mps;
}

void PassivityController::hold(const Eigen::Vector3d& F_D_n) {
  // A non-finite force never reaches the device: it holds zero then, and E must say so.
  last_F_D_n_ = F_D_n.allFinite() ? F_D_n : Eigen::Vector3d::Zero();
}

void PassivityController::reset() {
  energy_j_ = 0.0;
  min_energy_j_ = 0.0;
  dissipated_j_ = 0.0;
  alpha_ns_per_m_ = 0.0;
  last_F_D_n_.setZero();
}

}  // namespace hq::haptics
