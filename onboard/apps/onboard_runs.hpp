#pragma once
// The runs of the on-board chain: hq-onboard's vehicle runtime on a recording, a live camera or
// the SITL process (vehicle_runs.cpp), and hq-sim-flight's in-process simulator with a script
// or over the DDS link (onboard/closed_loop/apps/sim_runs.cpp), with what they share
// (run_support.cpp, onboard_record.cpp: the hq_onboard_runs library, which holds no simulator).

#include "hq/base/format_into.hpp"
#include "hq/link/config.hpp"
#include "hq/link_bridge/link_bridge.hpp"
#include "hq/onboard_log/onboard_recorder.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/pipeline/steady_clock.hpp"
#include "hq/vehicle/vehicle_runtime.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <CLI/CLI.hpp>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

namespace hq::onboard_app {

using hq::pipeline::SteadyClock;

struct Options {
  std::string source_kind;
  std::string sequence_dir;
  std::string camera_path;
  std::string config_path = "config/onboard.yaml";
  std::string vehicle_path = "calib/vehicle_core_paper.yaml";
  std::string csv_path;
  std::string world_path;
  std::string script_path;
  std::string sim_config_path = "onboard/sim/config/sim.yaml";
  std::string resolution = "320x240";
  long long seed = -1;
  bool link = false;
  double duration_s = 0.0;  ///< Wall-time runs; 0 (default) runs until SIGINT/SIGTERM.
  std::string link_config_path;
  hq::link::LinkOverrides link_overrides;
  double command_timeout_ms = 200.0;
  double heartbeat_timeout_ms = 2000.0;
  double hold_to_land_s = 5.0;  ///< --link: held without commands this long -> land.
  double camera_rate_hz = 10.0;
  std::string link_log_path;
  std::string save_map_path;
  std::string fc_spec;           ///< none | mavlink:<transport>; empty: the source's default.
  double fc_max_thrust_n = 0.0;  ///< > 0: overrides the MAVLink thrust normalisation.
  std::string fc_velocity_message = "odometry";  ///< odometry | vision_speed_estimate.
  std::string gcs_spec;               ///< --gcs: udp:HOST:PORT | udp-listen:[HOST:]PORT; "" no GCS.
  std::string sitl_channel = "sitl";  ///< hq-sim --sitl's default: /hq-sitl.
  double sitl_wait_s = 10.0;
  double fc_lost_exit_s = -1.0;  ///< Stop after the FC is lost this long; 0 never; < 0 default.
  std::string record_dir;        ///< --record: DIR/onboard.mcap, the on-board flight log.
  std::string on_stop = "land";  ///< --on-stop: land | hold when the run ends.
  double stop_timeout_s = 30.0;  ///< --stop-timeout-s: the landing or hold given this long.
};

/// --config, --vehicle, --csv and --record, with the program's own help for --csv. Each program
/// adds its own --duration-s: what a run length means differs between them.
void add_flight_options(CLI::App& app, Options& o, const std::string& csv_help);
/// --link and its options: the ground station over DDS and the on-board fail-safes.
void add_ground_link_options(CLI::App& app, Options& o);

/// The program's name at the start of its messages: "hq-onboard" unless main sets another.
extern const char* g_program_name;

/// Set by SIGINT/SIGTERM; runs that last (sim --link, cameras) stop cleanly when it is.
extern std::atomic<bool> g_stop;
/// The signal that set g_stop first (0: none), and how many arrived: a second one cuts the
/// landing short.
extern std::atomic<int> g_stop_signal;
extern std::atomic<int> g_stop_requests;
void request_stop(int signal);
/// "stopped by SIGTERM" (or SIGINT) for the goodbye.
std::string signal_reason();

/// --on-stop and --stop-timeout-s: what the vehicle does when its run ends.
void add_stop_options(CLI::App& app, Options& o);
/// How the wind-down of a run went, for the goodbye and the exit summary.
struct StopOutcome {
  std::string reason;  ///< Why the run ended: "run length 60 s reached", "stopped by SIGTERM".
  std::string result;  ///< "landed", "holding", "landing cut short after 30 s", ...
};
/// Steps `step(t_ns)` (the caller's loop, one control period per call, returning the time it
/// reached) after runtime.begin_stop() until the stop is complete, stop_timeout_s passed or a
/// second signal arrived; says what happened in outcome.result.
template <typename Step>
void wind_down(const Options& o, vehicle::VehicleRuntime& runtime, std::int64_t t_ns, Step step,
               StopOutcome& outcome);
/// Publishes the goodbye on the link and says on stdout whether the ground acknowledged it.
void say_goodbye(link_bridge::LinkBridge& bridge, std::int64_t t_ns, const StopOutcome& outcome);

/// One live status line on stderr (overwritten in place).
void print_status(const pipeline::ChainOutput& out, int frames);

/// The link bridge the options ask for (--link-config, --domain-id, --vehicle-id, the fail-safe
/// timeouts and the camera rate). Throws hq::InputError for a bad file or value.
std::unique_ptr<link_bridge::LinkBridge> make_link_bridge(const Options& o);
/// The link's lines of an exit summary: commands, mode requests and heartbeats accepted and
/// rejected, fail-safes, what was published.
void print_link_summary(const link_bridge::LinkBridge& bridge);

/// --record DIR: the on-board MCAP log (null without --record), created before the flight so
/// an unwritable folder stops the start with hq::InputError naming it.
std::unique_ptr<onboard_log::OnboardRecorder> make_recorder(const Options& o,
                                                            const VehicleConfig& vehicle);
/// Exit status of a run whose flight went well but whose record failed (disk full): the record
/// is not flight-critical, so the flight went on, but whoever started the run must learn that
/// its record is incomplete.
inline constexpr int kRecordFailedExitStatus = 5;
/// Exit status of hq-onboard when the camera or the flight controller's serial port is absent or
/// busy at start (hq::DeviceUnavailableError): unlike bad input (2), starting again may succeed,
/// so a supervisor retries this one.
inline constexpr int kDeviceUnavailableExitStatus = 6;
/// Closes the log with the run summary (plus session id, duration, steps and IMU samples
/// pushed) as its metadata and prints the record's lines of the exit summary. Returns false,
/// after saying so on stderr, when the record failed at any time in the flight or at close.
[[nodiscard]] bool close_recorder(onboard_log::OnboardRecorder& recorder, mcap::KeyValues summary,
                                  const link_bridge::LinkBridge* bridge);
/// The run's exit status with the record's outcome: a failed flight keeps its own status, a
/// good one with a failed record becomes kRecordFailedExitStatus.
inline int with_record_status(int flight_status, bool record_ok) {
  return flight_status == 0 && !record_ok ? kRecordFailedExitStatus : flight_status;
}

/// hq-onboard: replay, openni2, freenect and sitl, with --fc and --link: one VehicleRuntime.
int run_vehicle(const Options& o);

template <typename Step>
void wind_down(const Options& o, vehicle::VehicleRuntime& runtime, std::int64_t t_ns, Step step,
               StopOutcome& outcome) {
  const vehicle::StopAction action =
      o.on_stop == "hold" ? vehicle::StopAction::kHold : vehicle::StopAction::kLand;
  const int signals = g_stop_requests.load();
  const bool was_landed = runtime.last_output() && runtime.last_output()->mode.landed;
  runtime.begin_stop(t_ns, action);
  const std::int64_t deadline_ns = t_ns + static_cast<std::int64_t>(o.stop_timeout_s * 1e9);
  while (!runtime.stop_complete() && t_ns < deadline_ns && g_stop_requests.load() == signals) {
    t_ns = step();
  }
  if (was_landed) {
    outcome.result = "on the ground";
  } else if (runtime.status().fc_lost) {
    outcome.result = "flight controller lost, not landed";
  } else if (runtime.stop_complete()) {
    outcome.result = action == vehicle::StopAction::kLand
                         ? "landed"
                         : "holding (the flight controller's failsafe takes over)";
  } else if (g_stop_requests.load() != signals) {
    outcome.result = std::string(vehicle::to_string(action)) + " cut short by a second signal";
  } else {
    char text[64];
    hq::format_into(text, "{} not complete after {:.0f} s", vehicle::to_string(action),
                    o.stop_timeout_s);
    outcome.result = text;
  }
}
/// hq-sim-flight: the closed loop on simulated time with the scripted operator, or paced to
/// wall time and flown over the DDS link.
int run_sim(const Options& o);
int run_sim_link(const Options& o);

}  // namespace hq::onboard_app
