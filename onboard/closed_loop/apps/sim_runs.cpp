// hq-sim-flight's runs: the closed loop flown by a scripted operator on simulated time, or paced
// to wall time and flown by a ground station over DDS (--link).

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/base/log.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/closed_loop/closed_loop.hpp"
#include "hq/closed_loop/flight_summary.hpp"
#include "hq/link/config.hpp"
#include "hq/link_bridge/link_bridge.hpp"
#include "hq/link_bridge/link_operator_port.hpp"
#include "hq/pipeline/stage_timing.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/world.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include "onboard_runs.hpp"
#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fmt/format.h>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace hq::onboard_app {

namespace {

// The DDS link as the closed loop's operator (the same port every vehicle source uses), plus
// one log row per control step with the simulator's truth.
class LoggedLinkPort final : public hq::link_bridge::LinkOperatorPort {
 public:
  LoggedLinkPort(hq::link_bridge::LinkBridge& bridge, const hq::pipeline::OnboardChain& chain,
                 const Eigen::Isometry3d& T_B_C, std::FILE* log)
      : LinkOperatorPort(bridge, chain, T_B_C, stdout), log_(log) {}
  void set_simulator(const hq::sim::Simulator* sim) { sim_ = sim; }

  void on_output(const hq::pipeline::ChainOutput& out,
                 const hq::vehicle::VehicleStatus& status) override {
    LinkOperatorPort::on_output(out, status);
    if (log_ == nullptr || sim_ == nullptr) return;
    const hq::sim::TruthState& truth = sim_->truth();
    const hq::link_bridge::FailsafeState& f = bridge().failsafe().state();
    const hq::link_bridge::FailsafeCounters& c = bridge().failsafe().counters();
    const Eigen::Vector3d& v = f.command.v_H_mps;
    fmt::print(log_,
               "{:.4f},{},{},{},{:.2f},{:.2f},{},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:."
               "4f},{:.4f},{},{},"
               "{},{},{}\n",
               hq::to_seconds(out.t_ns), hq::modes::to_string(out.mode.mode),
               out.mode.landed ? 1 : 0, truth.on_ground ? 0 : 1,
               f.command_age_ns < 0 ? -1.0 : 1e-6 * static_cast<double>(f.command_age_ns),
               f.heartbeat_age_ns < 0 ? -1.0 : 1e-6 * static_cast<double>(f.heartbeat_age_ns),
               f.hold ? 1 : 0, f.heartbeat_lost ? 1 : 0, v.x(), v.y(), v.z(),
               f.command.yaw_rate_radps, truth.v_H_mps.x(), truth.v_H_mps.y(), truth.v_H_mps.z(),
               truth.T_N_B.translation().z(), truth.collision ? 1 : 0, out.estimate.ok() ? 1 : 0,
               static_cast<unsigned long long>(c.commands_accepted),
               static_cast<unsigned long long>(c.commands_rejected),
               static_cast<unsigned long long>(c.mode_requests_rejected));
  }

 private:
  std::FILE* log_;
  const hq::sim::Simulator* sim_ = nullptr;
};

// What both runs fly: the world, the simulator (its --resolution and --seed applied), the
// on-board config and the vehicle file.
struct SimInputs {
  hq::sim::World world;
  hq::sim::SimConfig sim_config;
  hq::pipeline::OnboardConfig config;
  hq::VehicleConfig vehicle;
};

SimInputs load_sim_inputs(const Options& o) {
  SimInputs in{
      hq::sim::load_world(o.world_path), hq::sim::load_sim_config(o.sim_config_path), {}, {}};
  hq::sim::set_resolution(in.sim_config, o.resolution, "--resolution");
  in.sim_config.seed = o.seed >= 0 ? static_cast<std::uint64_t>(o.seed) : in.world.seed;
  in.config = hq::pipeline::load_onboard_config(o.config_path);
  in.vehicle = hq::load_vehicle_config(o.vehicle_path);
  return in;
}

// The recorder's ROS 2 bag and the bridge's ROS 2 topics in simulated time with /clock
// (use_sim_time), with the simulator's camera and the vehicle's camera mount.
void use_simulated_ros_time(hq::onboard_log::OnboardRecorder* recorder,
                            hq::link_bridge::LinkBridge& bridge, const SimInputs& in) {
  if (recorder != nullptr) {
    recorder->set_camera(in.sim_config.camera.pinhole);
    recorder->set_ros_clock(hq::ros2_bridge::RosClock::simulated_time());
  }
  if (bridge.ros2() != nullptr) {
    bridge.ros2()->set_camera(in.sim_config.camera.pinhole);
    bridge.ros2()->set_camera_mount(in.vehicle.camera);
    bridge.ros2()->set_clock(hq::ros2_bridge::RosClock::simulated_time());
  }
}

// --link-log: one CSV row per control step (LoggedLinkPort), or nullptr without the option.
std::FILE* open_link_log(const std::string& path) {
  if (path.empty()) return nullptr;
  std::FILE* log = std::fopen(path.c_str(), "w");
  if (!log) throw hq::InputError(path + ": cannot open for writing");
  // Line-buffered: a row per frame is cheap, and tests follow the flight while it happens.
  std::setvbuf(log, nullptr, _IOLBF, 0);
  fmt::print(log,
             "t_s,mode,landed,airborne,command_age_ms,heartbeat_age_ms,hold,heartbeat_lost,"
             "v_cmd_x_mps,v_cmd_y_mps,v_cmd_z_mps,yaw_rate_cmd_radps,v_true_x_mps,"
             "v_true_y_mps,v_true_z_mps,altitude_m,collision,estimate_ok,commands_accepted,"
             "commands_rejected,mode_requests_rejected\n");
  return log;
}

hq::closed_loop::ClosedLoop make_link_loop(const Options& o, const SimInputs& in) {
  hq::closed_loop::OperatorScript script;
  // Over the link the script gives only the length the flight record is sized for.
  script.end_s = o.duration_s > 0.0 ? o.duration_s : 600.0;
  hq::closed_loop::ClosedLoopOptions options;
  options.realtime = true;
  return hq::closed_loop::ClosedLoop(
      in.sim_config, in.world, in.config, in.vehicle,
      hq::closed_loop::OperatorPlayer(script, in.vehicle.camera.heading_rad()), options);
}

// Paced to wall time in 0.1 s steps until --duration-s (0: forever) or SIGINT/SIGTERM.
void fly_until_stopped(const Options& o, hq::closed_loop::ClosedLoop& loop,
                       const std::string& world_name) {
  std::signal(SIGINT, request_stop);
  std::signal(SIGTERM, request_stop);
  hq::log::note(
      "hq-sim-flight: simulated {} over the link: {}, command timeout {:.0f} ms, "
      "heartbeat timeout {:.0f} ms\n",
      world_name.c_str(),
      o.duration_s > 0.0 ? fmt::format("{:.1f} s", o.duration_s).c_str()
                         : "until SIGINT or SIGTERM",
      o.command_timeout_ms, o.heartbeat_timeout_ms);
  const double end_s = o.duration_s > 0.0 ? o.duration_s : std::numeric_limits<double>::max();
  double t_s = 0.0;
  while (t_s < end_s && !g_stop) {
    t_s = std::min(end_s, t_s + 0.1);
    loop.run_until(t_s);
  }
}

// However the run ends, the vehicle lands (or holds) and says goodbye to the ground.
void land_and_say_goodbye(const Options& o, hq::closed_loop::ClosedLoop& loop,
                          hq::link_bridge::LinkBridge& bridge) {
  StopOutcome stop;
  if (g_stop) {
    stop.reason = signal_reason();
  } else {
    char text[64];
    hq::format_into(text, "run length {:g} s reached", o.duration_s);
    stop.reason = text;
  }
  wind_down(
      o, loop.runtime(), loop.t_ns(),
      [&loop] {
        loop.run_until(hq::to_seconds(loop.t_ns()) + 0.01);
        return loop.t_ns();
      },
      stop);
  say_goodbye(bridge, loop.t_ns(), stop);
}

void print_link_flight_report(const hq::closed_loop::ClosedLoop& loop,
                              const hq::link_bridge::LinkBridge& bridge,
                              const hq::closed_loop::FlightSummary& summary,
                              const std::string& world_name) {
  hq::closed_loop::print_summary(stdout, "flight summary over the link (" + world_name + ")",
                                 summary);
  const bool landed = !loop.samples().empty() && loop.samples().back().landed;
  const bool on_ground = loop.simulator().truth().on_ground;
  print_link_summary(bridge);
  hq::log::info("  {:<40} {:.1f} ms\n", "largest lag behind real time",
                1e3 * loop.max_realtime_lag_s());
  hq::log::info("  {:<40} {} (vehicle believes {})\n", "final state",
                on_ground ? "on the ground" : "in the air",
                landed ? "landed, motors idle" : "flying");
  for (const std::string& refusal : loop.refusals()) {
    hq::log::info("  mode request refused at {}\n", refusal.c_str());
  }
}

}  // namespace

int run_sim_link(const Options& o) {
  if (o.world_path.empty()) throw hq::InputError("--link needs --world <world.yaml>");
  const SimInputs in = load_sim_inputs(o);
  // --record: before the link, so an unwritable folder stops the start.
  const std::unique_ptr<hq::onboard_log::OnboardRecorder> recorder = make_recorder(o, in.vehicle);
  const std::unique_ptr<hq::link_bridge::LinkBridge> link_bridge = make_link_bridge(o);
  hq::link_bridge::LinkBridge& bridge = *link_bridge;
  use_simulated_ros_time(recorder.get(), bridge, in);

  std::FILE* log = open_link_log(o.link_log_path);
  hq::closed_loop::ClosedLoop loop = make_link_loop(o, in);
  // The vehicle's own extrinsics (not the simulator's truth) place the cloud in the body.
  LoggedLinkPort port(bridge, loop.chain(), in.vehicle.camera.T_B_C(), log);
  port.set_simulator(&loop.simulator());
  // --record: the recorder behind the port (chain outputs; the simulator's IMU is not tapped).
  std::optional<hq::onboard_log::RecordingPort> record_port;
  if (recorder) record_port.emplace(&port, *recorder);
  loop.set_operator_port(record_port ? static_cast<hq::vehicle::OperatorPort*>(&*record_port)
                                     : &port);
  fly_until_stopped(o, loop, in.world.name);
  land_and_say_goodbye(o, loop, bridge);
  if (log && std::fclose(log) != 0) throw hq::InputError(o.link_log_path + ": write failed");

  const hq::closed_loop::FlightSummary summary = hq::closed_loop::summarise(loop);
  print_link_flight_report(loop, bridge, summary, in.world.name);
  const bool record_ok =
      !recorder || close_recorder(*recorder,
                                  {{"source", "simulator " + in.world.name},
                                   {"steps", std::to_string(loop.samples().size())},
                                   {"collision_ticks", std::to_string(summary.collision_ticks)}},
                                  &bridge);
  return with_record_status(summary.collision_ticks == 0 ? 0 : 3, record_ok);
}

int run_sim(const Options& o) {
  if (o.world_path.empty() || o.script_path.empty()) {
    throw hq::InputError(
        "hq-sim-flight needs --world <world.yaml> and --script <timeline.yaml> (or --link)");
  }
  if (!o.record_dir.empty()) {
    throw hq::InputError("--record " + o.record_dir +
                         ": a scripted flight records with --link only (it has its CSV, --csv)");
  }
  const SimInputs in = load_sim_inputs(o);
  const hq::sim::World& world = in.world;
  const hq::sim::SimConfig& sim_config = in.sim_config;
  const hq::pipeline::OnboardConfig& config = in.config;
  const hq::VehicleConfig& vehicle = in.vehicle;
  hq::closed_loop::OperatorPlayer player(hq::closed_loop::load_operator_script(o.script_path),
                                         vehicle.camera.heading_rad());
  const SteadyClock clock;
  hq::closed_loop::ClosedLoopOptions options;
  options.clock = &clock;
  hq::closed_loop::ClosedLoop loop(sim_config, world, config, vehicle, std::move(player), options);
  hq::log::note("hq-sim-flight: simulated {}, {}x{}, seed {}, script {} ({:.1f} s)\n", world.name,
                sim_config.camera.pinhole.width, sim_config.camera.pinhole.height, sim_config.seed,
                o.script_path, loop.player().script().end_s);
  const std::int64_t wall_start_ns = hq::monotonic_now_ns();
  loop.run();
  const double wall_s = hq::to_seconds(hq::monotonic_now_ns() - wall_start_ns);

  const hq::closed_loop::FlightSummary summary = hq::closed_loop::summarise(loop);
  hq::closed_loop::print_summary(stdout, "flight summary (" + world.name + ")", summary);
  hq::log::info("  {:<40} {}\n", "obstacle memory (outside the view)",
                config.memory.enabled ? "on" : "off");
  hq::log::info("  {:<40} {:.1f}x real time ({:.1f} s wall)\n", "simulation speed",
                summary.duration_s / std::max(wall_s, 1e-9), wall_s);
  for (const std::string& refusal : loop.refusals()) {
    hq::log::info("  mode request refused at {}\n", refusal.c_str());
  }
  hq::log::info("per-stage time from frame arrival to setpoint:\n");
  loop.timing().print(stdout);
  if (!o.save_map_path.empty()) {
    // The obstacle memory's map at the end of the flight (points in the world of the
    // odometry), for PCL's viewers and CloudCompare.
    loop.chain().memory().save(o.save_map_path);
    hq::log::info("obstacle memory map ({} points) written to {}\n", loop.chain().memory().size(),
                  o.save_map_path.c_str());
  }
  if (!o.csv_path.empty()) {
    hq::closed_loop::write_figure_csv(o.csv_path, loop.samples());
    hq::log::info("Fig. 6-8 signals written to {}\n", o.csv_path.c_str());
  }
  return summary.collision_ticks == 0 ? 0 : 3;
}

}  // namespace hq::onboard_app
