// hq-bench-memory-campaign: the obstacle-memory campaign, the vehicle moving towards a box it saw
// but no longer sees (backing up, sideways, after a yaw while close), each seeded run flown with
// the obstacle memory off and on (same world, noise and script). Prints collisions and the closest
// distance distribution side by side, then the chain's stage timings with each setting (the
// memory stage beside the odometry stage and the whole chain measured in the same flights).
//   hq-bench-memory-campaign [--runs 20] [--seed 20261126]
// Run from the repository root (configs are read from config/ and onboard/).

#include "hq/base/error.hpp"
#include "hq/base/program.hpp"
#include "hq/base/quantile.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/pipeline/stage_timing.hpp"
#include "hq/pipeline/steady_clock.hpp"

#include "memory_campaign.hpp"
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fmt/format.h>
#include <optional>
#include <string>
#include <vector>

namespace {

using hq::closed_loop::testing::MemoryCase;
using hq::closed_loop::testing::MemoryOutcome;

using hq::pipeline::SteadyClock;

struct Column {
  int collisions = 0;
  std::vector<double> clearance_m;
  int max_map_size = 0;
};

using hq::quantile;

void print_stage(const char* setting, const hq::pipeline::StageTimingLog& log) {
  const auto memory = log.statistics(2);
  const auto odometry = log.statistics(0);
  const auto total = log.statistics(5);
  fmt::print(
      "  memory {:<3}  {:7} frames  memory stage median {:.3f} p99 {:.3f} max {:.3f} ms;  odometry "
      "median {:.3f} ms (memory/odometry {:.2f});  total median {:.3f} p99 {:.3f} ms (memory/total "
      "{:.2f})\n",
      setting, log.size(), memory.median_ms, memory.p99_ms, memory.max_ms, odometry.median_ms,
      memory.median_ms / std::max(odometry.median_ms, 1e-9), total.median_ms, total.p99_ms,
      memory.median_ms / std::max(total.median_ms, 1e-9));
}

/// --trace CASE:INDEX: that run only, memory off then on, one line per frame.
int trace_one(const std::string& trace, unsigned seed, const hq::sim::World& room) {
  const auto colon = trace.find(':');
  for (const MemoryCase kind : hq::closed_loop::testing::kMemoryCases) {
    if (colon == std::string::npos ||
        trace.substr(0, colon) != hq::closed_loop::testing::to_string(kind)) {
      continue;
    }
    const auto r =
        hq::closed_loop::testing::draw_memory_run(kind, std::stoi(trace.substr(colon + 1)), seed);
    for (int on = 0; on < 2; ++on) {
      fmt::print("--- {} memory {}\n", trace, on ? "on" : "off");
      hq::closed_loop::testing::fly_memory_run(r, on == 1, room, nullptr, nullptr, stdout);
    }
    return 0;
  }
  throw hq::InputError("--trace " + trace +
                       ": expected CASE:INDEX with CASE one of back-up, "
                       "sideways, yaw-close");
}

/// Every case's runs, each flown with the memory off and on; one line per run.
void fly_campaign(int runs, unsigned seed, const hq::sim::World& room, const SteadyClock& clock,
                  Column (&columns)[3][2], hq::pipeline::StageTimingLog (&timing)[2]) {
  for (int c = 0; c < 3; ++c) {
    const MemoryCase kind = hq::closed_loop::testing::kMemoryCases[c];
    for (int i = 0; i < runs; ++i) {
      const auto r = hq::closed_loop::testing::draw_memory_run(kind, i, seed);
      MemoryOutcome outcome[2];
      for (int on = 0; on < 2; ++on) {
        outcome[on] =
            hq::closed_loop::testing::fly_memory_run(r, on == 1, room, &clock, &timing[on]);
        Column& col = columns[c][on];
        col.collisions += outcome[on].collided ? 1 : 0;
        col.clearance_m.push_back(outcome[on].min_clearance_m);
        col.max_map_size = std::max(col.max_map_size, outcome[on].max_map_size);
      }
      fmt::print(
          "{:<9} run {:2}: {:.2f} m/s, box {:.2f} x {:.2f} at {:.2f} m, turn {:3.0f} deg: closest "
          "off {:+.3f}{}  on {:+.3f}{}\n",
          hq::closed_loop::testing::to_string(kind), i, r.speed_mps, r.box_size_m.x(),
          r.box_size_m.y(), r.distance_m, r.turn_rad * 180.0 / M_PI, outcome[0].min_clearance_m,
          outcome[0].collided ? " COLLIDED" : "", outcome[1].min_clearance_m,
          outcome[1].collided ? " COLLIDED" : "");
      std::fflush(stdout);
    }
  }
}

/// Collisions and closest distances per case, memory off beside on.
void print_columns(int runs, const Column (&columns)[3][2]) {
  fmt::print("closest distance = box surface to the {:.2f} m vehicle sphere (m)\n",
             hq::closed_loop::testing::kVehicleRadiusM);
  fmt::print("{:<10} | {:<36} | {:<36}\n", "case", "memory off", "memory on");
  fmt::print("{:<10} | {:>10} {:>7} {:>7} {:>8} | {:>10} {:>7} {:>7} {:>8}\n", "", "collisions",
             "min", "p10", "median", "collisions", "min", "p10", "median");
  for (int c = 0; c < 3; ++c) {
    fmt::print("{:<10} |",
               hq::closed_loop::testing::to_string(hq::closed_loop::testing::kMemoryCases[c]));
    for (int on = 0; on < 2; ++on) {
      const Column& col = columns[c][on];
      fmt::print(" {:4}/{:<5} {:+7.3f} {:+7.3f} {:+8.3f} {}", col.collisions, runs,
                 quantile(col.clearance_m, 0.0), quantile(col.clearance_m, 0.1),
                 quantile(col.clearance_m, 0.5), on == 0 ? "|" : "\n");
    }
  }
  int largest_map = 0;
  for (const auto& row : columns) largest_map = std::max(largest_map, row[1].max_map_size);
  fmt::print("largest memory map in any run: {} points\n", largest_map);
}

int run(int argc, char** argv) {
  CLI::App app{"hq-bench-memory-campaign: obstacles outside the view, memory off against on"};
  int runs = 20;
  unsigned seed = 20261126;
  app.add_option("--runs", runs, "runs per case")->check(CLI::Range(1, 1000));
  app.add_option("--seed", seed, "campaign seed");
  std::string trace;
  app.add_option("--trace", trace,
                 "CASE:INDEX (e.g. back-up:0): fly that run only, memory off then on, one line "
                 "per frame");
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;

  const hq::sim::World room = hq::sim::load_world("onboard/sim/worlds/room.yaml");
  if (!trace.empty()) return trace_one(trace, seed, room);
  const SteadyClock clock;
  hq::pipeline::StageTimingLog timing[2];
  Column columns[3][2];
  const auto wall_start = std::chrono::steady_clock::now();
  fly_campaign(runs, seed, room, clock, columns, timing);
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();

  fmt::print("\nobstacle memory campaign, {} runs per case, seed {}, 320x240 ({:.0f} s wall)\n",
             runs, seed, wall_s);
  print_columns(runs, columns);
  fmt::print("\nper-frame stage time over every frame of the campaign (wall clock, one thread):\n");
  print_stage("off", timing[0]);
  print_stage("on", timing[1]);
  fmt::print("memory on: chain stages\n");
  timing[1].print(stdout);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return hq::run_tool("hq-bench-memory-campaign", argc, argv, run);
}
