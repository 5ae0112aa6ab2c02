#pragma once
/// Passivity observer at the device port (Ryu, Hannaford et al. 2002, "Time domain passivity
/// control of haptic interfaces").
///
/// Sign convention: F_D_n is the force the device applies to the hand and v_D_mps the end
/// effector's velocity, both in D. The power flowing from the operator into the teleoperation
/// system (device, mapping, feedback, link and vehicle) is -F.v, so
///   E(t) = -sum_k F_k . v_k dt_k
/// is the energy the system has absorbed. Starting at rest it is passive iff E(t) >= 0 for all t;
/// a negative E is energy the loop injected into the operator's hand. A conservative centring
/// spring stores and returns energy (E returns to 0 at rest), damping makes E grow.

#include <Eigen/Core>

namespace hq::haptics {

class PassivityObserver {
 public:
  /// Adds one sample period: force on the hand held over dt_s while the effector moved at v.
  void update(const Eigen::Vector3d& F_D_n, const Eigen::Vector3d& v_D_mps, double dt_s);

  /// E(t) in joules (positive: absorbed from the operator).
  [[nodiscard]] double energy_j() const { return energy_j_; }
  /// min over t of E(t): how much energy the loop has injected at worst.
  [[nodiscard]] double min_energy_j() const { return min_energy_j_; }
  /// Total energy the system gave out over all samples where -F.v < 0 (for reports).
  [[nodiscard]] double injected_j() const { return injected_j_; }

  void reset();

 private:
  double energy_j_ = 0.0;
  double min_energy_j_ = 0.0;
  double injected_j_ = 0.0;
};

}  // namespace hq::haptics
