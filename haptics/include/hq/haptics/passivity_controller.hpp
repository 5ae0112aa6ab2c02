#pragma once
/// Time-domain passivity control (Hannaford & Ryu 2002; Ryu, Kwon & Hannaford 2004): a
/// passivity observer on the port where the force law meets the operator's hand, and a passivity
/// controller, a variable damper, that dissipates whatever energy that port would otherwise give
/// the hand.
///
/// The port: force F on the hand and the end effector's velocity v, in D. Beyond it lie the link
/// (whose round trip the velocity-error cue carries), the vehicle and the force saturation (which
/// scales the centring spring in time): each can make the port active. Its energy, with the
/// observer's sign (positive: absorbed from the operator),
///   E(n) = -sum_k F_k . v_k dt_k,
/// must stay >= 0 for the port to be passive: the hand never gets back more than it put in.
///
/// Each tick, with the velocity v(n) of the interval just measured:
///   E(n)  = E(n-1) - F(n-1) . v(n) dt     (exact: F(n-1) was held over that interval),
///   E_obs = E(n) - F_law(n) . v(n) dt     (predicted for the next interval at the same v),
///   alpha = -E_obs / (|v|^2 dt) if E_obs < 0, else 0, capped at max_damping,
///   F(n)  = F_law(n) - alpha v(n),
/// so the displayed force dissipates exactly the deficit. The cap keeps the damper renderable
/// (a discrete damper is stable below 2 m / dt); a deficit it cannot remove in one tick is carried
/// to the next, as is the prediction's error (one tick's change of velocity, measured in the
/// tests).
///
/// Why this and not wave variables (Niemeyer & Slotine): the cue is computed on the ground from
/// a delayed state and the vehicle follows a velocity command (no force pushes it), so the only
/// physical energy port is the device. The controller acts only when the observer sees the port
/// give energy, so the cue is untouched at no delay and whenever the loop is passive anyway;
/// wave variables filter every cue at every delay and need the vehicle to send waves back.
///
/// Allocation-free, lock-free, no clock: data and time in, force out (for the 1 kHz loop).

#include <Eigen/Core>

namespace hq::haptics {

class PassivityController {
 public:
  /// @param max_damping_ns_per_m  cap on alpha (> 0); @param enabled  false observes only.
  PassivityController(double max_damping_ns_per_m, bool enabled);

  /// One tick: F_law_D_n the force the law asks for, v_D_mps the effector's velocity over the
  /// last interval dt_s. Returns the force to display (F - alpha v) and holds it: for callers
  /// that display exactly that force. Non-finite input returns zero force (held as such) and
  /// leaves E unchanged.
  Eigen::Vector3d apply(const Eigen::Vector3d& F_law_D_n, const Eigen::Vector3d& v_D_mps,
                        double dt_s);

  /// The first half of apply() for a loop that caps the force after the damper: updates E with
  /// the force held over the last interval and returns the damper's term -alpha v alone (zero on
  /// non-finite input, E then unchanged). Follow it with hold() of the force displayed.
  Eigen::Vector3d damping_force(const Eigen::Vector3d& F_law_D_n, const Eigen::Vector3d& v_D_mps,
                                double dt_s);
  /// The force the device displays this tick (after the cap, which may scale the damper's term
  /// down): held over the next interval, so next tick's E is the work actually done. A deficit
  /// the capped damper could not remove is carried to the next tick, as the cap on alpha is.
  void hold(const Eigen::Vector3d& F_D_n);

  /// E of the port in joules (positive: absorbed from the operator).
  [[nodiscard]] double energy_j() const { return energy_j_; }
  /// min over t of E.
  [[nodiscard]] double min_energy_j() const { return min_energy_j_; }
  /// Energy the controller's damper was asked to dissipate (the price of passivity, in joules);
  /// less when the device cap scaled its term down.
  [[nodiscard]] double dissipated_j() const { return dissipated_j_; }
  /// alpha of the last tick, N s/m.
  [[nodiscard]] double damping_ns_per_m() const { return alpha_ns_per_m_; }
  [[nodiscard]] bool enabled() const { return enabled_; }
  void reset();

 private:
  double max_damping_ns_per_m_;
  bool enabled_;
  double energy_j_ = 0.0;
  double min_energy_j_ = 0.0;
  double dissipated_j_ = 0.0;
  double alpha_ns_per_m_ = 0.0;
  Eigen::Vector3d last_F_D_n_ = Eigen::Vector3d::Zero();
};

}  // namespace hq::haptics
