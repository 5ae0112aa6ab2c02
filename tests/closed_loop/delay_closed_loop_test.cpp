// The small ctest variant of hq-bench-delay-closed-loop: the closed loop flown by the haptic
// loop and the operator's arm at 0 and 300 ms round trip (5 % loss, +-30 ms jitter), controller
// on. Bounds sit beside the figures measured by the bench.
#include "delayed_operator.hpp"
#include <gtest/gtest.h>

#include <cstdio>
#include <fmt/format.h>

namespace hq::closed_loop {
namespace {

TEST(DelayClosedLoop, PassiveAndCollisionFreeAt0And300MsRoundTrip) {
  const haptics::HapticsConfig config = haptics::load_haptics_config("config/haptics.yaml");
  for (const double rtt_s : {0.0, 0.3}) {
    haptics::campaign::LinkModel link;
    link.round_trip_s = rtt_s;
    link.jitter_s = rtt_s > 0.0 ? 0.03 : 0.0;
    link.loss = rtt_s > 0.0 ? 0.05 : 0.0;
    const delay::FlightResult r = delay::fly(config, link, 20.0);
    fmt::print(
        "rtt {:.0f} ms: min E {:.5f} J, |F| rms {:.2f} N, tracking {:.3f} m/s, clearance {:.3f} m, "
        "collision ticks {}, altitude {:.2f} m\n",
        1e3 * rtt_s, r.min_energy_j, r.force_rms_n, r.tracking_rms_mps, r.min_clearance_m,
        r.collision_ticks, r.max_altitude_m);
    EXPECT_GT(r.max_altitude_m, 0.5) << rtt_s;  // it took off: the run is not vacuous
    EXPECT_GT(r.force_rms_n, 0.5) << rtt_s;     // the operator felt something
    EXPECT_GT(r.min_energy_j, -1e-3) << rtt_s;
    EXPECT_EQ(r.collision_ticks, 0) << rtt_s;
  }
}

}  // namespace
}  // namespace hq::closed_loop
