// hq-onboard: the on-board chain (odometry -> velocity estimator -> obstacle field -> modes ->
// velocity PID) on a frame source, printing a live status line and the per-stage timing.
//   hq-onboard --source replay <sequence-dir> --camera calib/tum_fr1.yaml
//              [--config config/onboard.yaml] [--vehicle calib/vehicle_core_paper.yaml]
//              [--csv out.csv]
//   hq-onboard --source sitl [--fc mavlink:udp:127.0.0.1:14560] [--channel sitl] [--link]
//   hq-onboard --source openni2|freenect [--fc none|mavlink:serial:/dev/ttyACM0:921600] [--link]
//   hq-onboard ... --fc mavlink:... --gcs udp:LAPTOP:14550 | udp-listen:PORT   the FC's MAVLink
//              routed to and from a GCS (QGroundControl) beside the companion
//   hq-onboard ... --link [--link-config config.yaml] [--domain-id N] [--vehicle-id N]
//              [--command-timeout-ms 200] [--heartbeat-timeout-ms 2000] [--camera-rate-hz 10]
//   hq-onboard ... --record DIR        the on-board MCAP flight log, DIR/onboard.mcap
//   hq-onboard ... [--duration-s 0] [--on-stop land|hold] [--stop-timeout-s 30]
//              however the run ends (its length, SIGINT/SIGTERM, the FC or camera lost) the
//              vehicle lands (or holds), then says goodbye to the ground with the reason
//
// Exit status: 0 a good run (also when stopped by SIGINT or SIGTERM), 2 bad input, 4 the flight
// controller lost, 5 a good flight whose --record failed (disk full; the flight went on without
// it), 6 the camera or the FC's serial port absent or busy at start (hq-onboard.service starts
// it again for 6, never for 2).
//
// Every source runs through one VehicleRuntime (onboard/vehicle) with a flight controller
// (--fc): none (replay, bench), or MAVLink to PX4/ArduPilot or hq-sim --sitl. --link works with
// every source. The flight binary holds no simulator: the in-process simulated flight (the
// simulator as camera and flight controller in this process) is hq-sim-flight.

#include "hq/base/error.hpp"
#include "hq/base/log.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/config/data_path.hpp"
#include "hq/link/config.hpp"
#include "hq/sources/camera_sources.hpp"

#include "onboard_runs.hpp"
#include <CLI/CLI.hpp>

#include <cstdio>
#include <optional>
#include <string>

namespace hq::onboard_app {

namespace {

/// --source and what every vehicle run takes: files, the flight controller, the duration.
void add_vehicle_options(CLI::App& app, Options& o) {
  std::string kinds = "replay (a TUM-layout sequence) | sitl (hq-sim --sitl's frame channel)";
  for (const std::string& camera : hq::sources::available_camera_sources()) {
    kinds +=
        " | " + camera + (camera == "openni2" ? "[:uri] (Xtion, .oni)" : "[:index] (Kinect v1)");
  }
  app.add_option("--source", o.source_kind, "frame source: " + kinds)->required();
  app.add_option("sequence-dir", o.sequence_dir, "sequence folder for --source replay");
  app.add_option(
      "--camera", o.camera_path,
      "replay: camera file, e.g. calib/tum_fr1.yaml; cameras: intrinsics instead of the device's");
  app.add_option("--fc", o.fc_spec,
                 "flight controller: none | mavlink:udp:HOST:PORT | mavlink:serial:DEVICE:BAUD "
                 "(default: none; sitl: mavlink:udp:127.0.0.1:14560)");
  app.add_option("--gcs", o.gcs_spec,
                 "MAVLink: route the FC's traffic to and from a ground control station: "
                 "udp:HOST:PORT (a GCS listening there, QGroundControl: 14550) | "
                 "udp-listen:[HOST:]PORT (learn the GCS's address from what it sends)");
  app.add_option(
         "--fc-max-thrust-n", o.fc_max_thrust_n,
         "MAVLink: collective thrust at full throttle, for the normalised thrust: a starting "
         "value, learnt in flight (hover_thrust: in the onboard config)")
      ->check(CLI::Range(1.0, 1000.0));
  app.add_option("--fc-velocity-message", o.fc_velocity_message,
                 "MAVLink: the velocity's message: odometry (PX4's EKF2 reads only this) | "
                 "vision_speed_estimate (ArduPilot)")
      ->check(CLI::IsMember({"odometry", "vision_speed_estimate"}));
  app.add_option("--channel", o.sitl_channel, "sitl: hq-sim's frame channel name");
  app.add_option("--fc-lost-exit-s", o.fc_lost_exit_s,
                 "stop once the flight controller is lost this long (0: never; default 3 s "
                 "for sitl, never otherwise)")
      ->check(CLI::Range(0.0, 3600.0));
  app.add_option("--sitl-wait-s", o.sitl_wait_s, "sitl: wait this long for hq-sim to start")
      ->check(CLI::Range(0.0, 600.0));
}

int run(int argc, char** argv) {
  CLI::App app{"hq-onboard: the on-board velocity chain of the core paper on a frame source"};
  Options o;
  add_vehicle_options(app, o);
  add_flight_options(app, o, "replay: per-frame estimates and setpoints");
  // A vehicle's run lasts until it is stopped unless a length is asked for: one that ended by
  // itself mid-flight would leave its operator with a vehicle gone.
  app.add_option("--duration-s", o.duration_s,
                 "sitl and cameras: run length (default 0: until SIGINT or SIGTERM)")
      ->check(CLI::Range(0.0, 86400.0));
  add_ground_link_options(app, o);
  add_stop_options(app, o);
  // Before parsing: the simulator's options (--world, --script) would be refused first, with
  // less to say.
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--source=sim" ||
        (arg == "--source" && i + 1 < argc && std::string(argv[i + 1]) == "sim")) {
      throw hq::InputError(
          "--source sim: the in-process simulated flight is its own program, so that the flight "
          "binary holds no simulator: hq-sim-flight --world W (--script S | --link) takes the "
          "same options; for the simulator as a separate flight controller, hq-sim --sitl with "
          "hq-onboard --source sitl");
    }
  }
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  // Which file serves, since a relative name may come from the current folder or the install.
  hq::log::note("hq-onboard: config {}\n", hq::config::resolve_data_path(o.config_path).c_str());
  try {
    return run_vehicle(o);
  } catch (const hq::DeviceUnavailableError& e) {
    hq::log::note("hq-onboard: {}\n", e.what());
    return kDeviceUnavailableExitStatus;
  }
}

}  // namespace
}  // namespace hq::onboard_app

int main(int argc, char** argv) {
  // Line-buffered even into a file or a pipe: the events of a flight (FC lost, fail-safes) are
  // read by operators and tests while it runs, not after it ends.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  return hq::run_tool("hq-onboard", argc, argv, hq::onboard_app::run);
}
