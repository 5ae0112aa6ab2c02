#pragma once
// The obstacle-memory campaign: the vehicle first sees a box, then the operator moves
// it towards the box while the box is outside the camera's view (the camera looks 45 deg right
// and 30 deg down, core paper Fig. 3). Three cases:
//   back-up:   face the box, yaw 180 deg, then command backwards (about the camera heading);
//   sideways:  face the box, yaw 90 deg left (box now on the right), then command right;
//   yaw-close: approach to ~1 m clearance, yaw 60-90 deg left, then slide at the box's bearing.
// Each run draws speed, distance, box size and headings from its own seeded generator, so run i
// of a case is the same flight whatever the number of runs, and the same with memory off or on.
// Shared by hq_obstacle_memory_campaign_test and hq-bench-memory-campaign.

#include "hq/pipeline/stage_timing.hpp"
#include "hq/sim/world.hpp"

#include "../closed_loop/scenario.hpp"
#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fmt/format.h>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace hq::closed_loop::testing {

enum class MemoryCase { kBackUp, kSideways, kYawClose };
inline constexpr MemoryCase kMemoryCases[] = {MemoryCase::kBackUp, MemoryCase::kSideways,
                                              MemoryCase::kYawClose};

inline const char* to_string(MemoryCase c) {
  switch (c) {
    case MemoryCase::kBackUp:
      return "back-up";
    case MemoryCase::kSideways:
      return "sideways";
    case MemoryCase::kYawClose:
      return "yaw-close";
  }
  return "?";
}

/// One drawn flight.
struct MemoryRun {
  MemoryCase kind = MemoryCase::kBackUp;
  int index = 0;
  double speed_mps = 0.5;      ///< The operator's push, 0.3-0.8 m/s.
  double start_yaw_rad = 0.0;  ///< NED yaw of the body at the start.
  double distance_m = 1.7;     ///< Body centre to the box's near face along the camera heading.
  Eigen::Vector3d box_size_m = Eigen::Vector3d(0.5, 0.5, 1.6);
  double box_yaw_rad = 0.0;
  double turn_rad = 0.0;  ///< Yaw to the left before the push (positive = left).
};

inline constexpr double kYawRateRadps = 80.0 * M_PI / 180.0;  ///< Below the 90 deg/s limit.
inline constexpr double kVehicleRadiusM = 0.35;
inline constexpr double kAltitudeM = 1.0;

inline MemoryRun draw_memory_run(MemoryCase kind, int index, std::uint32_t seed) {
  std::mt19937 rng(seed + 7919u * static_cast<std::uint32_t>(kind) +
                   104729u * static_cast<std::uint32_t>(index));
  std::uniform_real_distribution<double> u(0.0, 1.0);
  MemoryRun r;
  r.kind = kind;
  r.index = index;
  r.speed_mps = 0.3 + 0.5 * u(rng);
  r.start_yaw_rad = 2.0 * M_PI * u(rng);
  r.box_size_m = Eigen::Vector3d(0.4 + 0.5 * u(rng), 0.4 + 0.5 * u(rng), 1.5 + 0.5 * u(rng));
  r.box_yaw_rad = M_PI * u(rng);
  switch (kind) {
    case MemoryCase::kBackUp:
      r.distance_m = 1.5 + 0.5 * u(rng);
      r.turn_rad = M_PI;
      break;
    case MemoryCase::kSideways:
      r.distance_m = 1.5 + 0.5 * u(rng);
      r.turn_rad = 0.5 * M_PI;
      break;
    case MemoryCase::kYawClose:
      r.distance_m = 1.8 + 0.4 * u(rng);
      r.turn_rad = (60.0 + 30.0 * u(rng)) * M_PI / 180.0;
      break;
  }
  return r;
}

/// The run's world (the room's textured floor with one noise-textured box) and operator script.
/// Returns the scenario ready to make(); memory_enabled sets config memory.enabled.
inline Scenario memory_scenario(const MemoryRun& r, bool memory_enabled, const sim::World& room) {
  Scenario s;
  s.world = room;
  // The room's walls moved out by 1.5x (12 m x 9 m): far enough to exert nothing, near enough
  // that the camera never looks into the void when the vehicle pitches up to brake (no depth in
  // the central window reads as the field's near hazard, and odometry loses its texture).
  for (sim::Rectangle& wall : s.world.walls) {
    wall.center_m.head<2>() *= 1.5;
    (std::abs(wall.axis_u.z()) < 0.5 ? wall.half_u_m : wall.half_v_m) *= 1.5;
  }
  s.world.boxes.clear();
  s.world.cylinders.clear();
  s.world.markers.clear();
  s.world.start_N_m = Eigen::Vector3d(0.0, 0.0, kAltitudeM);
  s.world.start_yaw_rad = r.start_yaw_rad;
  s.start_airborne(kAltitudeM);
  s.sim.seed =
      5000u + 100u * static_cast<std::uint64_t>(r.kind) + static_cast<std::uint64_t>(r.index);
  s.onboard.memory.enabled = memory_enabled;
  // These runs measure the memory's push on a vehicle driven out of view; the seen-space
  // limiter refuses that drive itself, so it is off here (its own campaign is
  // tests/closed_loop/unseen_campaign_test.cpp).
  s.onboard.seen_space.enabled = false;

  s.add_box_in_view(r.start_yaw_rad, r.distance_m, r.box_size_m, r.box_yaw_rad,
                    static_cast<std::uint32_t>(31 * static_cast<int>(r.kind) + r.index + 17));

  // Settle 1.5 s facing the box (the memory sees it), then the case's moves. Yaw left is a
  // negative NED yaw rate. The push lasts long enough to reach the box plus 0.3 m.
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  s.step(0.0, zero, 0.0, modes::Mode::kTeleop);
  double t = 1.5;
  double to_contact_m = r.distance_m - kVehicleRadiusM;
  if (r.kind == MemoryCase::kYawClose) {
    // Forward to ~1 m clearance (the field's reach), then stop and settle.
    const double approach_m = std::max(0.0, to_contact_m - 1.0);
    s.step(t, Eigen::Vector3d(r.speed_mps, 0, 0));
    t += approach_m / r.speed_mps;
    s.step(t, zero);
    t += 1.0;
    to_contact_m = 1.0;
  }
  const double yaw_s = r.turn_rad / kYawRateRadps;
  s.step(t, zero, r.kind == MemoryCase::kBackUp ? kYawRateRadps : -kYawRateRadps);
  t += yaw_s;
  s.step(t, zero, 0.0);
  t += 0.75;
  // The box's bearing from the camera heading after the turn: behind (back-up) or turn_rad to
  // the right (left turns); [forward, right, down] about the camera heading.
  const Eigen::Vector3d push = r.kind == MemoryCase::kBackUp
                                   ? Eigen::Vector3d(-r.speed_mps, 0, 0)
                                   : Eigen::Vector3d(r.speed_mps * std::cos(r.turn_rad),
                                                     r.speed_mps * std::sin(r.turn_rad), 0);
  s.step(t, push);
  t += (to_contact_m + 0.3) / r.speed_mps;
  s.step(t, zero);
  s.script.end_s = t + 1.5;
  return s;
}

/// Wraps the scripted player as an OperatorSource to see every chain output: the frame stage
/// durations go into `timing` (frames only, the first of the flight excluded).
class TimedPlayer final : public OperatorSource {
 public:
  /// @param trace  optional: one line per frame (memory, v_obs, truth) for diagnosis.
  TimedPlayer(OperatorPlayer player, pipeline::StageTimingLog* timing, std::FILE* trace = nullptr)
      : player_(std::move(player)), timing_(timing), trace_(trace) {}
  modes::OperatorCommand poll(std::int64_t t_ns, std::vector<modes::Mode>& requests) override {
    player_.take_mode_requests(t_ns, requests);
    return player_.command(t_ns);
  }
  void on_output(const pipeline::ChainOutput& out, const sim::TruthState& truth) override {
    if (!out.frame) return;
    if (trace_ != nullptr) {
      const auto& m = out.memory;
      const double nearest_m =
          m.count > 0 ? m.p_H_m[0].norm() : std::numeric_limits<double>::quiet_NaN();
      const Eigen::Vector3d& v_obs = out.obstacles.v_obs_H_mps;
      const Eigen::Vector3d& v_des = out.mode.v_des_H_mps;
      fmt::print(trace_,
                 "t {:6.2f} track {:<5} map {:5} recalled {:2} nearest {:5.2f} view {:2} v_obs "
                 "[{:+.2f} {:+.2f}] v_des [{:+.2f} {:+.2f}] v_true [{:+.2f} {:+.2f}] yaw {:+6.1f} "
                 "clear {:+.3f} {}{} near {} p0 [{:+.2f} {:+.2f} {:+.2f}]\n",
                 1e-9 * static_cast<double>(out.t_ns), odometry::to_string(out.tracking),
                 m.map_size, m.count, nearest_m, out.obstacles.count, v_obs.x(), v_obs.y(),
                 v_des.x(), v_des.y(), truth.v_H_mps.x(), truth.v_H_mps.y(),
                 truth.euler_rad.z() * 180.0 / M_PI, truth.clearance_m, m.updated ? "" : m.reason,
                 m.cleared ? " CLEARED" : "", out.obstacles.near_hazard ? 1 : 0,
                 m.count > 0 ? m.p_H_m[0].x() : 0.0, m.count > 0 ? m.p_H_m[0].y() : 0.0,
                 m.count > 0 ? m.p_H_m[0].z() : 0.0);
    }
    if (frames_++ > 0 && timing_ != nullptr) timing_->add(out.durations);
    max_map_size_ = std::max(max_map_size_, out.memory.map_size);
  }
  [[nodiscard]] int max_map_size() const { return max_map_size_; }

 private:
  OperatorPlayer player_;
  pipeline::StageTimingLog* timing_;
  std::FILE* trace_;
  int frames_ = 0;
  int max_map_size_ = 0;
};

struct MemoryOutcome {
  bool collided = false;
  double min_clearance_m = 0.0;
  int max_map_size = 0;
};

/// Flies one run. With `clock` the chain's stages are timed into `timing`.
inline MemoryOutcome fly_memory_run(const MemoryRun& r, bool memory_enabled, const sim::World& room,
                                    const pipeline::Clock* clock = nullptr,
                                    pipeline::StageTimingLog* timing = nullptr,
                                    std::FILE* trace = nullptr) {
  Scenario s = memory_scenario(r, memory_enabled, room);
  TimedPlayer player(OperatorPlayer(s.script, s.vehicle.camera.heading_rad()), timing, trace);
  s.options.clock = clock;
  s.options.operator_source = &player;
  auto loop = s.make();
  loop->run();
  MemoryOutcome o;
  o.collided = loop->collision_ticks() > 0;
  o.min_clearance_m = loop->min_clearance_m();
  o.max_map_size = player.max_map_size();
  return o;
}

}  // namespace hq::closed_loop::testing
