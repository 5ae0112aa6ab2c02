// hq-sim: flies a scripted, truth-stabilised attitude/thrust sequence in a simulated world and
// records it in the TUM RGB-D layout (with IMU), giving the odometry team ground-truthed runs.
//   hq-sim --world onboard/sim/worlds/arena.yaml --duration-s 10 --record out_dir
//          [--resolution 640x480] [--seed N] [--script hover|circle] [--yaw-rate-degps R]
//          [--start-yaw-deg Y] [--config onboard/sim/config/sim.yaml]
// hq-sim --sitl: the same simulator as a separate SITL process, paced to real time, playing a
// PX4-like flight controller over MAVLink and publishing its RGB-D frames into shared memory
// for hq-onboard --source sitl (SIGINT/SIGTERM or --duration-s end it with a summary).
//   hq-sim --sitl --world onboard/sim/worlds/arena.yaml [--resolution 320x240] [--seed N]
//          [--mavlink udp-listen:14560] [--channel sitl] [--duration-s S] [--config ...]
#include "hq/base/error.hpp"
#include "hq/base/log.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/sim/scripted_flight.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/tum_writer.hpp"
#include "hq/sitl/sitl_runner.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <signal.h>
#include <string>
#include <vector>

namespace {

std::atomic<bool> g_stop{false};

void request_stop(int /*signal*/) { g_stop.store(true); }

/// SIGINT and SIGTERM end a SITL run cleanly (summary printed, frame channel unlinked).
void install_stop_handlers() {
  struct sigaction action {};
  action.sa_handler = request_stop;
  sigemptyset(&action.sa_mask);
  action.sa_flags = 0;  // no SA_RESTART: a sleep returns early
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

/// The command line.
struct Options {
  std::string world_path;
  std::string config_path = "onboard/sim/config/sim.yaml";
  std::string record_dir;
  std::string resolution = "320x240";
  std::string script_kind = "hover";
  double duration_s = 10.0;
  long long seed = -1;
  bool sitl = false;
  hq::sitl::SitlOptions sitl_options;
  double yaw_rate_degps = -1.0;
  std::optional<double> start_yaw_deg;
};

void add_options(CLI::App& app, Options& o) {
  app.add_option("--world", o.world_path, "world YAML (onboard/sim/worlds/*.yaml)")->required();
  app.add_option("--config", o.config_path,
                 "sim config YAML (default: the shipped onboard/sim/config/sim.yaml)");
  app.add_option("--duration-s", o.duration_s, "simulated seconds")->check(CLI::Range(0.1, 3600.0));
  app.add_option("--record", o.record_dir, "output directory (TUM RGB-D layout)");
  app.add_option("--resolution", o.resolution, "WIDTHxHEIGHT, e.g. 320x240 or 640x480");
  app.add_option("--seed", o.seed, "noise and gust seed (default: the world's seed)")
      ->check(CLI::Range(0LL, 2147483647LL));
  app.add_option("--script", o.script_kind, "hover | circle")
      ->check(CLI::IsMember({"hover", "circle"}));
  app.add_flag("--sitl", o.sitl,
               "run as a real-time SITL process: MAVLink flight controller, frames in shared "
               "memory (without --duration-s: until SIGINT/SIGTERM)");
  app.add_option("--mavlink", o.sitl_options.mavlink_spec,
                 "with --sitl: MAVLink transport spec (udp-listen:[HOST:]PORT, udp:HOST:PORT, "
                 "serial:DEV:BAUD)");
  app.add_option("--channel", o.sitl_options.channel,
                 "with --sitl: frame channel name, shared memory /hq-<name>");
  app.add_option("--yaw-rate-degps", o.yaw_rate_degps,
                 "yaw rate of the circle script (default: the script's slow turn)")
      ->check(CLI::Range(0.0, 360.0));
  app.add_option("--start-yaw-deg", o.start_yaw_deg,
                 "vehicle heading at the start (default: the world's start.yaw_deg)")
      ->check(CLI::Range(-180.0, 180.0));
}

/// The scripted flight as fast as it simulates, recorded in the TUM layout when asked.
int fly_script(hq::sim::Simulator& sim, const hq::sim::World& world, const Options& o) {
  const hq::sim::SimConfig& config = sim.config();
  hq::sim::FlightScript script = hq::sim::script_for_world(
      world, o.script_kind == "circle" ? hq::sim::FlightScript::Kind::kCircle
                                       : hq::sim::FlightScript::Kind::kHover);
  if (o.yaw_rate_degps >= 0.0) script.circle_yaw_rate_radps = o.yaw_rate_degps * M_PI / 180.0;

  std::unique_ptr<hq::sim::TumWriter> writer;
  if (!o.record_dir.empty()) {
    writer = std::make_unique<hq::sim::TumWriter>(o.record_dir, config.camera.pinhole,
                                                  config.camera.T_B_C);
  }
  std::vector<hq::sim::ImuSample> imu(2000);
  cv::Mat image, depth;
  std::size_t frames = 0;
  std::size_t imu_samples = 0;
  double min_clearance_m = 1e9;
  const auto end_ns = static_cast<std::int64_t>(std::llround(o.duration_s * 1e9));
  for (std::int64_t t = 0; t <= end_ns; t += hq::sim::kScriptControlPeriodNs) {
    sim.set_command(hq::sim::scripted_command(sim, script, static_cast<double>(t) * 1e-9));
    sim.step_to(t);
    const std::size_t n = sim.take_imu(imu.data(), imu.size());
    imu_samples += n;
    if (writer) {
      for (std::size_t i = 0; i < n; ++i) writer->write_imu(imu[i]);
    }
    if (sim.camera_due()) {
      const std::int64_t t_frame = sim.camera_t_ns();
      const Eigen::Isometry3d T_N_C = sim.camera_T_N_C();
      sim.render_camera(image, depth);
      if (writer) writer->write_frame(t_frame, image, depth, T_N_C);
      ++frames;
    }
    if (!sim.truth().on_ground) {
      min_clearance_m = std::min(min_clearance_m, sim.truth().clearance_m);
    }
  }
  if (writer) writer->close();

  const Eigen::Vector3d p_N_m = sim.truth().T_N_B.translation();
  hq::log::info(
      "hq-sim: {}, script {}, seed {}, {:.1f} s: {} frames ({}x{}), {} IMU samples, "
      "{} dropped frames\n",
      world.name.c_str(), o.script_kind.c_str(), static_cast<unsigned long long>(config.seed),
      o.duration_s, frames, config.camera.pinhole.width, config.camera.pinhole.height, imu_samples,
      static_cast<long long>(sim.dropped_frames()));
  hq::log::info("final position [{:.2f} {:.2f} {:.2f}] m, min clearance {:.2f} m, collision {}\n",
                p_N_m.x(), p_N_m.y(), p_N_m.z(), min_clearance_m, sim.collided() ? "YES" : "no");
  if (writer) hq::log::info("recorded to {}\n", o.record_dir.c_str());
  return 0;
}

int run(int argc, char** argv) {
  CLI::App app{"hq-sim: scripted flight in a simulated world, recorded as a TUM RGB-D sequence"};
  Options o;
  add_options(app, o);
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;

  hq::sim::World world = hq::sim::load_world(o.world_path);
  if (o.start_yaw_deg) world.start_yaw_rad = *o.start_yaw_deg * M_PI / 180.0;
  hq::sim::SimConfig config = hq::sim::load_sim_config(o.config_path);
  hq::sim::set_resolution(config, o.resolution, "--resolution");
  config.seed = o.seed >= 0 ? static_cast<std::uint64_t>(o.seed) : world.seed;

  hq::sim::Simulator sim(config, world);
  if (o.sitl) {
    o.sitl_options.duration_s = app.count("--duration-s") > 0 ? o.duration_s : 0.0;
    install_stop_handlers();
    return hq::sitl::run_sitl(sim, o.sitl_options, g_stop);
  }
  if (app.count("--mavlink") > 0 || app.count("--channel") > 0) {
    throw hq::InputError("--mavlink and --channel need --sitl");
  }
  return fly_script(sim, world, o);
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-sim", argc, argv, run); }
