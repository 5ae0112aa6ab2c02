// The closed loop in simulation: hover, step responses and camera faults flown by the real
// on-board chain (odometry, estimator, obstacles, modes, PID) against the simulator's truth.
// Bounds are set from measured runs (figures printed) with margin for other seeds.

#include "hq/closed_loop/flight_summary.hpp"
#include "hq/testing/input_error.hpp"

#include "scenario.hpp"
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fmt/format.h>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

namespace hq::closed_loop {
namespace {

using ::testing::HasSubstr;
using testing::Scenario;
using Vec = Eigen::Vector3d;

constexpr modes::Mode kTeleop = modes::Mode::kTeleop;

/// Take off from the room's start to about 1 m, then hold still.
Scenario room_takeoff(double end_s) {
  Scenario s;
  s.world = sim::load_world("onboard/sim/worlds/room.yaml");
  s.sim.seed = 5;
  s.script.end_s = end_s;
  s.step(0.0, Vec::Zero(), 0.0, kTeleop);
  s.step(1.0, Vec(0, 0, -0.4));
  s.step(3.5, Vec::Zero());
  return s;
}

const FlightSample& sample_at(const ClosedLoop& loop, double t_s) {
  const auto& samples = loop.samples();
  const auto it = std::lower_bound(samples.begin(), samples.end(), t_s,
                                   [](const FlightSample& s, double t) { return s.t_s < t; });
  return it == samples.end() ? samples.back() : *it;
}

TEST(ClosedLoop, HoversThirtySecondsWithSmallEstimateErrorAndDrift) {
  Scenario s = room_takeoff(36.0);
  auto loop = s.make();
  loop->run_until(6.0);
  const Vec p_start = loop->simulator().truth().T_N_B.translation();
  loop->run();
  const Vec p_end = loop->simulator().truth().T_N_B.translation();

  Vec sum_sq = Vec::Zero();
  int n = 0;
  for (const FlightSample& x : loop->samples()) {
    if (x.t_s < 6.0 || !x.frame) continue;
    ASSERT_TRUE(x.airborne) << "t = " << x.t_s;
    ASSERT_TRUE(x.estimate_ok) << "t = " << x.t_s << ": " << x.reason;
    sum_sq += (x.v_est_mps - x.v_true_mps).cwiseAbs2();
    ++n;
  }
  ASSERT_GT(n, 850);
  const Vec rmse = (sum_sq / n).cwiseSqrt();
  const double drift_m = (p_end - p_start).head<2>().norm();
  const double climb_m = std::abs(p_end.z() - p_start.z());
  fmt::print(
      "hover 30 s: velocity RMSE x {:.4f} y {:.4f} z {:.4f} m/s, drift {:.3f} m horizontal, {:.3f} "
      "m vertical\n",
      rmse.x(), rmse.y(), rmse.z(), drift_m, climb_m);
  // Measured at seed 5: about 0.01 m/s per axis and a few centimetres of drift.
  EXPECT_LT(rmse.x(), 0.03);
  EXPECT_LT(rmse.y(), 0.03);
  EXPECT_LT(rmse.z(), 0.03);
  EXPECT_LT(drift_m, 0.30);
  EXPECT_LT(climb_m, 0.20);
  EXPECT_EQ(loop->collision_ticks(), 0);
}

/// Velocity estimate RMSE (per axis) and horizontal drift of a take-off and hover in `world`
/// from 6 s on, and whether anything touched the vehicle.
struct HoverFigures {
  Vec rmse_mps = Vec::Zero();
  double drift_m = 0.0;
  double available = 0.0;
  int collision_ticks = 0;
};

HoverFigures hover_in(const std::string& world, double end_s) {
  Scenario s = room_takeoff(end_s);
  s.world = sim::load_world(world);
  auto loop = s.make();
  loop->run_until(6.0);
  const Vec p_start = loop->simulator().truth().T_N_B.translation();
  loop->run();
  HoverFigures f;
  f.drift_m = (loop->simulator().truth().T_N_B.translation() - p_start).head<2>().norm();
  Vec sum_sq = Vec::Zero();
  int frames = 0;
  int with_estimate = 0;
  for (const FlightSample& x : loop->samples()) {
    if (x.t_s < 6.0 || !x.frame) continue;
    ++frames;
    if (!x.estimate_ok) continue;
    ++with_estimate;
    sum_sq += (x.v_est_mps - x.v_true_mps).cwiseAbs2();
  }
  f.rmse_mps = (sum_sq / std::max(with_estimate, 1)).cwiseSqrt();
  f.available = static_cast<double>(with_estimate) / std::max(frames, 1);
  f.collision_ticks = loop->collision_ticks();
  return f;
}

TEST(ClosedLoop, HoversAsStillWithPeopleWalkingThroughTheViewAsWithout) {
  // GIVEN the same take-off and hover in the room, alone and with two people walking through
  // the camera's view (people.yaml: the room and them)
  const HoverFigures alone = hover_in("onboard/sim/worlds/room.yaml", 26.0);
  const HoverFigures people = hover_in("onboard/sim/worlds/people.yaml", 26.0);
  fmt::print(
      "hover 20 s alone: velocity RMSE {:.4f} {:.4f} {:.4f} m/s, drift {:.3f} m, {:.1f} % "
      "estimated\nwith people:      velocity RMSE {:.4f} {:.4f} {:.4f} m/s, drift {:.3f} m, {:.1f} "
      "% estimated\n",
      alone.rmse_mps.x(), alone.rmse_mps.y(), alone.rmse_mps.z(), alone.drift_m,
      100.0 * alone.available, people.rmse_mps.x(), people.rmse_mps.y(), people.rmse_mps.z(),
      people.drift_m, 100.0 * people.available);
  // THEN nothing touches the vehicle, and the people cost its velocity estimate at most a
  // fifth (the goal: 1.2x) and 0.3 mm/s: measured 1.14x (1.8x with
  // Kerl's fixed-point scale of the robust weights)
  EXPECT_EQ(alone.collision_ticks, 0);
  EXPECT_EQ(people.collision_ticks, 0);
  EXPECT_GT(people.available, 0.98);
  for (int axis = 0; axis < 3; ++axis) {
    EXPECT_LT(people.rmse_mps[axis], 1.2 * alone.rmse_mps[axis] + 0.0003) << "axis " << axis;
  }
  EXPECT_LT(people.drift_m, 0.30);
}

// How far the attitude filter's gyro bias (whole, body axes) is from the simulated IMU's
// after a take-off and a hover, rad/s.
double gyro_bias_error_after_a_hover(bool from_odometry) {
  Scenario s = room_takeoff(20.0);
  s.onboard.estimator.gyro_bias_from_odometry = from_odometry;
  auto loop = s.make();
  loop->run();
  const Vec error = loop->chain().estimator().attitude().gyro_bias_radps() -
                    loop->simulator().imu().gyro_bias_radps();
  fmt::print(
      "gyro bias after 20 s, {}: error {:.5f} {:.5f} {:.5f} rad/s (truth {:.5f} {:.5f} {:.5f})\n",
      from_odometry ? "with the odometry's" : "levelling alone", error.x(), error.y(), error.z(),
      loop->simulator().imu().gyro_bias_radps().x(), loop->simulator().imu().gyro_bias_radps().y(),
      loop->simulator().imu().gyro_bias_radps().z());
  return error.norm();
}

TEST(ClosedLoop, GyroBiasTheOdometryMeasuresReachesTheAttitude) {
  // GIVEN the simulated IMU's gyro bias (about 0.005 rad/s per axis, sim.yaml)
  // WHEN the vehicle takes off and hovers, the odometry tracking
  const double with_odometry = gyro_bias_error_after_a_hover(true);
  const double levelling_alone = gyro_bias_error_after_a_hover(false);
  // THEN the attitude filter knows the bias (yaw too, which the accelerometer cannot see)
  // far better than its levelling alone learns it
  EXPECT_LT(with_odometry, 0.0005);  // measured 0.00007, the levelling alone 0.011
  EXPECT_LT(with_odometry, 0.5 * levelling_alone);
}

// Issue 39: an allowed station holding full climb took the vehicle past the depth sensor's
// range and the walls, where it decided it had landed and fell from 11.8 m. The envelope's
// ceiling (modes.max_height_m) stops the climb; the vehicle neither falls nor hits anything.
TEST(ClosedLoop, FullClimbHeldStopsAtTheCeilingAndNeverFalls) {
  Scenario s = room_takeoff(25.0);
  s.script.frame = CommandFrame::kHorizontal;
  s.step(4.0, Vec(0, 0, -1.0));  // full climb, held to the end
  auto loop = s.make();
  loop->run();
  double highest_m = 0.0;
  bool landed_in_the_air = false;
  for (const FlightSample& x : loop->samples()) {
    highest_m = std::max(highest_m, x.p_N_m.z());
    landed_in_the_air = landed_in_the_air || (x.landed && x.p_N_m.z() > 0.5);
  }
  const FlightSummary summary = summarise(*loop);
  fmt::print(
      "full climb held 21 s: highest {:.2f} m (ceiling {:.1f} m), collision ticks {}, floor "
      "contacts {} (fastest {:.2f} m/s)\n",
      highest_m, s.onboard.modes.max_height_m, summary.collision_ticks, summary.floor_impacts,
      summary.max_floor_impact_speed_mps);
  // The body's height above the floor, measured by the depth of a tilted camera, is within a
  // few centimetres of the truth here.
  EXPECT_LT(highest_m, s.onboard.modes.max_height_m + 0.2);
  EXPECT_GT(highest_m, s.onboard.modes.max_height_m - 0.3);  // it did climb to it
  EXPECT_FALSE(landed_in_the_air);
  EXPECT_EQ(summary.collision_ticks, 0);
  EXPECT_EQ(loop->simulator().hard_floor_impacts(), 0);
}

// The largest horizontal distance (truth) from where the vehicle left the floor, for a dash
// held away from it with the envelope's horizontal bound at bound_m.
double farthest_from_takeoff_m(double bound_m, int* collision_ticks) {
  Scenario s = room_takeoff(16.0);
  s.onboard.modes.max_distance_from_takeoff_m = bound_m;
  s.onboard.modes.horizontal_slowdown_m = 0.4;
  s.step(4.0, Vec(0.5, 0.0, 0.0));  // where the camera looks, held to the end
  auto loop = s.make();
  loop->run();
  std::optional<Eigen::Vector2d> takeoff_m;
  double farthest_m = 0.0;
  for (const FlightSample& x : loop->samples()) {
    if (!takeoff_m && x.airborne) takeoff_m = x.p_N_m.head<2>();
    if (takeoff_m) farthest_m = std::max(farthest_m, (x.p_N_m.head<2>() - *takeoff_m).norm());
  }
  *collision_ticks = summarise(*loop).collision_ticks;
  return farthest_m;
}

// Issue 39: the envelope's horizontal bound around the take-off point, dead-reckoned by the
// chain, stops a dash held away from it; without it the same dash goes on (to the room's walls).
TEST(ClosedLoop, DashHeldAwayStopsAtTheHorizontalBound) {
  int bounded_collisions = 0;
  int free_collisions = 0;
  const double bounded_m = farthest_from_takeoff_m(0.8, &bounded_collisions);
  const double free_m = farthest_from_takeoff_m(10.0, &free_collisions);
  fmt::print(
      "dash held 12 s: farthest {:.2f} m from take-off with a 0.8 m bound, {:.2f} m without\n",
      bounded_m, free_m);
  EXPECT_LT(bounded_m, 0.8 + 0.15);  // the dead reckoning's error and the PID's lag
  EXPECT_GT(bounded_m, 0.8 - 0.25);  // it did go there
  EXPECT_GT(free_m, bounded_m + 0.3);
  EXPECT_EQ(bounded_collisions, 0);
}

// Issue 39: the estimate lost high up ends in a land on the IMU alone. The blind descent holds
// blind_descent_speed_mps on the IMU's vertical velocity and meets the floor at about that
// speed, not at the 2-3 m/s of a fixed 0.9 m g from 2 m.
TEST(ClosedLoop, CameraLostHighUpLandsOnTheImuAtTheBlindDescentSpeed) {
  Scenario s = room_takeoff(40.0);
  s.script.frame = CommandFrame::kHorizontal;
  s.step(4.0, Vec(0, 0, -0.5));  // up to the ceiling (2 m)
  s.step(8.0, Vec::Zero());
  s.options.faults.push_back({CameraFault::Kind::kDrop, 10.0, 30.0});  // for good
  auto loop = s.make();
  loop->run();
  double height_at_loss_m = 0.0;
  bool descended_blind = false;
  for (const FlightSample& x : loop->samples()) {
    if (x.t_s <= 10.0) height_at_loss_m = x.p_N_m.z();
    descended_blind = descended_blind || (x.t_s > 10.0 && x.mode == modes::Mode::kLand);
  }
  const FlightSummary summary = summarise(*loop);
  fmt::print(
      "camera lost at {:.2f} m: floor met at {:.2f} m/s (blind_descent_speed_mps {:.1f}), {} hard "
      "impacts\n",
      height_at_loss_m, summary.max_floor_impact_speed_mps, s.onboard.modes.blind_descent_speed_mps,
      loop->simulator().hard_floor_impacts());
  EXPECT_GT(height_at_loss_m, 1.5);
  EXPECT_TRUE(descended_blind);
  EXPECT_LT(summary.max_floor_impact_speed_mps, s.onboard.modes.blind_descent_speed_mps + 0.3);
  EXPECT_EQ(loop->simulator().hard_floor_impacts(), 0);
  EXPECT_TRUE(loop->samples().back().landed) << "on the floor's evidence";
}

/// Hover <-> land requested by the operator at 10 Hz from 6 s to 26 s after the room take-off.
struct ToggleFlight {
  FlightSummary summary;
  int hard_floor_impacts = 0;
  double lowest_m = 1e9;  // truth, after the take-off
  double final_m = 0.0;
  int mode_changes = 0;
  bool landed = false;
  std::vector<std::string> refusals;
};

ToggleFlight toggle_hover_land_at_10_hz(const modes::ModesConfig& modes) {
  Scenario s = room_takeoff(28.0);
  s.onboard.modes = modes;
  for (int k = 0; k < 200; ++k) {
    s.step(6.0 + 0.1 * k, std::nullopt, std::nullopt,
           k % 2 == 0 ? modes::Mode::kLand : modes::Mode::kHover);
  }
  auto loop = s.make();
  loop->run();
  ToggleFlight f;
  modes::Mode previous = modes::Mode::kTeleop;
  for (const FlightSample& x : loop->samples()) {
    if (x.t_s < 6.0) continue;
    f.lowest_m = std::min(f.lowest_m, x.p_N_m.z());
    f.landed = f.landed || x.landed;
    f.mode_changes += x.mode != previous ? 1 : 0;
    previous = x.mode;
  }
  f.final_m = loop->samples().back().p_N_m.z();
  f.summary = summarise(*loop);
  f.hard_floor_impacts = loop->simulator().hard_floor_impacts();
  f.refusals = loop->refusals();
  fmt::print(
      "hover<->land at 10 Hz for 20 s (dwell {:.1f} s): collision ticks {}, min clearance {:.2f} "
      "m, hard floor impacts {}, lowest {:.2f} m, final {:.2f} m, {} mode changes, {} refused\n",
      modes.min_mode_dwell_s, f.summary.collision_ticks, f.summary.min_clearance_m,
      f.hard_floor_impacts, f.lowest_m, f.final_m, f.mode_changes, f.refusals.size());
  return f;
}

// Issue 39: valid requests toggled hover <-> land every 0.5 s sank the vehicle into a wall
// (983-1135 collision ticks, clearance -0.35 m). The operator's changes wait a minimum dwell
// per mode and a rate limit, and land -> hover low down climbs back first.
TEST(ClosedLoop, HoverLandToggledAt10HzNeverSinksIntoAnything) {
  const modes::ModesConfig config = Scenario{}.onboard.modes;
  const ToggleFlight f = toggle_hover_land_at_10_hz(config);
  EXPECT_EQ(f.summary.collision_ticks, 0);
  EXPECT_EQ(f.hard_floor_impacts, 0);
  EXPECT_FALSE(f.landed);
  EXPECT_GT(f.lowest_m, 0.3);
  EXPECT_GT(f.final_m, 0.5);
  // The requests beyond the dwell were refused, saying so.
  EXPECT_LE(f.mode_changes, static_cast<int>(20.0 / config.min_mode_dwell_s) + 1);
  ASSERT_FALSE(f.refusals.empty());
  EXPECT_THAT(f.refusals.front(), HasSubstr("mode change refused: minimum dwell in land"));
}

// The same without the hysteresis, as before issue 39's fix: run by hand for the figures
// (--gtest_also_run_disabled_tests).
TEST(ClosedLoop, DISABLED_HoverLandToggledAt10HzWithoutTheHysteresis) {
  modes::ModesConfig config = Scenario{}.onboard.modes;
  config.min_mode_dwell_s = 0.0;
  config.operator_mode_changes_per_min = 1e5;
  config.operator_mode_change_burst = 100;
  config.land_abort_min_height_m = 1e-3;
  const ToggleFlight f = toggle_hover_land_at_10_hz(config);
  EXPECT_GT(f.summary.collision_ticks + f.hard_floor_impacts, 0);
}

TEST(ClosedLoop, VelocityStepRisesFastWithBoundedOvershoot) {
  Scenario s = room_takeoff(11.0);
  s.script.frame = CommandFrame::kHorizontal;
  // The velocity loop's step response along H-x, 45 deg off the camera: the seen-space limiter
  // would refuse the step, so it is off for this measurement of the loop.
  s.onboard.seen_space.enabled = false;
  constexpr double kStepMps = 0.5;
  s.step(6.0, Vec(kStepMps, 0, 0));
  s.step(9.0, Vec::Zero());
  auto loop = s.make();
  loop->run();

  double t10 = -1.0;
  double t90 = -1.0;
  double peak = 0.0;
  for (const FlightSample& x : loop->samples()) {
    if (x.t_s < 6.0 || x.t_s > 9.0) continue;
    const double v = x.v_true_mps.x();
    if (t10 < 0 && v >= 0.1 * kStepMps) t10 = x.t_s;
    if (t90 < 0 && v >= 0.9 * kStepMps) t90 = x.t_s;
    peak = std::max(peak, v);
  }
  ASSERT_GT(t10, 0.0);
  ASSERT_GT(t90, 0.0) << "never reached 90 % of the step";
  const double rise_s = t90 - t10;
  const double overshoot = peak / kStepMps - 1.0;
  const double tail_error = std::abs(sample_at(*loop, 8.9).v_true_mps.x() - kStepMps);
  fmt::print(
      "step 0.5 m/s: rise (10-90 %) {:.2f} s, overshoot {:.1f} %, error after 2.9 s {:.3f} m/s\n",
      rise_s, 100.0 * overshoot, tail_error);
  // The mode ramp alone (1 m/s^2) takes 0.4 s of the rise; measured about 0.6 s and 10 %.
  EXPECT_LT(rise_s, 1.2);
  EXPECT_LT(overshoot, 0.30);
  EXPECT_LT(tail_error, 0.08);
}

TEST(ClosedLoop, OneSecondCameraLossAndNanBurstKeepTheVehicleInPlace) {
  Scenario s = room_takeoff(16.0);
  s.options.faults.push_back({CameraFault::Kind::kDrop, 8.0, 1.0});
  s.options.faults.push_back({CameraFault::Kind::kNanDepth, 12.0, 0.5});
  auto loop = s.make();
  loop->run();

  for (const auto& [start_s, duration_s] : {std::pair{8.0, 1.0}, std::pair{12.0, 0.5}}) {
    const Vec p0 = sample_at(*loop, start_s - 0.05).p_N_m;
    double max_drift_m = 0.0;
    bool degraded = false;
    bool odometry_throughout = true;
    for (const FlightSample& x : loop->samples()) {
      if (x.t_s < start_s + 0.1 || x.t_s > start_s + duration_s) continue;
      degraded = degraded || x.degraded;
      odometry_throughout = odometry_throughout && x.estimate_ok;
      EXPECT_NE(x.degraded, x.estimate_ok) << "t = " << x.t_s << ": degraded is said exactly "
                                           << "when the velocity is not the odometry's";
      EXPECT_FALSE(x.safe_hover) << "t = " << x.t_s << ": the IMU coast should cover it";
      EXPECT_TRUE(x.airborne) << "t = " << x.t_s;
      max_drift_m = std::max(max_drift_m, (x.p_N_m - p0).norm());
    }
    const FlightSample& after = sample_at(*loop, start_s + duration_s + 1.0);
    fmt::print(
        "camera fault at {:.1f} s for {:.1f} s: max drift {:.3f} m, estimate ok 1 s later: {}\n",
        start_s, duration_s, max_drift_m, after.estimate_ok ? "yes" : "no");
    // Without frames nothing tracks; through NaN depth frame-to-keyframe odometry may keep
    // tracking on its keyframe's depth, and then there is nothing to say.
    if (start_s == 8.0) {
      EXPECT_FALSE(odometry_throughout);
    }
    EXPECT_TRUE(degraded || odometry_throughout)
        << "the chain must say its estimate is degraded when it is not the odometry's";
    EXPECT_LT(max_drift_m, 0.25);
    EXPECT_TRUE(after.estimate_ok);
  }
  EXPECT_EQ(loop->collision_ticks(), 0);
}

TEST(ClosedLoop, LongCameraLossCoastsForABoundedTimeThenSafeHovers) {
  Scenario s = room_takeoff(14.0);
  s.options.faults.push_back({CameraFault::Kind::kDrop, 8.0, 4.0});
  auto loop = s.make();
  loop->run();
  double first_safe_hover_s = -1.0;
  double last_ok_s = -1.0;
  for (const FlightSample& x : loop->samples()) {
    if (x.t_s < 8.0 && x.estimate_ok) last_ok_s = x.t_s;
    if (x.t_s > 8.0 && x.t_s < 12.0 && x.safe_hover && first_safe_hover_s < 0) {
      first_safe_hover_s = x.t_s;
    }
  }
  ASSERT_GT(first_safe_hover_s, 0.0) << "the IMU coast must end";
  // The coast runs from the last odometry velocity, the frame before the loss.
  const double coast_s = first_safe_hover_s - last_ok_s;
  fmt::print("4 s camera loss: IMU coast {:.2f} s (inertial_coast_s {:.1f}), then safe hover\n",
             coast_s, s.onboard.estimator.inertial_coast_s);
  // The coast's length is what the fused filter still does not know of the accelerometer
  // allows, at most inertial_coast_s: after 8 s tracked its unseen acceleration is known to
  // 0.05 m/s^2 (its random walk against the frames' noise), which allows 1.97 s of the 2.
  EXPECT_GE(coast_s, 0.95 * s.onboard.estimator.inertial_coast_s);
  EXPECT_LE(coast_s, s.onboard.estimator.inertial_coast_s + 0.05);
  EXPECT_TRUE(sample_at(*loop, 11.9).airborne);
  EXPECT_TRUE(sample_at(*loop, 13.9).estimate_ok) << "odometry resumes when frames return";
}

TEST(ClosedLoop, CorePaperFlightTakesOffApproachesTheBoxAndLands) {
  Scenario s;
  s.world = sim::load_world("onboard/sim/worlds/arena.yaml");
  s.sim.seed = s.world.seed;
  s.script = load_operator_script("onboard/closed_loop/flights/core_paper_box.yaml");
  auto loop = s.make();
  loop->run();
  const FlightSummary summary = summarise(*loop);
  print_summary(stdout, "core paper flight", summary);
  EXPECT_EQ(summary.collision_ticks, 0);
  EXPECT_GT(summary.min_clearance_m, 0.1);
  EXPECT_LT(summary.min_clearance_m, 0.8) << "the operator drove it close to the box";
  EXPECT_GT(summary.estimate_available, 0.9);
  EXPECT_LT(summary.velocity_rmse_mps.maxCoeff(), 0.08);
  EXPECT_TRUE(loop->samples().back().landed);
  EXPECT_FALSE(loop->samples().back().airborne);
}

/// Takes off from the room with the simulated vehicle `mass_ratio` times as heavy as the chain
/// believes, hovers, and returns the loop.
std::unique_ptr<ClosedLoop> hover_with_mass_off(double mass_ratio, bool learn, double end_s) {
  Scenario s;
  s.world = sim::load_world("onboard/sim/worlds/room.yaml");
  s.sim.seed = 5;
  s.sim.vehicle.mass_kg *= mass_ratio;
  s.onboard.hover_thrust.enabled = learn;
  s.script.end_s = end_s;
  auto loop = s.make();
  loop->run_until(0.5);  // the estimator starts on the floor, at rest
  pipeline::ModeRequest request;
  request.mode = modes::Mode::kHover;
  request.take_off = true;
  EXPECT_TRUE(loop->chain().request_mode(request).accepted);
  loop->run();
  return loop;
}

/// The first time (s) after which the vehicle is airborne and the learnt gain stays within
/// `tolerance` of `true_gain`; negative if never.
double settled_at_s(const ClosedLoop& loop, double true_gain, double tolerance) {
  double since_s = -1.0;
  for (const FlightSample& x : loop.samples()) {
    const bool within = std::abs(x.hover_thrust_gain - true_gain) <= tolerance * true_gain;
    if (!within) {
      since_s = -1.0;
    } else if (since_s < 0.0 && x.airborne) {
      since_s = x.t_s;
    }
  }
  return since_s;
}

double first_airborne_s(const ClosedLoop& loop) {
  for (const FlightSample& x : loop.samples()) {
    if (x.airborne) return x.t_s;
  }
  return -1.0;
}

/// The widest height excursion (m) after `from_s`: a hover that holds still stays within cm.
double height_excursion_after(const ClosedLoop& loop, double from_s) {
  double low = 1e9;
  double high = -1e9;
  for (const FlightSample& x : loop.samples()) {
    if (x.t_s < from_s) continue;
    low = std::min(low, x.p_N_m.z());
    high = std::max(high, x.p_N_m.z());
  }
  return high - low;
}

TEST(ClosedLoop, HoverThrustIsLearntWhenTheVehicleIsOffItsConfig) {
  // A vehicle 30 % lighter than its file says (or the FC's maximum thrust set 30 % too low:
  // the same gain), then 10 % heavier. The rotors give 1/0.7 (1/1.1) of the thrust the chain
  // believes it asks for. Heavier by much more does not leave the floor: the take-off is
  // open loop at m g until the camera's estimate starts, and nothing is learnt on the floor.
  for (const double mass_ratio : {0.7, 1.1}) {
    const auto loop = hover_with_mass_off(mass_ratio, true, 20.0);
    const double true_gain = 1.0 / mass_ratio;
    const double airborne_s = first_airborne_s(*loop);
    const double settled_s = settled_at_s(*loop, true_gain, 0.10);
    const FlightSample& last = loop->samples().back();
    fmt::print(
        "[ figures ] vehicle {:.0f} % of its believed mass: airborne at {:.2f} s, gain within 10 % "
        "of {:.3f} from {:.2f} s ({:.2f} s airborne), final {:.3f}; height {:.2f} m\n",
        100.0 * mass_ratio, airborne_s, true_gain, settled_s, settled_s - airborne_s,
        last.hover_thrust_gain, last.p_N_m.z());
    ASSERT_GE(airborne_s, 0.0) << "never left the floor";
    ASSERT_GE(settled_s, 0.0) << "the gain never settled";
    EXPECT_LT(settled_s - airborne_s, 8.0);
    EXPECT_NEAR(last.hover_thrust_gain, true_gain, 0.05 * true_gain);
    EXPECT_TRUE(loop->chain().hover_thrust().converged);
    // Once learnt, the gain takes over from the velocity loop's integral without a jump: the
    // hover holds its height (before the integral was moved, the vehicle sank 0.6 m).
    const double excursion_m = height_excursion_after(*loop, settled_s + 2.0);
    fmt::print("[ figures ] height excursion after the gain settled: {:.3f} m\n", excursion_m);
    EXPECT_LT(excursion_m, 0.15);
    EXPECT_EQ(loop->collision_ticks(), 0);
  }
}

TEST(ClosedLoop, TakeOffRequestAloneEndsHoveringAtTargetHeightWithHeightNearTruth) {
  // GIVEN the vehicle on the floor of the room, no operator command at all
  Scenario s;
  s.world = sim::load_world("onboard/sim/worlds/room.yaml");
  s.sim.seed = 5;
  s.script.end_s = 12.0;
  auto loop = s.make();
  loop->run_until(0.5);
  ASSERT_EQ(loop->samples().back().flight_state, modes::FlightState::kLanded);
  // WHEN only a take-off (then hover) is requested
  pipeline::ModeRequest request;
  request.mode = modes::Mode::kHover;
  request.take_off = true;
  ASSERT_TRUE(loop->chain().request_mode(request).accepted);
  loop->run();
  // THEN it took off through the taking-off state, ends airborne and hovering at the target
  // height, and the height it reports tracks the simulator's truth while airborne.
  const double target_m = s.onboard.modes.takeoff_target_height_m;
  bool saw_taking_off = false;
  double max_error_m = 0.0;
  int depth_samples = 0;
  int airborne_samples = 0;
  for (const FlightSample& x : loop->samples()) {
    saw_taking_off |= x.flight_state == modes::FlightState::kTakingOff;
    if (!x.frame || !x.airborne || x.t_s < 2.0) continue;
    ASSERT_NE(x.height_source, pipeline::HeightSource::kNone) << "t = " << x.t_s;
    ++airborne_samples;
    depth_samples += x.height_source == pipeline::HeightSource::kDepth ? 1 : 0;
    max_error_m = std::max(max_error_m, std::abs(x.height_m - x.p_N_m.z()));
  }
  const FlightSample& last = loop->samples().back();
  fmt::print(
      "take-off: final height {:.3f} m (truth {:.3f} m, target {:.2f} m), height error max {:.3f} "
      "m over {} airborne frames ({} from depth)\n",
      last.height_m, last.p_N_m.z(), target_m, max_error_m, airborne_samples, depth_samples);
  EXPECT_TRUE(saw_taking_off);
  EXPECT_EQ(last.flight_state, modes::FlightState::kAirborne);
  EXPECT_EQ(last.mode, modes::Mode::kHover);
  EXPECT_TRUE(last.airborne);
  EXPECT_NEAR(last.p_N_m.z(), target_m, 0.1);
  EXPECT_GT(airborne_samples, 200);
  EXPECT_GT(depth_samples, airborne_samples / 2) << "the floor is in the camera's view";
  EXPECT_LT(max_error_m, 0.1);
  EXPECT_EQ(loop->collision_ticks(), 0);
}

TEST(OperatorScript, RejectsBadFilesNamingStepAndKey) {
  const std::string path = ::testing::TempDir() + "hq_script.yaml";
  const auto message_for = [&](const char* text) {
    std::ofstream(path) << text;
    return hq::testing::input_error_message([&] { (void)load_operator_script(path); });
  };
  EXPECT_THAT(message_for("end_s: 5\nsteps: [{t_s: 1}, {t_s: 1}]\n"), HasSubstr("steps[1].t_s"));
  EXPECT_THAT(message_for("end_s: 5\nsteps: [{t_s: 1, mode: fly}]\n"), HasSubstr("mode"));
  EXPECT_THAT(message_for("end_s: 5\nsteps: [{t_s: 1, v_mps: [0, .nan, 0]}]\n"),
              HasSubstr("v_mps"));
  EXPECT_THAT(message_for("end_s: 5\nsteps: [{t_s: 6}]\n"), HasSubstr("steps[0].t_s"));
  EXPECT_THAT(message_for("end_s: 5\nsteps: [{t_s: 1, speed: 2}]\n"), HasSubstr("speed"));
  EXPECT_THAT(message_for("end_s: 5\n"), HasSubstr("steps"));
  EXPECT_THAT(
      hq::testing::input_error_message([] { (void)load_operator_script("no/such/script.yaml"); }),
      HasSubstr("no/such/script.yaml"));
}

TEST(OperatorPlayer, HoldsStepsAndTurnsCameraHeadingIntoH) {
  OperatorScript script;
  script.end_s = 10.0;
  OperatorStep a;
  a.t_s = 1.0;
  a.v_mps = Vec(1.0, 0.0, -0.5);
  a.mode = modes::Mode::kTeleop;
  OperatorStep b;
  b.t_s = 2.0;
  b.yaw_rate_radps = 0.3;
  script.steps = {a, b};
  OperatorPlayer player(script, M_PI / 4.0);
  EXPECT_TRUE(player.command(500'000'000).v_H_mps.isZero());
  const modes::OperatorCommand held = player.command(2'500'000'000);
  EXPECT_NEAR(held.v_H_mps.x(), std::sqrt(0.5), 1e-12);  // eq. 6, alpha = 45 deg
  EXPECT_NEAR(held.v_H_mps.y(), std::sqrt(0.5), 1e-12);  // eq. 7
  EXPECT_NEAR(held.v_H_mps.z(), -0.5, 1e-12);
  EXPECT_NEAR(held.yaw_rate_radps, 0.3, 1e-12);
  std::vector<modes::Mode> requests;
  player.take_mode_requests(1'500'000'000, requests);
  player.take_mode_requests(3'000'000'000, requests);
  ASSERT_EQ(requests.size(), 1u);
  EXPECT_EQ(requests[0], modes::Mode::kTeleop);
}

// Issue 43: the odom pose (odom -> base_link) integrated on board without markers, against the
// simulator's truth expressed in the odom frame (origin and heading of the start, NED-like).
TEST(ClosedLoop, OdomPoseFollowsTheTruthWithinItsOwnUncertainty) {
  // GIVEN a take-off, a leg where the camera looks, a turn on the spot and a second leg
  Scenario s = room_takeoff(22.0);
  s.step(4.0, Vec(0.4, 0.0, 0.0), 0.0);
  s.step(8.0, Vec::Zero(), 0.4);
  s.step(11.0, Vec(0.4, 0.0, 0.0), 0.0);
  s.step(15.0, Vec::Zero(), 0.0);
  auto loop = s.make();
  loop->run();
  const FlightSample& start = loop->samples().front();
  const Eigen::AngleAxisd R_odom_ned(-start.heading_true_ned_rad, Vec::UnitZ());
  double worst_error_m = 0.0;
  double sigma_at_worst_m = 0.0;
  double worst_ratio = 0.0;
  double worst_yaw_error_rad = 0.0;
  double flown_m = 0.0;
  Vec last_truth = Vec::Zero();
  const FlightSample* last = nullptr;
  for (const FlightSample& x : loop->samples()) {
    ASSERT_TRUE(x.odom.valid) << "t = " << x.t_s;
    EXPECT_TRUE(x.odom.yaw_relative_to_start);
    const Vec d_N = x.p_N_m - start.p_N_m;
    const Vec truth_odom = R_odom_ned * Vec(d_N.x(), -d_N.y(), -d_N.z());
    flown_m += (truth_odom - last_truth).head<2>().norm();
    last_truth = truth_odom;
    const double error_m = (x.odom.p_odom_m - truth_odom).head<2>().norm();
    // The sigma of a horizontal 2-D error: its radius is within 3 sigma at 99 %.
    const double ratio = error_m / std::max(x.odom.position_sigma_m, 1e-3);
    if (error_m > worst_error_m) {
      worst_error_m = error_m;
      sigma_at_worst_m = x.odom.position_sigma_m;
    }
    worst_ratio = std::max(worst_ratio, ratio);
    const double yaw_true =
        std::remainder(x.heading_true_ned_rad - start.heading_true_ned_rad, 2.0 * M_PI);
    const double yaw_error = std::abs(std::remainder(x.odom.yaw_rad - yaw_true, 2.0 * M_PI));
    worst_yaw_error_rad = std::max(worst_yaw_error_rad, yaw_error);
    if (x.airborne) {
      EXPECT_LT(yaw_error, 3.0 * x.odom.yaw_sigma_rad + 0.01) << "t = " << x.t_s;
    }
    last = &x;
  }
  ASSERT_NE(last, nullptr);
  const double end_error_m = (last->odom.p_odom_m - last_truth).head<2>().norm();
  fmt::print(
      "odom pose over {:.1f} m flown in {:.1f} s: drift at the end {:.3f} m (sigma {:.3f} m), "
      "worst {:.3f} m (sigma then {:.3f} m), worst error/sigma {:.2f}; yaw: worst error {:.4f} "
      "rad, sigma at the end {:.4f} rad; turned {:.2f} rad\n",
      flown_m, last->t_s, end_error_m, last->odom.position_sigma_m, worst_error_m, sigma_at_worst_m,
      worst_ratio, worst_yaw_error_rad, last->odom.yaw_sigma_rad, last->odom.yaw_rad);
  // THEN it moved with the vehicle (a leg, a turn, a leg), its drift stays within 3 sigma of
  // its own uncertainty, and that uncertainty is not so wide as to say nothing. Measured at
  // seed 5: 0.07 m of drift over 3.6 m flown, sigma 0.56 m (error/sigma at worst 0.23); yaw
  // 0.03 rad off, sigma 0.11 rad.
  EXPECT_GT(flown_m, 2.0);
  EXPECT_GT(std::abs(last->odom.yaw_rad), 0.8);
  EXPECT_LT(worst_ratio, 3.0);
  EXPECT_LT(last->odom.position_sigma_m, 0.25 * flown_m);
  EXPECT_EQ(loop->collision_ticks(), 0);
}

}  // namespace
}  // namespace hq::closed_loop
