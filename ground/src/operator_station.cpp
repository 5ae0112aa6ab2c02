#include "hq/ground/operator_station.hpp"

#include "hq/base/format_into.hpp"
#include "hq/mcap_recorder/flight_recorder.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <fmt/format.h>
#include <optional>
#include <string>

namespace hq::ground {
namespace {

constexpr std::int64_t kHeartbeatPeriodNs = 100'000'000;  // 10 Hz, well inside the vehicle's 2 s
constexpr std::int64_t kHealthPeriodNs = 250'000'000;     // 4 Hz: rates are per quarter second
constexpr double kHealthRatePerS = 4.0;
constexpr std::int64_t kStatusPeriodNs = 1'000'000'000;

// Stale, lost or waiting, as the headless status line says it.
const char* link_word(const LinkStatus& s, double age_s) {
  if (!s.have_state) return "waiting";
  if (s.vehicle_ended) return "ENDED";
  return age_s < 0.2 ? "ok" : age_s < 2.0 ? "STALE" : "LOST";
}

}  // namespace

std::int64_t SystemClock::monotonic_ns() { return haptics::monotonic_now_ns(); }
std::int64_t SystemClock::wall_ns() { return dds_time(); }

OperatorStation::OperatorStation(const OperatorStationOptions& options, VehicleLink& link,
                                 haptics::HapticLoop& hand, console::ConsoleModel& model,
                                 StationClock& clock, const OperatorOutputs& outputs)
    : options_(options),
      link_(link),
      hand_(hand),
      model_(model),
      clock_(clock),
      outputs_(outputs),
      link_loss_(options.link_lost_after_s) {
  period_ns_ = static_cast<std::int64_t>(std::llround(1e9 / options_.command_rate_hz));
  start_ns_ = clock_.monotonic_ns();
  next_ns_ = start_ns_ + period_ns_;
  next_heartbeat_ns_ = start_ns_;
  next_status_ns_ = start_ns_;
  next_health_ns_ = start_ns_;
}

void OperatorStation::run(const std::atomic<bool>& stop, const std::atomic<bool>& done) {
  while (!stop && !done && step()) {
  }
}

bool OperatorStation::step() {
  // Wait for the next command tick, taking vehicle states the moment they arrive so the force
  // feedback gets them at once and their receipt time is exact.
  std::int64_t now_ns = 0;
  do {
    const bool fresh = link_.poll_until(next_ns_);
    now_ns = clock_.monotonic_ns();
    if (fresh) take_state(now_ns);
  } while (now_ns < next_ns_);
  next_ns_ += period_ns_;
  const double t_s = 1e-9 * static_cast<double>(now_ns - start_ns_);
  if (options_.duration_s > 0.0 && t_s >= options_.duration_s) return false;
  ++stats_.ticks;
  watch_link_loss(now_ns, t_s);
  const haptics::LoopOutput hand = hand_.latest();
  const std::int64_t wall_ns = clock_.wall_ns();  // the clock of the recorded receipts
  const bool valid = send_command(hand, now_ns, wall_ns);
  show_hand(hand, valid, wall_ns);
  request_modes(hand, now_ns, wall_ns, t_s);
  if (const std::int64_t id = requests_.vehicle.exchange(-1); id >= 0) {
    link_.select_vehicle(static_cast<std::uint32_t>(id));
  }
  send_heartbeat(now_ns);
  report_health(now_ns);
  report_status(now_ns, t_s, hand);
  return true;
}

void OperatorStation::take_state(std::int64_t now_ns) {
  const link::VehicleState& s = link_.status().state;
  haptics::VehicleEstimate estimate;
  // Stamped with when the vehicle measured it (through the heartbeat clock offset), so the
  // force law's fade sees the link's delay; the receipt time until the offset is known.
  const std::int64_t age_ns = link_.status().last_state_age_ns;
  estimate.t_ns = now_ns - std::max<std::int64_t>(age_ns, 0);
  estimate.valid = static_cast<int>(s.estimator_health) != hq_msgs_HEALTH_LOST;
  estimate.v_H_mps = {s.v_H_mps.x, s.v_H_mps.y, s.v_H_mps.z};
  estimate.yaw_rate_radps = s.omega_B_radps.z;
  hand_.set_vehicle_estimate(estimate);
  if (last_state_ns_ != 0) {
    stats_.max_state_gap_s =
        std::max(stats_.max_state_gap_s, 1e-9 * static_cast<double>(now_ns - last_state_ns_));
  }
  last_state_ns_ = now_ns;
}

// The link-loss alarm: told once per loss on `out`, in the console's events and in the
// recording (so a replay shows it), and counted for the summary.
void OperatorStation::watch_link_loss(std::int64_t now_ns, double t_s) {
  // A vehicle that said goodbye is silent on purpose: no alarm (its banner says why it ended).
  const LinkStatus& st = link_.status();
  const console::LinkLossMonitor::Change loss =
      link_loss_.update(st.have_state && !st.vehicle_ended ? link_.state_age_s() : -1.0);
  if (loss == console::LinkLossMonitor::Change::kNone) return;
  const bool lost = loss == console::LinkLossMonitor::Change::kLost;
  link::Event e{};
  e.vehicle_id = link_.vehicle_id();
  e.t_ns = now_ns;
  e.severity = lost ? hq_msgs_SEVERITY_ERROR : hq_msgs_SEVERITY_INFO;
  if (lost) {
    hq::format_into(e.text, "VEHICLE LINK LOST: no vehicle state for {:.1f} s (ground)",
                    link_loss_.last_loss_s());
  } else {
    hq::format_into(e.text, "vehicle link regained after {:.1f} s (ground)",
                    link_loss_.last_loss_s());
  }
  if (outputs_.out != nullptr) {
    fmt::print(outputs_.out, "hq-ground: t {:.1f} s: {}\n", t_s, e.text);
    std::fflush(outputs_.out);
  }
  const std::int64_t event_wall_ns = clock_.wall_ns();
  model_.on_event(event_wall_ns, lost ? 2 : 0, e.text);
  if (outputs_.recorder != nullptr) outputs_.recorder->event(event_wall_ns, e);
}

// The hand's command to the vehicle, the recording and the MCAP record; zero without a device.
// Returns whether the command was valid.
bool OperatorStation::send_command(const haptics::LoopOutput& hand, std::int64_t now_ns,
                                   std::int64_t wall_ns) {
  if (was_connected_ && !hand.device_connected) {
    ++stats_.device_losses;
    if (outputs_.log != nullptr) {
      fmt::print(outputs_.log, "\nhq-ground: device lost ({}): sending zero commands\n",
                 hand.status.data());
    }
  }
  was_connected_ = hand.device_connected;
  const bool valid = hand.command_valid && hand.device_connected;
  link_.send_command(now_ns, hand.command, valid);
  if (outputs_.recorder != nullptr) outputs_.recorder->command(wall_ns, hand.command, valid);
  if (outputs_.mcap != nullptr) {
    const LinkStatus& st = link_.status();
    mcap_recorder::GroundSample g;
    g.t_ns = wall_ns;
    g.command_valid = valid;
    for (int i = 0; i < 3; ++i) {
      g.v_cmd_H_mps[i] = valid ? static_cast<float>(hand.command.v_H_mps[i]) : 0.0F;
      g.p_D_m[i] = static_cast<float>(hand.p_D_m[i]);
      g.F_D_n[i] = static_cast<float>(hand.F_D_n[i]);
    }
    g.yaw_rate_cmd_radps = valid ? static_cast<float>(hand.command.yaw_rate_radps) : 0.0F;
    g.latency_ms = st.have_state ? 1e-6F * static_cast<float>(st.last_latency_ns) : -1.0F;
    g.round_trip_ms = 1e-6F * static_cast<float>(st.round_trip_ns);
    g.state_age_ms = 1e-6F * static_cast<float>(st.last_state_age_ns);
    outputs_.mcap->push(g);  // never blocks; dropped and counted when full
  }
  return valid;
}

// The command sent and the hand (position, force, buttons) into the console.
void OperatorStation::show_hand(const haptics::LoopOutput& hand, bool valid, std::int64_t wall_ns) {
  const Eigen::Vector3d v = valid ? hand.command.v_H_mps : Eigen::Vector3d::Zero();
  model_.on_command(
      wall_ns, {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())},
      valid ? static_cast<float>(hand.command.yaw_rate_radps) : 0.0F);
  console::HapticState h;
  h.valid = true;
  for (int i = 0; i < 3; ++i) {
    h.p_D_m[static_cast<std::size_t>(i)] = static_cast<float>(hand.p_D_m[i]);
    h.F_D_n[static_cast<std::size_t>(i)] = static_cast<float>(hand.F_D_n[i]);
  }
  stats_.max_force_n = std::max(stats_.max_force_n, hand.F_D_n.norm());
  h.buttons = hand.buttons;
  h.connected = hand.device_connected;
  h.cue_weight = static_cast<float>(hand.cue_weight);
  h.passivity_energy_j = static_cast<float>(hand.passivity_energy_j);
  h.status = hand.status;
  model_.on_haptics(h);
}

// Mode requests: the device's buttons, the window's requests, and the command line's take-off
// and marker task once the vehicle is heard from.
void OperatorStation::request_modes(const haptics::LoopOutput& hand, std::int64_t now_ns,
                                    std::int64_t wall_ns, double t_s) {
  const bool heard = link_.status().have_state;
  const hq_msgs_Mode vehicle_mode = heard ? link_.status().state.mode : hq_msgs_MODE_HOVER;
  std::optional<hq_msgs_Mode> mode = toggle_.on_buttons(hand.buttons, vehicle_mode);
  if (const int ui_mode = requests_.mode.exchange(-1); ui_mode >= 0) {
    mode = static_cast<hq_msgs_Mode>(ui_mode);
  }
  // Take-off: the vehicle climbs to its take-off height, then flies teleop.
  bool take_off = requests_.take_off.exchange(false);
  if (options_.take_off && !take_off_sent_ && heard) {
    take_off = true;
    take_off_sent_ = true;
  }
  if (take_off) mode = hq_msgs_MODE_TELEOP;
  if (!mode && options_.marker.task != hq_msgs_MARKER_TASK_NONE && !marker_sent_ && heard) {
    mode = hq_msgs_MODE_MARKER;
    marker_sent_ = true;
  }
  if (!mode) return;
  // A marker request carries the window's last marker choice, else the command line's.
  MarkerChoice marker;
  if (*mode == hq_msgs_MODE_MARKER) {
    const int ui_task = requests_.marker_task.exchange(hq_msgs_MARKER_TASK_NONE);
    marker = options_.marker;
    if (ui_task != hq_msgs_MARKER_TASK_NONE) {
      marker.task = static_cast<hq_msgs_MarkerTask>(ui_task);
      marker.target_id = requests_.marker_id.load();
    }
  }
  const bool sent = link_.request_mode(now_ns, *mode, marker, take_off);
  if (outputs_.log != nullptr && marker.task != hq_msgs_MARKER_TASK_NONE) {
    static constexpr std::array<const char*, 4> kTaskNames = {"none", "hold", "goto", "land"};
    fmt::print(outputs_.log, "hq-ground: marker task {} on marker {}\n",
               kTaskNames[static_cast<std::size_t>(marker.task) % kTaskNames.size()],
               static_cast<int>(marker.target_id));
  }
  if (outputs_.recorder != nullptr) outputs_.recorder->mode_request(wall_ns, *mode);
  if (outputs_.log != nullptr) {
    fmt::print(outputs_.log, "hq-ground: t {:.1f} s: requesting {}mode {}{}\n", t_s,
               take_off ? "take-off, then " : "", to_string(*mode),
               sent ? "" : " (waiting for vehicle)");
  }
}

void OperatorStation::send_heartbeat(std::int64_t now_ns) {
  if (now_ns < next_heartbeat_ns_) return;
  link_.send_heartbeat(now_ns);
  next_heartbeat_ns_ += kHeartbeatPeriodNs;
}

// The console's link panel at 4 Hz.
void OperatorStation::report_health(std::int64_t now_ns) {
  if (now_ns < next_health_ns_) return;
  const LinkStatus& st = link_.status();
  console::LinkHealth health;
  health.latency_p50_ms = link_.latency().quantile_ms(0.5);
  health.latency_p99_ms = link_.latency().quantile_ms(0.99);
  health.last_latency_ms = 1e-6 * static_cast<double>(st.last_latency_ns);
  health.state_age_s = st.have_state ? link_.state_age_s() : -1.0;
  health.round_trip_ms = 1e-6 * static_cast<double>(st.round_trip_ns);
  health.round_trip_p50_ms = link_.round_trip().quantile_ms(0.5);
  health.round_trip_p99_ms = link_.round_trip().quantile_ms(0.99);
  health.state_one_way_ms = 1e-6 * static_cast<double>(st.last_state_age_ns);
  health.state_one_way_p99_ms = link_.state_age().quantile_ms(0.99);
  health.state_loss_percent = 100.0 * link_.state_loss();
  health.state_rate_hz = kHealthRatePerS * static_cast<double>(st.states - last_states_);
  health.camera_rate_hz = kHealthRatePerS * static_cast<double>(st.camera_frames - last_frames_);
  last_states_ = st.states;
  last_frames_ = st.camera_frames;
  health.states = st.states;
  health.camera_frames = st.camera_frames;
  health.events = st.events;
  health.commands_sent = st.commands_sent;
  health.write_failures = st.write_failures;
  health.sequence_gaps = st.state_sequence_gaps;
  health.states_rejected = st.states_rejected;
  health.states_implausible = st.states_implausible;
  health.states_wrong_session = st.states_wrong_session;
  health.events_rejected = st.events_rejected;
  health.vehicle_session = st.vehicle_session;
  health.waiting_for_vehicle = st.waiting_for_vehicle;
  health.control_lost = st.control_lost;
  health.commanding_station = st.commanding_station_id;
  health.own_station = options_.station_id;
  health.intrusion_reports = st.intrusion_reports;
  health.last_intrusion = st.last_intrusion;
  health.heartbeat_seen = st.have_vehicle_heartbeat;
  health.vehicle_ids = st.vehicle_ids_seen;
  health.vehicle_id_count = st.vehicle_ids_seen_count;
  health.selected_vehicle = link_.vehicle_id();
  health.link_lost = link_loss_.lost();
  health.vehicle_ended = st.vehicle_ended;
  health.vehicle_ended_text = st.vehicle_ended_text;
  health.link_losses = link_loss_.losses();
  health.longest_loss_s = link_loss_.longest_s();
  model_.on_link(health);
  next_health_ns_ += kHealthPeriodNs;
}

// Once a second: the headless status line, and a failed recording told once each.
void OperatorStation::report_status(std::int64_t now_ns, double t_s,
                                    const haptics::LoopOutput& hand) {
  if (now_ns < next_status_ns_) return;
  next_status_ns_ += kStatusPeriodNs;
  std::FILE* log = outputs_.log;
  if (options_.headless && log != nullptr) {
    const LinkStatus& s = link_.status();
    const auto& v = hand.command.v_H_mps;
    fmt::print(log,
               "t {:6.1f} s  link {:<7}  vehicle {:<7} est {:<8} vlink {:<8}  latency {:5.2f} ms  "
               "rtt {:4.0f} ms  age {:4.0f} ms  loss {:4.1f} %  cmd [{:+.2f} {:+.2f} {:+.2f}] yaw "
               "{:+.2f}  |F| {:.1f} N  {}{}\n",
               t_s, link_word(s, link_.state_age_s()), s.have_state ? to_string(s.state.mode) : "-",
               s.have_state ? to_string(s.state.estimator_health) : "-",
               s.have_state ? to_string(s.state.link_health) : "-",
               1e-6 * static_cast<double>(s.last_latency_ns),
               1e-6 * static_cast<double>(s.round_trip_ns),
               1e-6 * static_cast<double>(s.last_state_age_ns), 100.0 * link_.state_loss(), v.x(),
               v.y(), v.z(), hand.command.yaw_rate_radps, hand.F_D_n.norm(),
               hand.device_connected ? "" : "DEVICE LOST ", s.last_event.data());
    std::fflush(log);
  }
  TelemetryRecorder* recorder = outputs_.recorder;
  if (recorder != nullptr && !recorder->flush() && !recording_failure_told_) {
    // Told once, on the console and the terminal; flying goes on, the exit status says it.
    recording_failure_told_ = true;
    if (log != nullptr) fmt::print(log, "\nhq-ground: recording: {}\n", recorder->error());
    model_.on_event(clock_.wall_ns(), 2, ("recording: " + recorder->error()).c_str());
  }
  mcap_recorder::FlightRecorder* mcap = outputs_.mcap;
  if (mcap != nullptr && mcap->failed() && !mcap_failure_told_) {
    mcap_failure_told_ = true;
    if (log != nullptr) fmt::print(log, "\nhq-ground: {}\n", mcap->error());
    model_.on_event(clock_.wall_ns(), 2, mcap->error().c_str());
  }
}

}  // namespace hq::ground
