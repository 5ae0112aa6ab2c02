// 100 seeded, randomized approaches into a box (speed 0.3-1.0 m/s, heading, box size and place):
// the operator holds the stick forward (eqs. 6-9: along the camera heading) well past the box,
// and only the obstacle field (core paper §3.1) stands between the vehicle and the box. Zero
// collisions, and the distribution of closest distances printed.

#include "scenario.hpp"
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fmt/format.h>
#include <random>
#include <vector>

namespace hq::closed_loop {
namespace {

using testing::Scenario;

struct Approach {
  double speed_mps;
  double yaw_rad;
  double distance_m;  ///< body centre to the box's near face along the camera heading
  Eigen::Vector3d box_size_m;
  double box_yaw_rad;
};

Approach draw(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Approach a;
  a.speed_mps = 0.3 + 0.7 * u(rng);
  a.yaw_rad = 2.0 * M_PI * u(rng);
  a.distance_m = 1.6 + 1.0 * u(rng);
  a.box_size_m = Eigen::Vector3d(0.3 + 0.6 * u(rng), 0.3 + 0.6 * u(rng), 1.4 + 0.6 * u(rng));
  a.box_yaw_rad = M_PI * u(rng);
  return a;
}

TEST(ApproachCampaign, HundredRandomizedApproachesNeverTouchTheBox) {
  const sim::World room = sim::load_world("onboard/sim/worlds/room.yaml");
  std::mt19937 rng(20261125);
  std::vector<double> clearances;
  std::vector<double> closing_speeds;
  int collisions = 0;
  for (int run = 0; run < 100; ++run) {
    const Approach a = draw(rng);
    Scenario s;
    // The room's textured floor, with its furniture replaced by one box in the open.
    s.world = room;
    s.world.walls.clear();
    s.world.boxes.clear();
    s.world.cylinders.clear();
    s.world.markers.clear();
    s.world.start_N_m = Eigen::Vector3d(0.0, 0.0, 1.0);
    s.world.start_yaw_rad = a.yaw_rad;
    s.start_airborne(1.0);
    s.sim.seed = static_cast<std::uint64_t>(1000 + run);

    s.add_box_in_view(a.yaw_rad, a.distance_m, a.box_size_m, a.box_yaw_rad,
                      static_cast<std::uint32_t>(run + 17));

    // Settle 1.5 s, then push forward for long enough to travel 1.5x the distance.
    const double push_s = 1.5 * (a.distance_m + 0.5) / a.speed_mps;
    s.script.end_s = 1.5 + push_s + 1.0;
    s.step(0.0, Eigen::Vector3d::Zero(), 0.0, modes::Mode::kTeleop);
    s.step(1.5, Eigen::Vector3d(a.speed_mps, 0, 0));
    s.step(1.5 + push_s, Eigen::Vector3d::Zero());
    auto loop = s.make();
    loop->run();
    clearances.push_back(loop->min_clearance_m());
    if (loop->collision_ticks() > 0) {
      ++collisions;
      fmt::print(
          "run {} COLLIDED: speed {:.2f} m/s, yaw {:.0f} deg, box {:.2f} x {:.2f} at {:.2f} m\n",
          run, a.speed_mps, a.yaw_rad * 180 / M_PI, a.box_size_m.x(), a.box_size_m.y(),
          a.distance_m);
    }
  }
  std::vector<double> sorted = clearances;
  std::sort(sorted.begin(), sorted.end());
  const auto at = [&](double q) {
    return sorted[static_cast<std::size_t>(q * static_cast<double>(sorted.size() - 1))];
  };
  fmt::print("closest distance (surface to the 0.35 m vehicle sphere) over {} approaches:\n",
             sorted.size());
  fmt::print("  min {:.3f}  p10 {:.3f}  median {:.3f}  p90 {:.3f}  max {:.3f} m; collisions {}\n",
             at(0.0), at(0.1), at(0.5), at(0.9), at(1.0), collisions);
  EXPECT_EQ(collisions, 0);
  EXPECT_GT(at(0.0), 0.0);
  // The approach is real: the vehicle ends well inside the field's influence (1 m clearance).
  EXPECT_LT(at(1.0), 1.0);
}

}  // namespace
}  // namespace hq::closed_loop
