// The small ctest variant of hq-bench-delay-campaign: 0 and 300 ms round trips, 10 s flights.
#include "hq/haptics/delay_campaign.hpp"

#include "test_support.hpp"
#include <gtest/gtest.h>

#include <cstdio>
#include <fmt/format.h>

namespace hq::haptics {
namespace {

campaign::RunResult fly(HapticsConfig config, double rtt_s, bool pc,
                        const campaign::VehicleModel& vehicle = {}) {
  config.feedback.passivity_control = pc;
  campaign::LinkModel link;
  link.round_trip_s = rtt_s;
  link.jitter_s = rtt_s > 0.0 ? 0.03 : 0.0;
  link.loss = rtt_s > 0.0 ? 0.05 : 0.0;
  const campaign::RunResult r =
      campaign::run(config, test::core_paper_R_B_C(), link, {}, vehicle, 10.0);
  fmt::print(
      "rtt {:.0f} ms pc {:d}: min E {:.4f} J, transparency {:.2f}, clearance {:.3f} m, coll {}\n",
      1e3 * rtt_s, pc, r.min_energy_j, r.transparency, r.min_clearance_m, r.collisions);
  return r;
}

TEST(DelayCampaign, ShippedLawStaysPassiveAndClearOfTheWallAt0And300Ms) {
  const HapticsConfig config = load_haptics_config("config/haptics.yaml");
  const campaign::RunResult base = fly(config, 0.0, true);
  const campaign::RunResult slow = fly(config, 0.3, true);
  for (const campaign::RunResult* r : {&base, &slow}) {
    EXPECT_GT(r->min_energy_j, -1e-3);  // measured > -1e-4 J
    EXPECT_EQ(r->collisions, 0);
    EXPECT_GT(r->min_clearance_m, 0.4);  // measured 0.70 and 0.67 m
    EXPECT_GT(r->force_rms_n, 1.0);      // the operator felt the wall
  }
  // The price of delay: 0.94 of the ideal cue at 0 ms, 0.88 at 300 ms (measured).
  EXPECT_GT(base.transparency, 0.9);
  EXPECT_GT(slow.transparency, 0.8);
}

TEST(DelayCampaign, ControllerRemovesTheEnergyAStiffDelayedCueGives) {
  // GIVEN a stiff cue that never fades and a quick vehicle, 300 ms away
  HapticsConfig config = load_haptics_config("config/haptics.yaml");
  config.feedback.velocity_stiffness_n_per_m = 200.0;
  config.feedback.damping_ns_per_m = 2.0;
  config.feedback.stale_after_s = 5.0;
  campaign::VehicleModel vehicle;
  vehicle.lag_s = 0.15;
  const campaign::RunResult off = fly(config, 0.3, false, vehicle);
  const campaign::RunResult on = fly(config, 0.3, true, vehicle);
  // THEN without the controller the port gives the hand energy (measured -22 mJ), with it the
  // deficit stays within the capped damper's reach (measured -0.1 mJ)
  EXPECT_LT(off.min_energy_j, -0.015);
  EXPECT_GT(on.min_energy_j, -0.005);
  EXPECT_EQ(on.collisions, 0);
}

}  // namespace
}  // namespace hq::haptics
