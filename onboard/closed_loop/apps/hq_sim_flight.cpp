// hq-sim-flight: the on-board chain flown in closed loop by the simulator in this process (the
// simulator is the camera, the IMU and the flight controller), either by a scripted operator on
// simulated time, or paced to wall time and commanded by a ground station over DDS (--link).
// The flight binary, hq-onboard, holds no simulator; this program is the simulator's.
//   hq-sim-flight --world onboard/sim/worlds/arena.yaml
//                 --script onboard/closed_loop/flights/core_paper_box.yaml
//                 [--sim-config onboard/sim/config/sim.yaml] [--resolution 320x240] [--seed N]
//                 [--csv fig6-8.csv] [--save-map map.pcd|map.ply]
//   hq-sim-flight --world W --link [--duration-s 0] [--on-stop land|hold] [--link-config
//   config.yaml]
//                 [--domain-id N] [--vehicle-id N] [--command-timeout-ms 200]
//                 [--heartbeat-timeout-ms 2000] [--camera-rate-hz 10] [--link-log link.csv]
//                 [--record DIR]
//
// Scripted: the run ends with the flight summary (estimate and tracking RMSE per axis of H,
// closest distance, collisions) and the CSV holds the signals of the core paper's Fig. 6-8.
// --link: the on-board fail-safes (onboard/link_bridge) judge the ground's commands: stale
// commands hold zero velocity, a silent ground lands the vehicle; --link-log writes one row per
// control step with the mode, the command and heartbeat ages and the simulator's truth.
//
// Exit status: 0 a good run, 2 bad input, 3 a simulated collision, 5 a good flight whose
// --record failed.

#include "hq/base/log.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/config/data_path.hpp"

#include "onboard_runs.hpp"
#include <CLI/CLI.hpp>

#include <cstdio>
#include <optional>
#include <string>

namespace hq::onboard_app {
namespace {

/// The simulator's world, script and camera.
void add_sim_options(CLI::App& app, Options& o) {
  app.add_option("--world", o.world_path, "world file (onboard/sim/worlds/*.yaml)")->required();
  app.add_option("--script", o.script_path,
                 "operator timeline (onboard/closed_loop/flights/*.yaml); without --link");
  app.add_option("--sim-config", o.sim_config_path, "simulator config");
  app.add_option("--resolution", o.resolution, "camera WIDTHxHEIGHT (320x240, 640x480)");
  app.add_option("--seed", o.seed, "noise and gust seed (default: the world's)")
      ->check(CLI::Range(0LL, 2147483647LL));
  app.add_option("--save-map", o.save_map_path,
                 "the obstacle memory's map at the end of the flight (.pcd or .ply)")
      ->check([](const std::string& path) -> std::string {
        const auto ends = [&](const char* ext) {
          return path.size() > 4 && path.compare(path.size() - 4, 4, ext) == 0;
        };
        return ends(".pcd") || ends(".ply") ? "" : path + ": expected a .pcd or .ply file";
      });
  app.add_option("--link-log", o.link_log_path,
                 "--link: per-step CSV of mode, command and heartbeat ages, truth");
}

int run(int argc, char** argv) {
  g_program_name = "hq-sim-flight";
  CLI::App app{"hq-sim-flight: the on-board chain flown in closed loop by the simulator"};
  Options o;
  add_sim_options(app, o);
  add_flight_options(app, o, "the Fig. 6-8 signals of a scripted flight");
  app.add_option("--duration-s", o.duration_s,
                 "--link: run length (default 0: until SIGINT or SIGTERM; a scripted flight "
                 "lasts its script)")
      ->check(CLI::Range(0.0, 86400.0));
  add_ground_link_options(app, o);
  add_stop_options(app, o);
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  // Which file serves, since a relative name may come from the current folder or the install.
  hq::log::note("hq-sim-flight: config {}\n", hq::config::resolve_data_path(o.config_path).c_str());
  return o.link ? run_sim_link(o) : run_sim(o);
}

}  // namespace
}  // namespace hq::onboard_app

int main(int argc, char** argv) {
  // Line-buffered even into a file or a pipe: tests and operators follow the flight as it runs.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  return hq::run_tool("hq-sim-flight", argc, argv, hq::onboard_app::run);
}
