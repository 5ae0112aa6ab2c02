// hq-ground: the operator's station. Runs the 1 kHz haptic loop on a device, publishes its
// velocity command (eq. 6-10) and heartbeats over DDS, feeds the force feedback with the vehicle
// state it receives, toggles modes from the device's buttons (button 0: teleop <-> hover,
// button 1: land) and shows link and vehicle status in the terminal.
//   hq-ground --device sim|keyboard|joystick|forcedim [--headless] [--duration-s N]
//             [--haptics-config config/haptics.yaml] [--vehicle calib/vehicle_core_paper.yaml]
//             [--link-config F] [--domain-id N] [--vehicle-id N] [--station-id N]
//             [--station-strength N] [--command-rate-hz 50] [--record DIR]
#include "hq/base/error.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/control/vehicle_config.hpp"
#include "hq/ground/ground_station.hpp"
#include "hq/haptics/haptic_device.hpp"
#include "hq/haptics/haptic_loop.hpp"
#include "hq/haptics/haptics_config.hpp"
#include "hq/link/config.hpp"

#include <CLI/CLI.hpp>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>

namespace {

std::atomic<bool> g_stop{false};
void request_stop(int /*signal*/) { g_stop = true; }

struct Options {
  std::string device = "sim";
  bool headless = false;
  double duration_s = 0.0;
  std::string haptics_path = "config/haptics.yaml";
  std::string vehicle_path = "calib/vehicle_core_paper.yaml";
  std::string link_config_path;
  hq::link::LinkOverrides link_overrides;
  double command_rate_hz = 50.0;
  std::string record_dir;
};

void print_status(std::FILE* out, bool live, double t_s, const hq::ground::GroundStation& ground,
                  const hq::haptics::LoopOutput& hand) {
  const hq::ground::LinkStatus& s = ground.status();
  const double age_s = ground.state_age_s();
  const char* link = !s.have_state ? "waiting" : age_s < 0.2 ? "ok" : age_s < 2.0 ? "STALE" : "LOST";
  const auto& v = hand.command.v_H_mps;
  std::fprintf(out,
               "%st %6.1f s  link %-7s  vehicle %-7s est %-8s vlink %-8s  latency %5.2f ms  "
               "cmd [%+.2f %+.2f %+.2f] yaw %+.2f  |F| %.1f N  %s%s",
               live ? "\r" : "", t_s, link,
               s.have_state ? hq::ground::to_string(s.state.mode) : "-",
               s.have_state ? hq::ground::to_string(s.state.estimator_health) : "-",
               s.have_state ? hq::ground::to_string(s.state.link_health) : "-",
               1e-6 * static_cast<double>(s.last_latency_ns), v.x(), v.y(), v.z(),
               hand.command.yaw_rate_radps, hand.F_D_n.norm(),
               hand.device_connected ? "" : "DEVICE LOST ", s.last_event.data());
  std::fprintf(out, live ? "\033[K" : "\n");
  std::fflush(out);
}

int run(int argc, char** argv) {
  CLI::App app{"hq-ground: haptic teleoperation of a vehicle over the DDS link"};
  Options o;
  app.add_option("--device", o.device, "haptic device")
      ->check(CLI::IsMember({"sim", "keyboard", "joystick", "forcedim"}));
  app.add_flag("--headless", o.headless, "no live status line: one status line per second");
  app.add_option("--duration-s", o.duration_s, "stop after this long (0: until Ctrl-C)")
      ->check(CLI::Range(0.0, 86400.0));
  app.add_option("--haptics-config", o.haptics_path, "mapping, feedback, loop and device config");
  app.add_option("--vehicle", o.vehicle_path, "vehicle file (R_QC gives eq. 9's alpha)");
  app.add_option("--link-config", o.link_config_path, "YAML with a link: section");
  hq::link::add_link_options(app, o.link_overrides);
  app.add_option("--command-rate-hz", o.command_rate_hz, "velocity commands sent per second")
      ->check(CLI::Range(5.0, 1000.0));
  app.add_option("--record", o.record_dir, "write received telemetry and events as CSV here");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  hq::link::LinkConfig link = o.link_config_path.empty()
                                  ? hq::link::LinkConfig{}
                                  : hq::link::load_link_config(o.link_config_path);
  hq::link::apply_overrides(o.link_overrides, link);
  const hq::haptics::HapticsConfig haptics = hq::haptics::load_haptics_config(o.haptics_path);
  const hq::control::VehicleConfig vehicle = hq::control::load_vehicle_config(o.vehicle_path);
  hq::haptics::DeviceOptions device_options;
  device_options.config = haptics;
  device_options.terminal_fd = STDIN_FILENO;
  std::unique_ptr<hq::haptics::HapticDevice> device =
      hq::haptics::open_device(o.device, device_options);

  std::unique_ptr<hq::ground::TelemetryRecorder> recorder;
  if (!o.record_dir.empty()) recorder = std::make_unique<hq::ground::TelemetryRecorder>(o.record_dir);
  hq::ground::GroundStation ground(link, recorder.get());
  hq::haptics::HapticLoop loop(*device, haptics, vehicle.R_body_camera);
  std::signal(SIGINT, request_stop);
  std::signal(SIGTERM, request_stop);
  const hq::haptics::RealtimeGrant grant = loop.start();
  std::fprintf(stderr,
               "hq-ground: device %s, domain %d, vehicle %u, station %u (strength %d); haptic "
               "loop: %s\n",
               device->name(), link.domain_id, link.vehicle_id, link.station_id,
               link.station_strength, grant.summary.c_str());

  const bool live = !o.headless && isatty(fileno(stderr)) != 0;
  const auto period_ns = static_cast<std::int64_t>(std::llround(1e9 / o.command_rate_hz));
  const std::int64_t start_ns = hq::haptics::monotonic_now_ns();
  std::int64_t next_ns = start_ns;
  std::int64_t next_heartbeat_ns = start_ns;
  std::int64_t next_status_ns = start_ns;
  const std::int64_t status_period_ns = live ? 200'000'000 : 1'000'000'000;
  hq::ground::ModeToggle toggle;
  std::uint64_t device_losses = 0;
  bool was_connected = true;
  double max_state_gap_s = 0.0;
  std::int64_t last_state_ns = 0;
  next_ns += period_ns;
  while (!g_stop) {
    // Wait for the next command tick, taking vehicle states the moment they arrive so the force
    // feedback gets them at once and their receipt time is exact.
    const bool fresh = ground.poll_until(next_ns);
    const std::int64_t now_ns = hq::haptics::monotonic_now_ns();
    if (fresh) {
      const hq::link::VehicleState& s = ground.status().state;
      hq::haptics::VehicleEstimate estimate;
      estimate.t_ns = now_ns;
      estimate.valid = static_cast<int>(s.estimator_health) != hq_msgs_HEALTH_LOST;
      estimate.v_H_mps = {s.v_H_mps.x, s.v_H_mps.y, s.v_H_mps.z};
      estimate.yaw_rate_radps = s.omega_body_radps.z;
      loop.set_vehicle_estimate(estimate);
      if (last_state_ns != 0) {
        max_state_gap_s =
            std::max(max_state_gap_s, 1e-9 * static_cast<double>(now_ns - last_state_ns));
      }
      last_state_ns = now_ns;
    }
    if (now_ns < next_ns) continue;
    next_ns += period_ns;
    const double t_s = 1e-9 * static_cast<double>(now_ns - start_ns);
    if (o.duration_s > 0.0 && t_s >= o.duration_s) break;

    const hq::haptics::LoopOutput hand = loop.latest();
    if (was_connected && !hand.device_connected) {
      ++device_losses;
      std::fprintf(stderr, "\nhq-ground: device lost (%s): sending zero commands\n",
                   hand.status.data());
    }
    was_connected = hand.device_connected;
    ground.send_command(now_ns, hand.command, hand.command_valid && hand.device_connected);
    const hq_msgs_Mode vehicle_mode =
        ground.status().have_state ? ground.status().state.mode : hq_msgs_MODE_HOVER;
    if (const std::optional<hq_msgs_Mode> mode = toggle.on_buttons(hand.buttons, vehicle_mode)) {
      ground.request_mode(now_ns, *mode);
      std::fprintf(stderr, "%shq-ground: t %.1f s: requesting mode %s\n", live ? "\n" : "", t_s,
                   hq::ground::to_string(*mode));
    }
    if (now_ns >= next_heartbeat_ns) {
      ground.send_heartbeat(now_ns);
      next_heartbeat_ns += 100'000'000;  // 10 Hz, well inside the vehicle's 2 s timeout
    }
    if (now_ns >= next_status_ns) {
      print_status(stderr, live, t_s, ground, hand);
      next_status_ns += status_period_ns;
    }
  }
  loop.stop();
  if (live) std::fprintf(stderr, "\n");

  const hq::ground::LinkStatus& s = ground.status();
  const hq::haptics::LoopTimingReport& timing = loop.timing();
  std::printf("hq-ground summary\n");
  std::printf("  %-40s %llu commands, %llu mode requests, %llu heartbeats, %llu failed\n", "sent",
              static_cast<unsigned long long>(s.commands_sent),
              static_cast<unsigned long long>(s.mode_requests_sent),
              static_cast<unsigned long long>(s.heartbeats_sent),
              static_cast<unsigned long long>(s.write_failures));
  std::printf("  %-40s %llu states, %llu events, %llu camera frames (%.1f KB)\n", "received",
              static_cast<unsigned long long>(s.states), static_cast<unsigned long long>(s.events),
              static_cast<unsigned long long>(s.camera_frames),
              1e-3 * static_cast<double>(s.camera_bytes));
  std::printf("  %-40s p50 %.2f ms, p99 %.2f ms over %lld\n", "vehicle state latency (one way)",
              ground.latency().quantile_ms(0.5), ground.latency().quantile_ms(0.99),
              static_cast<long long>(ground.latency().count()));
  std::printf("  %-40s %.1f ms\n", "largest gap between vehicle states", 1e3 * max_state_gap_s);
  std::printf("  %-40s %s\n", "last vehicle mode",
              s.have_state ? hq::ground::to_string(s.state.mode) : "-");
  std::printf("  %-40s %s\n", "last event", s.last_event.data());
  std::printf("  %-40s p50 %.1f us, p99 %.1f us, max %.1f us, %lld missed\n",
              "haptic loop period jitter", timing.period.quantile_us(0.5),
              timing.period.quantile_us(0.99), timing.period.max_us(),
              static_cast<long long>(timing.missed_deadlines));
  std::printf("  %-40s %.4f J (>= 0: passive)\n", "passivity observer energy",
              loop.passivity().energy_j());
  std::printf("  %-40s %llu\n", "device losses", static_cast<unsigned long long>(device_losses));
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-ground", argc, argv, run); }
