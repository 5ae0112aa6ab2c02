// Marker mode in the simulated closed loop: hold over a marker after a bumpless switch
// from velocity-only flight, markers hidden for 5 s (bounded drift, then recovery), zero
// collisions. Figures printed; the seed (marker-EKF) holds to a few centimetres.

#include "hq/marker_modes/marker_providers.hpp"

#include "scenario.hpp"
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fmt/format.h>
#include <vector>

namespace hq::marker_modes {
namespace {

constexpr const char* kScript = "onboard/closed_loop/flights/marker_hover.yaml";

struct Window {
  double rms_m = 0.0;
  double max_m = 0.0;
  double height_rms_m = 0.0;
};

/// Horizontal error of the truth position against the target marker's truth centre, and the
/// height error against the hold height, sampled every 0.1 s over [t0, t1).
Window hold_window(test::Flight& f, int id, double hold_height_m, double t0_s, double t1_s) {
  const Eigen::Vector3d target = f.marker_truth_m(id);
  double sum = 0.0;
  double sum_h = 0.0;
  Window w;
  int n = 0;
  for (double t = t0_s; t < t1_s; t += 0.1) {
    f.loop->run_until(t);
    const Eigen::Vector3d p = f.p_truth_m();
    const double e = (p - target).head<2>().norm();
    sum += e * e;
    sum_h += (p.z() - target.z() - hold_height_m) * (p.z() - target.z() - hold_height_m);
    w.max_m = std::max(w.max_m, e);
    ++n;
  }
  w.rms_m = std::sqrt(sum / n);
  w.height_rms_m = std::sqrt(sum_h / n);
  return w;
}

TEST(MarkerHover, HoldsOverTheMarkerAndRecoversAfterMarkersHidden) {
  test::Flight f = test::make_flight(kScript, 3);
  const MarkerModeConfig& mc = f.stage().marker_mode().config();
  const int id = mc.target_id;
  f.loop->run_until(15.0);
  ASSERT_TRUE(f.stage().navigation().map().contains(id)) << "target marker never mapped";
  ASSERT_EQ(f.loop->chain().mode(), modes::Mode::kMarker);
  const Window hold = hold_window(f, id, mc.hold_height_m, 15.0, 25.0);

  // Markers hidden 5 s: the filter flies on IMU + RGB-D velocity, its covariance growing.
  f.stage().navigation().set_markers_hidden(true);
  const Window hidden = hold_window(f, id, mc.hold_height_m, 25.0, 30.0);
  const double sigma_hidden_m = f.stage().navigation().filter().health().position_sigma_m;
  f.stage().navigation().set_markers_hidden(false);
  f.loop->run_until(34.0);
  const Window recovered = hold_window(f, id, mc.hold_height_m, 34.0, 40.0);

  fmt::print("marker hover over id {} (320x240, seed 3)\n", id);
  fmt::print("  hold 15-25 s          horizontal rms {:.3f} m, max {:.3f} m, height rms {:.3f} m\n",
             hold.rms_m, hold.max_m, hold.height_rms_m);
  fmt::print(
      "  markers hidden 25-30 s horizontal rms {:.3f} m, max {:.3f} m (filter sigma {:.3f} m)\n",
      hidden.rms_m, hidden.max_m, sigma_hidden_m);
  fmt::print("  recovered 34-40 s     horizontal rms {:.3f} m, max {:.3f} m\n", recovered.rms_m,
             recovered.max_m);
  fmt::print("  collision ticks {}, min clearance {:.2f} m\n", f.loop->collision_ticks(),
             f.loop->min_clearance_m());
  EXPECT_LT(hold.rms_m, 0.05);
  EXPECT_LT(hold.height_rms_m, 0.05);
  EXPECT_LT(hidden.max_m, 0.30) << "drift without markers not bounded";
  EXPECT_LT(recovered.rms_m, 0.05);
  EXPECT_EQ(f.loop->collision_ticks(), 0);
}

}  // namespace
}  // namespace hq::marker_modes
