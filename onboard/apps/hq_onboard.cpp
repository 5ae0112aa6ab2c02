// hq-onboard: the on-board chain (odometry -> velocity estimator -> obstacle field -> modes ->
// velocity PID) on a frame source, printing a live status line and the per-stage timing.
//   hq-onboard --source replay <sequence-dir> --camera calib/tum_fr1.yaml
//              [--config config/onboard.yaml] [--vehicle calib/vehicle_core_paper.yaml]
//              [--csv out.csv]
//   hq-onboard --source sim --world onboard/sim/worlds/arena.yaml
//              --script onboard/closed_loop/flights/core_paper_box.yaml
//              [--sim-config onboard/sim/config/sim.yaml] [--resolution 320x240] [--seed N]
//              [--csv fig6-8.csv] [--save-map map.pcd|map.ply]
//   hq-onboard --source sim --world W --link [--duration-s 60] [--link-config config.yaml]
//              [--domain-id N] [--vehicle-id N] [--command-timeout-ms 200]
//              [--heartbeat-timeout-ms 2000] [--camera-rate-hz 10] [--link-log link.csv]
//   hq-onboard --source sitl [--fc mavlink:udp:127.0.0.1:14560] [--channel sitl] [--link]
//   hq-onboard --source openni2|freenect [--fc none|mavlink:serial:/dev/ttyACM0:921600] [--link]
//   hq-onboard ... --record DIR        the on-board MCAP flight log, DIR/onboard.mcap
//
// Exit status: 0 a good run, 2 bad input, 3 a simulated collision, 4 the flight controller
// lost, 5 a good flight whose --record failed (disk full; the flight went on without it).
//
// Every source but the in-process sim runs through one VehicleRuntime (onboard/vehicle) with a
// flight controller (--fc): none (replay, bench), or MAVLink to PX4/ArduPilot or hq-sim --sitl.
// --link works with every source.
//
// Sim with --link: the closed loop is paced to wall time and flown by a ground station over DDS
// (hq-ground) instead of the script, through the on-board fail-safes (onboard/link_bridge):
// stale commands hold zero velocity, a silent ground lands the vehicle. --link-log writes one
// row per control step with the mode and the command and heartbeat ages.
//
// Sim: the simulator flies the chain in closed loop on simulated time, commanded by the
// scripted operator; the run ends with the flight summary (estimate and tracking RMSE per axis
// of H, closest distance, collisions) and the CSV holds the signals of the core paper's
// Fig. 6-8.
//

#include "hq/base/error.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/config/data_path.hpp"
#include "hq/link/config.hpp"
#include "hq/sources/camera_sources.hpp"

#include "onboard_runs.hpp"
#include <CLI/CLI.hpp>

#include <atomic>
#include <cstdio>
#include <string>

namespace hq::onboard_app {

std::atomic<bool> g_stop{false};

void request_stop(int /*signal*/) { g_stop = true; }

namespace {

/// --source and what every vehicle run takes: files, the flight controller, the duration.
void add_vehicle_options(CLI::App& app, Options& o) {
  std::string kinds =
      "replay (a TUM-layout sequence) | sim (closed loop in simulation) | sitl (hq-sim --sitl's "
      "frame channel)";
  for (const std::string& camera : hq::sources::available_camera_sources()) {
    kinds +=
        " | " + camera + (camera == "openni2" ? "[:uri] (Xtion, .oni)" : "[:index] (Kinect v1)");
  }
  app.add_option("--source", o.source_kind, "frame source: " + kinds)->required();
  app.add_option("sequence-dir", o.sequence_dir, "sequence folder for --source replay");
  app.add_option(
      "--camera", o.camera_path,
      "replay: camera file, e.g. calib/tum_fr1.yaml; cameras: intrinsics instead of the device's");
  app.add_option("--config", o.config_path, "on-board config");
  app.add_option("--vehicle", o.vehicle_path, "vehicle file (mass, limits, T_body_camera)");
  app.add_option("--csv", o.csv_path,
                 "replay: per-frame estimates and setpoints; sim: the Fig. 6-8 signals");
  app.add_option("--fc", o.fc_spec,
                 "flight controller: none | mavlink:udp:HOST:PORT | mavlink:serial:DEVICE:BAUD "
                 "(default: none; sitl: mavlink:udp:127.0.0.1:14560)");
  app.add_option("--fc-max-thrust-n", o.fc_max_thrust_n,
                 "MAVLink: collective thrust at full throttle, for the normalised thrust")
      ->check(CLI::Range(1.0, 1000.0));
  app.add_option("--channel", o.sitl_channel, "sitl: hq-sim's frame channel name");
  app.add_option("--fc-lost-exit-s", o.fc_lost_exit_s,
                 "stop once the flight controller is lost this long (0: never; default 3 s "
                 "for sitl, never otherwise)")
      ->check(CLI::Range(0.0, 3600.0));
  app.add_option("--sitl-wait-s", o.sitl_wait_s, "sitl: wait this long for hq-sim to start")
      ->check(CLI::Range(0.0, 600.0));
  app.add_option("--duration-s", o.duration_s, "sim --link, sitl and cameras: run length")
      ->check(CLI::Range(0.1, 86400.0));
  app.add_option("--record", o.record_dir,
                 "write the flight's on-board MCAP log to DIR/onboard.mcap (link samples as CDR, "
                 "IMU, estimates, setpoints, stage timings)");
}

/// The in-process simulator's world, script and camera.
void add_sim_options(CLI::App& app, Options& o) {
  app.add_option("--world", o.world_path, "sim: world file (onboard/sim/worlds/*.yaml)");
  app.add_option("--script", o.script_path,
                 "sim: operator timeline (onboard/closed_loop/flights/*.yaml)");
  app.add_option("--sim-config", o.sim_config_path, "sim: simulator config");
  app.add_option("--resolution", o.resolution, "sim: camera WIDTHxHEIGHT (320x240, 640x480)");
  app.add_option("--seed", o.seed, "sim: noise and gust seed (default: the world's)")
      ->check(CLI::Range(0LL, 2147483647LL));
  app.add_option("--save-map", o.save_map_path,
                 "sim: the obstacle memory's map at the end of the flight (.pcd or .ply)")
      ->check([](const std::string& path) -> std::string {
        const auto ends = [&](const char* ext) {
          return path.size() > 4 && path.compare(path.size() - 4, 4, ext) == 0;
        };
        return ends(".pcd") || ends(".ply") ? "" : path + ": expected a .pcd or .ply file";
      });
}

/// --link: the ground station over DDS and the on-board fail-safes.
void add_ground_link_options(CLI::App& app, Options& o) {
  app.add_flag("--link", o.link,
               "fly commanded by a ground station over DDS (sim: paced to real time)");
  app.add_option("--link-config", o.link_config_path, "--link: YAML with a link: section");
  hq::link::add_link_options(app, o.link_overrides);
  app.add_option("--command-timeout-ms", o.command_timeout_ms,
                 "--link: no fresh command this long -> hold zero velocity")
      ->check(CLI::Range(1.0, 10000.0));
  app.add_option("--heartbeat-timeout-ms", o.heartbeat_timeout_ms,
                 "--link: no ground heartbeat this long -> land")
      ->check(CLI::Range(1.0, 60000.0));
  app.add_option("--hold-to-land-s", o.hold_to_land_s,
                 "--link: still no fresh command this long after the hold began -> land")
      ->check(CLI::Range(0.1, 600.0));
  app.add_option("--camera-rate-hz", o.camera_rate_hz,
                 "--link: JPEG frames to the ground (0: none)")
      ->check(CLI::Range(0.0, 60.0));
  app.add_option("--link-log", o.link_log_path,
                 "sim --link: per-step CSV of mode, command and heartbeat ages, truth");
}

int run(int argc, char** argv) {
  CLI::App app{"hq-onboard: the on-board velocity chain of the core paper on a frame source"};
  Options o;
  add_vehicle_options(app, o);
  add_sim_options(app, o);
  add_ground_link_options(app, o);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  // Which file serves, since a relative name may come from the current folder or the install.
  std::fprintf(stderr, "hq-onboard: config %s\n",
               hq::config::resolve_data_path(o.config_path).c_str());
  if (o.source_kind == "sim") {
    if (!o.fc_spec.empty()) {
      throw hq::InputError(
          "--source sim is its own flight controller; for MAVLink run hq-sim "
          "--sitl and hq-onboard --source sitl --fc mavlink:udp:HOST:PORT");
    }
    return o.link ? run_sim_link(o) : run_sim(o);
  }
  return run_vehicle(o);
}

}  // namespace
}  // namespace hq::onboard_app

int main(int argc, char** argv) {
  // Line-buffered even into a file or a pipe: the events of a flight (FC lost, fail-safes) are
  // read by operators and tests while it runs, not after it ends.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  return hq::run_tool("hq-onboard", argc, argv, hq::onboard_app::run);
}
