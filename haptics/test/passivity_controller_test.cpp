#include "hq/haptics/passivity_controller.hpp"

#include "hq/testing/allocation_counter.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <deque>
#include <fmt/format.h>

namespace hq::haptics {
namespace {

// A hand on the device (mass, grip damping, an arm spring to its rest point) coupled to a stiff
// spring rendered from the effector's position as it was one delay ago: the force the operator
// feels when a remote side closes a stiff coupling over a slow link. The delayed spring lags the
// motion and pushes energy into the oscillation; a passive port could not.
struct DelayedCouplingRun {
  double min_energy_j = 0.0;      // the port's E as the controller keeps it
  double min_exact_j = 0.0;       // E from the force held times the displacement actually made
  double late_amplitude_m = 0.0;  // max |p| over the last second
  double dissipated_j = 0.0;
};

DelayedCouplingRun run_delayed_coupling(double delay_s, bool control) {
  constexpr double kDt = 1e-3;
  constexpr double kMassKg = 0.5;
  constexpr double kArmStiffness = 100.0;
  constexpr double kArmDamping = 1.0;
  constexpr double kCouplingStiffness = 150.0;
  PassivityController controller(200.0, control);
  const auto delay_ticks = static_cast<std::size_t>(std::lround(delay_s / kDt));
  std::deque<double> history(delay_ticks + 1, 0.0);
  double p = 0.02;  // released from 2 cm
  double v = 0.0;
  double previous_p = p;
  double exact_j = 0.0;
  double held_force = 0.0;
  DelayedCouplingRun run;
  const int ticks = 6000;
  for (int k = 0; k < ticks; ++k) {
    history.push_back(p);
    const double p_delayed = history.front();
    history.pop_front();
    const double v_step = (p - previous_p) / kDt;
    exact_j -= held_force * (p - previous_p);
    run.min_exact_j = std::min(run.min_exact_j, exact_j);
    const Eigen::Vector3d F = controller.apply(
        Eigen::Vector3d(-kCouplingStiffness * p_delayed, 0, 0), Eigen::Vector3d(v_step, 0, 0), kDt);
    held_force = F.x();
    previous_p = p;
    // Semi-implicit Euler on the hand.
    const double a = (held_force - kArmStiffness * p - kArmDamping * v) / kMassKg;
    v += a * kDt;
    p += v * kDt;
    if (k >= ticks - 1000) run.late_amplitude_m = std::max(run.late_amplitude_m, std::abs(p));
  }
  run.min_energy_j = controller.min_energy_j();
  run.dissipated_j = controller.dissipated_j();
  return run;
}

TEST(PassivityController, DelayedStiffCouplingGainsEnergyWithoutController) {
  // GIVEN a stiff coupling closed over 100 ms, WHEN nothing controls the port
  const DelayedCouplingRun run = run_delayed_coupling(0.1, false);
  fmt::print("no PC, 100 ms: min E {:.3g} J, exact {:.3g} J, late amplitude {:.3g} m\n",
             run.min_energy_j, run.min_exact_j, run.late_amplitude_m);
  // THEN the port gives the hand energy and the oscillation grows past its 2 cm start
  EXPECT_LT(run.min_exact_j, -0.05);
  EXPECT_GT(run.late_amplitude_m, 0.02);
}

TEST(PassivityController, ControllerKeepsThePortPassiveAndStopsTheOscillation) {
  for (const double delay_s : {0.05, 0.1, 0.3, 0.6}) {
    // GIVEN the same coupling, WHEN the controller damps the port
    const DelayedCouplingRun run = run_delayed_coupling(delay_s, true);
    fmt::print(
        "PC, {:.0f} ms: min E {:.5f} J, exact {:.5f} J, late amplitude {:.5f} m, dissipated {:.4f} "
        "J\n",
        1e3 * delay_s, run.min_energy_j, run.min_exact_j, run.late_amplitude_m, run.dissipated_j);
    // THEN E stays above -10 mJ, 2 % of what the damper dissipates (measured at worst -5 mJ
    // at 300 ms: the velocity held over a tick is not the one the damper was sized with) ...
    EXPECT_GT(run.min_energy_j, -0.01) << delay_s;
    EXPECT_GT(run.min_exact_j, -0.01) << delay_s;
    // ... and the hand comes to rest instead of oscillating
    EXPECT_LT(run.late_amplitude_m, 0.005) << delay_s;
  }
}

TEST(PassivityController, LeavesAPassiveCueAlmostUntouched) {
  // A spring rendered without delay stores energy on the way out and returns it on the way back.
  // Held for a tick, the sampled spring returns a little more than it stored (the zero-order
  // hold's own activity): only that is dissipated, 0.2 % of the 0.125 J stored.
  PassivityController controller(200.0, true);
  double p = 0.0;
  for (int k = 0; k < 2000; ++k) {
    const double v = k < 1000 ? 0.05 : -0.05;
    p += v * 1e-3;
    const Eigen::Vector3d F_cue(-100.0 * p, 0, 0);
    const Eigen::Vector3d F = controller.apply(F_cue, Eigen::Vector3d(v, 0, 0), 1e-3);
    if (k < 1000) {
      EXPECT_EQ(F, F_cue) << k;  // storing: untouched
    }
  }
  EXPECT_LT(controller.dissipated_j(), 0.01 * 0.125);
  EXPECT_GT(controller.min_energy_j(), -1e-6);
}

TEST(PassivityController, DampingIsCappedAndNonFiniteInputGivesZero) {
  PassivityController controller(10.0, true);
  // A cue pushing along the motion: active from the first tick.
  const Eigen::Vector3d F = controller.apply({5.0, 0, 0}, {0.01, 0, 0}, 1e-3);
  EXPECT_DOUBLE_EQ(controller.damping_ns_per_m(), 10.0);
  EXPECT_NEAR(F.x(), 5.0 - 10.0 * 0.01, 1e-12);
  const double energy_j = controller.energy_j();
  EXPECT_EQ(controller.apply({NAN, 0, 0}, {0.01, 0, 0}, 1e-3), Eigen::Vector3d::Zero());
  EXPECT_EQ(controller.apply({1, 0, 0}, {0.01, 0, 0}, 0.0), Eigen::Vector3d::Zero());
  EXPECT_EQ(controller.energy_j(), energy_j);
}

// GIVEN the damper's term asked for alone and the force actually displayed held afterwards (a
// loop that caps the force last), THEN E counts the work of the displayed force, not of the
// force asked for: the next tick's E uses what the hand really got.
TEST(PassivityController, HoldOfTheCappedForceKeepsTheEnergyExact) {
  PassivityController split(60.0, true);
  const Eigen::Vector3d F_law(8.0, 0, 0);
  const Eigen::Vector3d v(0.3, 0, 0);  // pushed along its motion: active, the damper acts
  const Eigen::Vector3d F_damper = split.damping_force(F_law, v, 1e-3);
  ASSERT_LT(F_damper.x(), 0.0);
  const Eigen::Vector3d F_displayed(-2.0, 0, 0);  // what a cap let through
  split.hold(F_displayed);
  const double energy_j = split.energy_j();
  (void)split.damping_force(F_law, v, 1e-3);
  EXPECT_NEAR(split.energy_j() - energy_j, -F_displayed.dot(v) * 1e-3, 1e-15);

  PassivityController whole(60.0, true);
  EXPECT_TRUE(whole.apply(F_law, v, 1e-3).isApprox(F_law + F_damper, 1e-15));
}

TEST(PassivityController, ApplyAllocatesNothing) {
  PassivityController controller(60.0, true);
  const long before = testing::allocation_count();
  double sum = 0.0;
  for (int k = 0; k < 1000; ++k) {
    sum += controller.apply({std::sin(k * 0.01), 0, 0}, {std::cos(k * 0.01), 0, 0}, 1e-3).x();
  }
  EXPECT_EQ(testing::allocation_count() - before, 0);
  EXPECT_TRUE(std::isfinite(sum));
}

}  // namespace
}  // namespace hq::haptics
