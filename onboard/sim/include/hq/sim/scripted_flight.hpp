#pragma once
/// Scripted flights for simulated runs (hq-sim, regression tests): a truth-stabilised hover or
/// circle, turned into the AttitudeCommand the on-board velocity tracker would send. The script
/// flies on truth, so a run is a pure function of (config, world, seed, script).

#include "hq/sim/quadrotor.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/world.hpp"

#include <Eigen/Core>

#include <cstdint>

namespace hq::sim {

/// Period at which a scripted flight issues commands: 200 Hz, as a flight computer would.
inline constexpr std::int64_t kScriptControlPeriodNs = 5'000'000;

struct FlightScript {
  enum class Kind { kHover, kCircle };
  Kind kind = Kind::kHover;
  double takeoff_s = 1.0;       ///< rests on the floor until then.
  double circle_start_s = 4.0;  ///< after take-off and settling.
  double altitude_m = 1.0;
  double circle_radius_m = 0.7;
  double circle_speed_mps = 0.4;
  double circle_yaw_rate_radps = 0.15;  ///< a slow turn so the camera sweeps the scene.
  Eigen::Vector2d circle_center_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d hover_xy_m = Eigen::Vector2d::Zero();  ///< lies on the circle.
};

/// The script hq-sim flies in `world`: hover above the start position; the circle passes
/// through it and bends towards the world origin, where the worlds keep their free space.
FlightScript script_for_world(const World& world, FlightScript::Kind kind);

/// Command at t_s from the simulator's truth: a PD on position plus feed-forward, converted to
/// roll/pitch with gravity compensation in the horizontal frame H (core paper §3). Allocates
/// nothing.
AttitudeCommand scripted_command(const Simulator& sim, const FlightScript& script, double t_s);

}  // namespace hq::sim
