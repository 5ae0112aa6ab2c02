// No motion into unseen space: seeded random in-envelope operator commands (every
// direction about the vehicle, 45 deg off the camera included, speeds up to the link's 2 m/s,
// with random yaw rates) in every world with obstacles, flown by the real chain against the
// simulator in lock-step. With the seen-space limiter (config/onboard.yaml seen_space) no run
// touches anything and none flies away. The issue's own case, 1.0 and 1.5 m/s along H-x in the
// arena (45 deg off the camera), is flown as well.
//
// Before/after: `hq_unseen_campaign_test --gtest_also_run_disabled_tests
// --gtest_filter='*Disabled*'` flies the same campaign with seen_space.enabled false.

#include "scenario.hpp"
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fmt/format.h>
#include <random>
#include <string>
#include <vector>

namespace hq::closed_loop {
namespace {

using testing::Scenario;

struct WorldRow {
  std::string world;
  int runs = 0;
  int collided_runs = 0;
  int collision_ticks = 0;
  int fly_aways = 0;
  double min_clearance_m = 1e9;
  double max_true_speed_mps = 0.0;
  double max_command_mps = 0.0;  ///< The fastest horizontal speed the operator asked for.
  double max_flown_m = 0.0;      ///< Largest horizontal distance from the start: it did move.
  /// The inertial coast's horizontal velocity error against the truth, over every frame flown
  /// on it: a figure that moves smoothly where collisions are rare events.
  int coast_frames = 0;
  double coast_error_sq_sum = 0.0;
  double max_coast_error_mps = 0.0;
  [[nodiscard]] double coast_rms_mps() const {
    return coast_frames > 0 ? std::sqrt(coast_error_sq_sum / coast_frames) : 0.0;
  }
  /// The estimator's roll and pitch against the truth's, on the coast (they level its
  /// acceleration: 1 deg off is 0.17 m/s^2) and on the frames tracked.
  double coast_tilt_error_sq_sum_rad2 = 0.0;
  int tracked_frames = 0;
  double tracked_tilt_error_sq_sum_rad2 = 0.0;
  [[nodiscard]] double coast_tilt_rms_deg() const {
    return coast_frames > 0 ? std::sqrt(coast_tilt_error_sq_sum_rad2 / coast_frames) * 180.0 / M_PI
                            : 0.0;
  }
  [[nodiscard]] double tracked_tilt_rms_deg() const {
    return tracked_frames > 0
               ? std::sqrt(tracked_tilt_error_sq_sum_rad2 / tracked_frames) * 180.0 / M_PI
               : 0.0;
  }
};

constexpr int kSegments = 4;
// The campaign's worlds, in order; each flies its own seeds, kFirstWorldSeed + 100 x its index.
constexpr std::array<const char*, 4> kWorlds = {"arena", "room", "nostructure_texture",
                                                "structure_notexture"};
constexpr std::uint32_t kFirstWorldSeed = 1600;
constexpr std::uint32_t kSeedStepPerWorld = 100;
constexpr double kSegmentS = 2.5;
constexpr double kSettleS = 1.5;

/// The default odometry, or the depth term with what this campaign showed it needs.
enum class Odometry { kDefault, kDepthTermWithItsGuards };

/// One run: settle, then kSegments random commands about the camera heading, then zero.
WorldRow fly(const std::string& world_path, int runs, bool limiter, std::uint32_t seed,
             Odometry odometry = Odometry::kDefault) {
  const sim::World world = sim::load_world(world_path);
  WorldRow row;
  row.world = world.name;
  // Inside the walls: the largest |x| and |y| of their centres.
  Eigen::Vector2d inside_m = Eigen::Vector2d::Zero();
  for (const sim::Rectangle& w : world.walls) {
    inside_m = inside_m.cwiseMax(w.center_m.head<2>().cwiseAbs());
  }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int run = 0; run < runs; ++run) {
    Scenario s;
    s.world = world;
    s.world.start_yaw_rad = 2.0 * M_PI * u(rng);
    s.start_airborne(1.0);
    s.sim.seed = seed + static_cast<std::uint64_t>(run);
    s.onboard.seen_space.enabled = limiter;
    if (odometry == Odometry::kDepthTermWithItsGuards) {
      s.onboard.odometry.use_depth_term = true;
      s.onboard.odometry.depth_jacobian_from_normals = true;
      s.onboard.odometry.min_translation_information_ratio = 0.01;
      s.onboard.odometry.degenerate_step_ratio = 0.01;
      // HQ_UNSEEN_REMAP=0: the depth-term runs without remapped steps (docs/odometry.md,
      // "Depth-term options").
      if (const char* r = std::getenv("HQ_UNSEEN_REMAP"))
        s.onboard.odometry.degenerate_step_ratio = std::atof(r);
    }
    // HQ_UNSEEN_CREEP=0.15: the same campaign with a creep speed towards no data.
    if (const char* c = std::getenv("HQ_UNSEEN_CREEP"))
      s.onboard.seen_space.creep_speed_mps = std::atof(c);
    s.script.end_s = kSettleS + kSegments * kSegmentS + 1.0;
    s.step(0.0, Eigen::Vector3d::Zero(), 0.0, modes::Mode::kTeleop);
    for (int k = 0; k < kSegments; ++k) {
      // Half the segments anywhere about the vehicle, half towards the camera's view (so
      // the vehicle does fly at walls); speeds up to the link envelope.
      const double angle_rad =
          u(rng) < 0.5 ? 2.0 * M_PI * u(rng) : (u(rng) - 0.5) * 70.0 * M_PI / 180.0;
      const double speed_mps = 0.3 + 1.7 * u(rng);
      row.max_command_mps = std::max(row.max_command_mps, speed_mps);
      const double yaw_rate_radps = u(rng) < 0.5 ? 0.0 : (u(rng) - 0.5) * 2.0;
      s.step(kSettleS + k * kSegmentS,
             Eigen::Vector3d(speed_mps * std::cos(angle_rad), speed_mps * std::sin(angle_rad), 0.0),
             yaw_rate_radps);
    }
    s.step(kSettleS + kSegments * kSegmentS, Eigen::Vector3d::Zero(), 0.0);
    auto loop = s.make();
    loop->run();
    ++row.runs;
    row.collision_ticks += loop->collision_ticks();
    if (loop->collision_ticks() > 0) ++row.collided_runs;
    row.min_clearance_m = std::min(row.min_clearance_m, loop->min_clearance_m());
    const Eigen::Vector3d p0 = loop->samples().front().p_N_m;
    bool away = false;
    for (const FlightSample& f : loop->samples()) {
      const double tilt_error_sq_rad2 =
          (f.roll_pitch_est_rad - f.roll_pitch_true_rad).squaredNorm();
      if (f.frame && f.airborne && !f.estimate_ok && !f.safe_hover) {
        const double error_mps = (f.v_est_mps - f.v_true_mps).head<2>().norm();
        ++row.coast_frames;
        row.coast_error_sq_sum += error_mps * error_mps;
        row.max_coast_error_mps = std::max(row.max_coast_error_mps, error_mps);
        row.coast_tilt_error_sq_sum_rad2 += tilt_error_sq_rad2;
      }
      if (f.frame && f.airborne && f.estimate_ok) {
        ++row.tracked_frames;
        row.tracked_tilt_error_sq_sum_rad2 += tilt_error_sq_rad2;
      }
      row.max_true_speed_mps = std::max(row.max_true_speed_mps, f.v_true_mps.head<2>().norm());
      row.max_flown_m = std::max(row.max_flown_m, (f.p_N_m - p0).head<2>().norm());
      // Fly-away: faster than the envelope allows, or out of the world.
      if (f.v_true_mps.head<2>().norm() > 2.5 || std::abs(f.p_N_m.x()) > inside_m.x() ||
          std::abs(f.p_N_m.y()) > inside_m.y()) {
        away = true;
      }
    }
    if (away) ++row.fly_aways;
    if (std::getenv("HQ_UNSEEN_DEBUG") != nullptr && (loop->collision_ticks() > 0 || away)) {
      fmt::print("{} run {} {} (yaw {:.0f} deg)\n", world.name, run,
                 away ? "flew away" : "collided", s.world.start_yaw_rad * 180 / M_PI);
      for (const OperatorStep& st : s.script.steps) {
        fmt::print("  step t {:.1f} v {:.2f} {:.2f} yaw {:.2f}\n", st.t_s, st.v_mps->x(),
                   st.v_mps->y(), st.yaw_rate_radps.value_or(0.0));
      }
      for (const FlightSample& f : loop->samples()) {
        if (!f.frame) continue;
        fmt::print(
            "  t {:.2f} ok {:d} sh {:d} clr {:.2f} p {:.2f} {:.2f} vtrue {:.2f} {:.2f} vest {:.2f} "
            "{:.2f} v* {:.2f} {:.2f} vobs {:.2f} {:.2f} tilt err deg {:.2f} {:.2f}\n",
            f.t_s, f.estimate_ok, f.safe_hover, f.clearance_m, f.p_N_m.x(), f.p_N_m.y(),
            f.v_true_mps.x(), f.v_true_mps.y(), f.v_est_mps.x(), f.v_est_mps.y(),
            f.v_star_des_mps.x(), f.v_star_des_mps.y(), f.v_obs_mps.x(), f.v_obs_mps.y(),
            (f.roll_pitch_est_rad.x() - f.roll_pitch_true_rad.x()) * 180.0 / M_PI,
            (f.roll_pitch_est_rad.y() - f.roll_pitch_true_rad.y()) * 180.0 / M_PI);
      }
    }
  }
  return row;
}

int runs_from_environment(int runs) {
  const char* n = std::getenv("HQ_UNSEEN_RUNS");
  return n != nullptr ? std::max(1, std::atoi(n)) : runs;
}

std::uint32_t seed_from_environment(std::uint32_t seed) {
  const char* s = std::getenv("HQ_UNSEEN_SEED");
  return s != nullptr ? static_cast<std::uint32_t>(std::strtoul(s, nullptr, 10)) : seed;
}

std::vector<WorldRow> campaign(bool limiter, int runs_per_world) {
  // HQ_UNSEEN_RUNS=N flies more runs per world and HQ_UNSEEN_SEED=S other ones (the figures
  // in docs/flight-safety.md, docs/odometry.md and docs/estimator.md); the test keeps it short.
  runs_per_world = runs_from_environment(runs_per_world);
  std::vector<WorldRow> rows;
  std::uint32_t seed = seed_from_environment(kFirstWorldSeed);
  const char* only = std::getenv("HQ_UNSEEN_WORLD");
  // Each world keeps its seed when HQ_UNSEEN_WORLD flies it alone.
  for (const char* w : kWorlds) {
    const std::uint32_t world_seed = seed;
    seed += kSeedStepPerWorld;
    if (only != nullptr && std::string(only) != w) continue;
    rows.push_back(
        fly(std::string("onboard/sim/worlds/") + w + ".yaml", runs_per_world, limiter, world_seed));
  }
  fmt::print("random in-envelope commands, seen_space {}:\n", limiter ? "on" : "off");
  fmt::print(
      "| world | runs | runs collided | collision ticks | fly-aways | min clearance m | max true "
      "speed m/s | farthest from start m | coast frames | coast error RMS / max m/s | tilt error "
      "RMS deg, coast / tracked |\n| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | "
      "---: | ---: |\n");
  for (const WorldRow& r : rows) {
    fmt::print(
        "| {} | {} | {} | {} | {} | {:.2f} | {:.2f} | {:.2f} | {} | {:.3f} / {:.2f} | {:.2f} / "
        "{:.2f} |\n",
        r.world, r.runs, r.collided_runs, r.collision_ticks, r.fly_aways, r.min_clearance_m,
        r.max_true_speed_mps, r.max_flown_m, r.coast_frames, r.coast_rms_mps(),
        r.max_coast_error_mps, r.coast_tilt_rms_deg(), r.tracked_tilt_rms_deg());
  }
  return rows;
}

TEST(UnseenCampaign, RandomInEnvelopeCommandsNeverCollideNorFlyAway) {
  for (const WorldRow& r : campaign(true, 4)) {
    EXPECT_EQ(r.collision_ticks, 0) << r.world;
    EXPECT_EQ(r.fly_aways, 0) << r.world;
    EXPECT_GT(r.min_clearance_m, 0.0) << r.world;
    EXPECT_LT(r.max_true_speed_mps, 2.5) << r.world;
  }
}

// The depth term in the world that flew it off (docs/odometry.md, "The depth term stays off"):
// beside a plain wall its gradient Jacobian claimed the motion along the wall, and the vehicle
// reached 3.8-5.9 m/s. With normals, the ratio bound, the coast's hold, a coast no longer than what
// it knows of its accelerometer and remapped steps, these four runs do not fly away; flown wider
// (HQ_UNSEEN_RUNS=16, ten seeds) 10 of 160 still collide and 2 fly away (docs/odometry.md,
// "The depth term stays off"), which is why the depth term is not the default and this test asserts
// no fly-away, not no collision. Same seeds as the campaign's structure_notexture.
TEST(UnseenCampaign, DepthTermWithItsGuardsNeverFliesAway) {
  const WorldRow r = fly("onboard/sim/worlds/structure_notexture.yaml", runs_from_environment(4),
                         true, seed_from_environment(kFirstWorldSeed) + 3 * kSeedStepPerWorld,
                         Odometry::kDepthTermWithItsGuards);
  fmt::print(
      "structure_notexture, depth term with its guards: {} of {} runs collided, {} fly-aways, min "
      "clearance {:.2f} m, max true speed {:.2f} m/s (asked up to {:.2f}), coast error RMS {:.3f} "
      "m/s over {} frames\n",
      r.collided_runs, r.runs, r.fly_aways, r.min_clearance_m, r.max_true_speed_mps,
      r.max_command_mps, r.coast_rms_mps(), r.coast_frames);
  EXPECT_EQ(r.fly_aways, 0);
  // Never faster than the operator asked (it flew off at 3.8-5.9 m/s). Measured 0.95 m/s; on
  // the way to the fused velocity's final form one run flew the 1.17 m/s it was asked where
  // the view allowed, which the old bound of 1 m/s (set with the lagging 1-euro velocity)
  // called a fly-away: the bound is what was asked.
  EXPECT_LT(r.max_true_speed_mps, r.max_command_mps + 0.1);
}

// The same campaign without the limiter: the figure the issue's closing note compares with.
TEST(UnseenCampaign, DISABLED_WithoutTheLimiterForComparison) { campaign(false, 4); }

/// The issue's case: hold v along H-x (45 deg off the camera axis) in the arena.
std::unique_ptr<ClosedLoop> along_h_x(double speed_mps, bool limiter) {
  Scenario s;
  s.world = sim::load_world("onboard/sim/worlds/arena.yaml");
  s.start_airborne(1.0);
  s.onboard.seen_space.enabled = limiter;
  s.script.frame = CommandFrame::kHorizontal;
  s.script.end_s = 10.0;
  s.step(0.0, Eigen::Vector3d::Zero(), 0.0, modes::Mode::kTeleop);
  s.step(1.0, Eigen::Vector3d(speed_mps, 0.0, 0.0));
  auto loop = s.make();
  loop->run();
  return loop;
}

TEST(UnseenCampaign, IssueCaseAlongHxInTheArenaDoesNotCollide) {
  for (double speed : {1.0, 1.5}) {
    const auto loop = along_h_x(speed, true);
    double max_speed = 0.0;
    for (const FlightSample& f : loop->samples()) {
      max_speed = std::max(max_speed, f.v_true_mps.head<2>().norm());
    }
    fmt::print(
        "H-x at {:.1f} m/s, seen_space on: collision ticks {}, min clearance {:.2f} m, max true "
        "speed {:.2f} m/s\n",
        speed, loop->collision_ticks(), loop->min_clearance_m(), max_speed);
    EXPECT_EQ(loop->collision_ticks(), 0) << speed;
    EXPECT_GT(loop->min_clearance_m(), 0.0) << speed;
    // Unseen direction, creep 0: the command is refused, the vehicle holds.
    EXPECT_LT(max_speed, 0.5) << speed;
  }
}

TEST(UnseenCampaign, DISABLED_IssueCaseWithoutTheLimiter) {
  for (double speed : {1.0, 1.5}) {
    const auto loop = along_h_x(speed, false);
    double max_speed = 0.0;
    for (const FlightSample& f : loop->samples()) {
      max_speed = std::max(max_speed, f.v_true_mps.head<2>().norm());
    }
    fmt::print(
        "H-x at {:.1f} m/s, seen_space off: collision ticks {}, min clearance {:.2f} m, max true "
        "speed {:.2f} m/s\n",
        speed, loop->collision_ticks(), loop->min_clearance_m(), max_speed);
  }
}

}  // namespace
}  // namespace hq::closed_loop
