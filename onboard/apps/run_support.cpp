// What every run of the on-board chain shares, in hq-onboard and hq-sim-flight alike: the
// command-line options of a flight and of the link, the link bridge, the status and summary
// lines, and the stop flag.

#include "hq/base/error.hpp"
#include "hq/base/log.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/link/link.hpp"
#include "hq/link_bridge/link_bridge.hpp"

#include "onboard_runs.hpp"

#include <cmath>
#include <csignal>
#include <cstdio>
#include <fmt/format.h>
#include <memory>
#include <string>

namespace hq::onboard_app {

const char* g_program_name = "hq-onboard";
std::atomic<bool> g_stop{false};
std::atomic<int> g_stop_signal{0};
std::atomic<int> g_stop_requests{0};

void request_stop(int signal) {
  int none = 0;
  g_stop_signal.compare_exchange_strong(none, signal);
  g_stop_requests.fetch_add(1);
  g_stop = true;
}

std::string signal_reason() {
  const int signal = g_stop_signal.load();
  return signal == SIGTERM  ? "stopped by SIGTERM"
         : signal == SIGINT ? "stopped by SIGINT"
                            : "stopped by signal " + std::to_string(signal);
}

void add_stop_options(CLI::App& app, Options& o) {
  app.add_option("--on-stop", o.on_stop,
                 "when the run ends (its length, SIGINT/SIGTERM, the FC or camera lost): land, "
                 "or hold and leave the rest to the FC's offboard-loss failsafe (default land)")
      ->check(CLI::IsMember({"land", "hold"}));
  app.add_option("--stop-timeout-s", o.stop_timeout_s,
                 "the landing or hold at the end is given this long (a second signal cuts it "
                 "short)")
      ->check(CLI::Range(0.0, 600.0));
}

void say_goodbye(link_bridge::LinkBridge& bridge, std::int64_t t_ns, const StopOutcome& outcome) {
  const std::string text = outcome.reason + "; " + outcome.result;
  const bool acknowledged = bridge.say_goodbye(t_ns, text);
  hq::log::info("{}: vehicle ended: {} (goodbye {})\n", g_program_name, text.c_str(),
                acknowledged ? "acknowledged by the ground"
                             : "not acknowledged within 500 ms: the ground may see a link loss");
}

void add_flight_options(CLI::App& app, Options& o, const std::string& csv_help) {
  app.add_option("--config", o.config_path, "on-board config");
  app.add_option("--vehicle", o.vehicle_path, "vehicle file (mass, limits, T_B_C)");
  app.add_option("--csv", o.csv_path, csv_help);
  app.add_option("--record", o.record_dir,
                 "write the flight's on-board MCAP log to DIR/onboard.mcap (link samples as CDR, "
                 "IMU, estimates, setpoints, stage timings)");
}

/// --link: the ground station over DDS and the on-board fail-safes.
void add_ground_link_options(CLI::App& app, Options& o) {
  app.add_flag("--link", o.link, "fly commanded by a ground station over DDS");
  app.add_option("--link-config", o.link_config_path, "--link: YAML with a link: section");
  hq::link::add_link_options(app, o.link_overrides, hq::link::LinkSide::kVehicle);
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
}

void print_status(const hq::pipeline::ChainOutput& out, int frames) {
  const auto& v = out.estimate.v_H_mps;
  const auto& s = out.mode.control.setpoint;
  // \033[K clears what a longer previous line left behind.
  hq::log::note(
      "\rt {:8.3f} s  frame {:5}  {:<5}  v_H [{:+.2f} {:+.2f} {:+.2f}] m/s  thrust {:5.2f} N  "
      "roll {:+.3f} pitch {:+.3f} rad  {:5.2f} ms  {}\033[K",
      hq::to_seconds(out.t_ns), frames, out.estimate.ok() ? "ok" : "HOVER", v.x(), v.y(), v.z(),
      s.thrust_n, s.roll_rad, s.pitch_rad, 1e-6 * static_cast<double>(out.durations.total_ns),
      out.safe_hover ? out.safe_hover_reason : "");
  std::fflush(stderr);
}

std::unique_ptr<hq::link_bridge::LinkBridge> make_link_bridge(const Options& o) {
  hq::link::LinkConfig link = o.link_config_path.empty()
                                  ? hq::link::LinkConfig{}
                                  : hq::link::load_link_config(o.link_config_path);
  hq::link::apply_overrides(o.link_overrides, link);
  hq::link_bridge::FailsafeConfig failsafe;
  failsafe.vehicle_id = link.vehicle_id;
  failsafe.envelope = link.envelope;
  failsafe.command_timeout_ns = std::llround(o.command_timeout_ms * 1e6);
  failsafe.heartbeat_timeout_ns = std::llround(o.heartbeat_timeout_ms * 1e6);
  failsafe.hold_to_land_ns = std::llround(o.hold_to_land_s * 1e9);
  hq::link_bridge::BridgeOptions bridge_options;
  bridge_options.camera_rate_hz = o.camera_rate_hz;
  auto bridge = std::make_unique<hq::link_bridge::LinkBridge>(link, failsafe, bridge_options);
  std::string stations;
  for (const std::uint32_t id : link.stations) {
    stations += (stations.empty() ? "" : ",") + std::to_string(id);
  }
  hq::log::note(
      "{}: link on domain {} as vehicle {}, session {:016x}, "
      "commanded by {}, {}\n",
      g_program_name, link.domain_id, link.vehicle_id,
      static_cast<unsigned long long>(bridge->session_id()),
      stations.empty() ? "any station" : ("stations " + stations).c_str(),
      hq::link::describe_security(link, hq::security::Role::kVehicle).c_str());
  if (const hq::ros2_bridge::Ros2Bridge* ros = bridge->ros2()) {
    hq::log::note(
        "{}: ROS 2 topics rt/{}/{{odom,imu,obstacles,camera/...}}, rt/tf; "
        "Twist on rt/{}/cmd_vel, TwistStamped on cmd_vel_in, mode texts on mode_request as "
        "station {} (lowest priority); node /{}\n",
        g_program_name, ros->ros_namespace().c_str(), ros->ros_namespace().c_str(),
        link.ros2.station_id, ros->node_name().c_str());
  }
  return bridge;
}

void print_link_summary(const hq::link_bridge::LinkBridge& bridge) {
  const hq::link_bridge::FailsafeCounters& c = bridge.failsafe().counters();
  hq::log::info("  {:<40} {} accepted, {} rejected\n", "velocity commands", c.commands_accepted,
                c.commands_rejected);
  hq::log::info("  {:<40} {} accepted, {} rejected\n", "mode requests", c.mode_requests_accepted,
                c.mode_requests_rejected);
  hq::log::info("  {:<40} {} accepted, {} rejected\n", "heartbeats", c.heartbeats_accepted,
                c.heartbeats_rejected);
  hq::log::info("  {:<40} {} holds, {} land requests ({} after a hold)\n", "fail-safes", c.holds,
                c.land_requests, c.land_requests_hold);
  hq::log::info(
      "  {:<40} station {}, {} changes; rejected: {} commands not allowed, {} requests not from "
      "it, {} for another session; {} foreign heartbeats\n",
      "commanding station", bridge.failsafe().state().commanding_station_id, c.commander_changes,
      c.commands_not_allowed, c.mode_requests_not_commander, c.mode_requests_wrong_session,
      c.heartbeats_not_commander);
  if (c.intrusions > 0) {
    const hq::link_bridge::Intrusion& last = bridge.failsafe().last_intrusion();
    hq::log::info(
        "  {:<40} {} refused; last: a {} claiming station {}, written by station {}'s "
        "certificate (0: no station's)\n",
        "intrusions", c.intrusions, last.kind, last.claimed_station_id, last.writer_station_id);
  } else {
    hq::log::info("  {:<40} 0 (samples claiming another station than their certificate)\n",
                  "intrusions");
  }
  if (c.unverified > 0) {
    hq::log::info("  {:<40} {} (their writer had left before they were checked)\n",
                  "samples refused unverified", c.unverified);
  }
  hq::log::info("  {:<40} {} states, {} camera frames, {} events\n", "published",
                bridge.states_sent(), bridge.camera_frames_sent(), bridge.events_sent());
  if (const hq::ros2_bridge::Ros2Bridge* ros = bridge.ros2()) {
    const hq::ros2_bridge::Ros2Counters& r = ros->counters();
    hq::log::info(
        "  {:<40} {} states, {} clouds, {} images, {} clocks; cmd_vel/cmd_vel_in {} taken, {} "
        "stale, {} overridden by a native station; {} mode requests, {} answers\n",
        "ROS 2 published", r.states_published, r.clouds_published, r.images_published,
        r.clocks_published, r.commands_received, r.commands_stale, r.commands_overridden,
        r.mode_requests_received, r.mode_answers_published);
  }
}

}  // namespace hq::onboard_app
