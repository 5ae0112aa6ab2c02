#include "hq/link_bridge/failsafe.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"

#include <algorithm>
#include <string>

namespace hq::link_bridge {

namespace {
constexpr const char* kUnverified = "its writer left before it could be checked (secured link)";
}  // namespace

void check_config(const FailsafeConfig& config) {
  const auto positive = [](const char* key, double value) {
    if (!(value > 0.0)) {
      throw InputError(std::string("link fail-safe: ") + key + " = " + std::to_string(value) +
                       ", expected > 0");
    }
  };
  positive("command_timeout_ms", 1e-6 * static_cast<double>(config.command_timeout_ns));
  positive("heartbeat_timeout_ms", 1e-6 * static_cast<double>(config.heartbeat_timeout_ns));
  positive("command_max_delay_ms", 1e-6 * static_cast<double>(config.command_max_delay_ns));
  positive("command_reanchor_ms", 1e-6 * static_cast<double>(config.command_reanchor_ns));
  const double hold_to_land_s = hq::to_seconds(config.hold_to_land_ns);
  if (!(hold_to_land_s >= 0.1 && hold_to_land_s <= 600.0)) {
    throw InputError("link fail-safe: hold_to_land_s = " + std::to_string(hold_to_land_s) +
                     ", expected in [0.1, 600]");
  }
  for (const std::uint32_t id : config.stations) {
    // Station 0 means "none" in VehicleState.commanding_station_id: it cannot command.
    if (id == 0) throw InputError("link.stations: station id 0, expected ids >= 1");
  }
  positive("envelope.max_v_x_mps", config.envelope.max_v_x_mps);
  positive("envelope.max_v_y_mps", config.envelope.max_v_y_mps);
  positive("envelope.max_v_z_mps", config.envelope.max_v_z_mps);
  positive("envelope.max_yaw_rate_radps", config.envelope.max_yaw_rate_radps);
  if (config.heartbeat_timeout_ns < config.command_timeout_ns) {
    // Landing before holding would skip the gentler fail-safe.
    throw InputError("link fail-safe: heartbeat_timeout_ms = " +
                     std::to_string(1e-6 * static_cast<double>(config.heartbeat_timeout_ns)) +
                     ", expected >= command_timeout_ms = " +
                     std::to_string(1e-6 * static_cast<double>(config.command_timeout_ns)));
  }
}

bool to_mode(hq_msgs_Mode value, modes::Mode& mode) {
  // The enum arrived off the wire: any integer is possible, so compare before converting.
  switch (static_cast<int>(value)) {
    case hq_msgs_MODE_TELEOP:
      mode = modes::Mode::kTeleop;
      return true;
    case hq_msgs_MODE_HOVER:
      mode = modes::Mode::kHover;
      return true;
    case hq_msgs_MODE_LAND:
      mode = modes::Mode::kLand;
      return true;
    case hq_msgs_MODE_MARKER:
      mode = modes::Mode::kMarker;
      return true;
    case hq_msgs_MODE_EXPLORE:
      mode = modes::Mode::kExplore;
      return true;
    default:
      return false;
  }
}

hq_msgs_Mode to_link_mode(modes::Mode mode) {
  switch (mode) {
    case modes::Mode::kTeleop:
      return hq_msgs_MODE_TELEOP;
    case modes::Mode::kHover:
      return hq_msgs_MODE_HOVER;
    case modes::Mode::kLand:
      return hq_msgs_MODE_LAND;
    case modes::Mode::kMarker:
      return hq_msgs_MODE_MARKER;
    case modes::Mode::kExplore:
      return hq_msgs_MODE_EXPLORE;
  }
  return hq_msgs_MODE_HOVER;
}

hq_msgs_OperatorInput operator_input(const FailsafeState& state, modes::Mode mode, bool landed) {
  if (state.last_command_station_id != 0 &&
      state.last_command_station_id != state.commanding_station_id) {
    return hq_msgs_INPUT_IGNORED_NOT_OWNER;
  }
  if (!state.have_command) return hq_msgs_INPUT_NONE;
  if (state.hold || state.heartbeat_lost) return hq_msgs_INPUT_IGNORED_FAILSAFE;
  if (mode == modes::Mode::kTeleop) {
    return landed ? hq_msgs_INPUT_IGNORED_LANDED : hq_msgs_INPUT_FLOWN;
  }
  return hq_msgs_INPUT_IGNORED_MODE;
}

Failsafe::Failsafe(const FailsafeConfig& config) : config_(config) { check_config(config_); }

bool Failsafe::allowed(std::uint32_t station_id) const {
  if (config_.stations.empty()) return station_id != 0;
  return std::find(config_.stations.begin(), config_.stations.end(), station_id) !=
         config_.stations.end();
}

void Failsafe::take_command(std::int64_t t_ns, std::uint32_t station_id) {
  if (station_id == commander_) return;
  commander_ = station_id;
  commander_since_t_ns_ = t_ns;
  commander_changed_ = true;
  ++counters_.commander_changes;
  // The previous commander's heartbeats say nothing about the new one: its own count from now.
  have_heartbeat_ = false;
}

Verdict Failsafe::reject(std::uint64_t& counter, const char* reason) {
  ++counter;
  last_rejection_ = reason;
  return {false, reason};
}

bool Failsafe::intrudes(const char* kind, std::uint32_t claimed, link::WriterStation writer) {
  if (!writer.bound || !writer.known || writer.station_id == claimed) return false;
  ++counters_.intrusions;
  last_intrusion_ = {claimed, writer.station_id, kind};
  return true;
}

bool Failsafe::unverified(link::WriterStation writer) {
  if (!writer.bound || writer.known) return false;
  ++counters_.unverified;
  return true;
}

Verdict Failsafe::on_command(std::int64_t t_ns, const link::VelocityCommand& command,
                             link::WriterStation writer) {
  if (unverified(writer)) {
    last_command_rejection_ = kUnverified;
    return reject(counters_.commands_rejected, kUnverified);
  }
  if (intrudes("command", command.station_id, writer)) {
    last_command_rejection_ = "command claiming another station than its writer's certificate";
    return reject(counters_.commands_rejected, last_command_rejection_);
  }
  if (command.vehicle_id != config_.vehicle_id) {
    last_command_rejection_ = "command for another vehicle id";
    return reject(counters_.commands_rejected, last_command_rejection_);
  }
  const link::Validation v = link::validate(command, config_.envelope);
  if (!v.ok) {
    last_command_rejection_ = v.reason;
    return reject(counters_.commands_rejected, v.reason);
  }
  last_command_station_ = command.station_id;
  if (!allowed(command.station_id)) {
    ++counters_.commands_not_allowed;
    last_command_rejection_ = "command from a station not allowed to command (link.stations)";
    return reject(counters_.commands_rejected, last_command_rejection_);
  }
  if (command.t_ns > 0) {
    if (command.station_id != commander_ && commander_ != 0 && have_command_) {
      // Another station's clock: its stamps say nothing about the previous one's delay.
      have_offset_ = false;
      stale_since_t_ns_ = -1;
    }
    if (const char* reason = stale(t_ns, command.t_ns); reason != nullptr) {
      ++counters_.commands_stale;
      last_command_rejection_ = reason;
      return reject(counters_.commands_rejected, reason);
    }
  }
  last_command_.t_ns = t_ns;
  last_command_.v_H_mps = {command.v_H_mps.x, command.v_H_mps.y, command.v_H_mps.z};
  last_command_.yaw_rate_radps = command.yaw_rate_radps;
  last_command_t_ns_ = t_ns;
  have_command_ = true;
  // DDS exclusive ownership delivers the strongest live writer's commands: the station of an
  // accepted command is the one the vehicle follows.
  take_command(t_ns, command.station_id);
  ++counters_.commands_accepted;
  return {true, ""};
}

const char* Failsafe::stale(std::int64_t t_ns, std::int64_t stamp_ns) {
  const std::int64_t offset_ns = t_ns - stamp_ns;
  if (!have_offset_) {
    have_offset_ = true;
    min_offset_ns_ = offset_ns;
    offset_relaxed_t_ns_ = t_ns;
    last_stamp_ns_ = stamp_ns - 1;
  }
  // The least delay rises by 5 % of elapsed time: clock drift is followed, a stall is not.
  min_offset_ns_ += (t_ns - offset_relaxed_t_ns_) / 20;
  offset_relaxed_t_ns_ = t_ns;
  min_offset_ns_ = std::min(min_offset_ns_, offset_ns);
  const char* reason = nullptr;
  if (offset_ns - min_offset_ns_ > config_.command_max_delay_ns) {
    reason = "command older than its deadline (link delay or stall)";
  } else if (stamp_ns <= last_stamp_ns_) {
    reason = "command older than one already accepted (reordered)";
  }
  if (reason == nullptr) {
    stale_since_t_ns_ = -1;
    last_stamp_ns_ = stamp_ns;
    return nullptr;
  }
  if (stale_since_t_ns_ < 0) stale_since_t_ns_ = t_ns;
  if (t_ns - stale_since_t_ns_ < config_.command_reanchor_ns) return reason;
  // Stale for command_reanchor without a fresh one in between: not a burst but another clock.
  min_offset_ns_ = offset_ns;
  last_stamp_ns_ = stamp_ns;
  stale_since_t_ns_ = -1;
  return nullptr;
}

Verdict Failsafe::on_mode_request(std::int64_t t_ns, const link::ModeRequest& request,
                                  modes::Mode& mode, link::WriterStation writer) {
  if (unverified(writer)) return reject(counters_.mode_requests_rejected, kUnverified);
  if (intrudes("mode request", request.station_id, writer)) {
    return reject(counters_.mode_requests_rejected,
                  "mode request claiming another station than its writer's certificate");
  }
  if (request.vehicle_id != config_.vehicle_id) {
    return reject(counters_.mode_requests_rejected, "mode request for another vehicle id");
  }
  const link::Validation v = link::validate(request);
  if (!v.ok) return reject(counters_.mode_requests_rejected, v.reason);
  modes::Mode requested = mode;  // `mode` is left alone unless the request is accepted
  if (!to_mode(request.requested_mode, requested)) {
    return reject(counters_.mode_requests_rejected, "requested_mode outside the Mode enum");
  }
  if (request.vehicle_session_id != config_.session_id) {
    // Made to a previous instance of this vehicle (a TRANSIENT_LOCAL leftover, a replay) or
    // before the station heard this one: it must not act.
    ++counters_.mode_requests_wrong_session;
    return reject(counters_.mode_requests_rejected,
                  "mode request for another vehicle session (stale or replayed)");
  }
  if (!allowed(request.station_id)) {
    ++counters_.mode_requests_not_commander;
    return reject(counters_.mode_requests_rejected,
                  "mode request from a station not allowed to command (link.stations)");
  }
  if (commander_ == 0) take_command(t_ns, request.station_id);  // the first station
  if (request.station_id != commander_) {
    ++counters_.mode_requests_not_commander;
    return reject(counters_.mode_requests_rejected,
                  "mode request from a station that does not command this vehicle");
  }
  mode = requested;
  ++counters_.mode_requests_accepted;
  return {true, ""};
}

Verdict Failsafe::on_heartbeat(std::int64_t t_ns, const link::Heartbeat& heartbeat,
                               link::WriterStation writer) {
  // A vehicle's heartbeat (its own among them) has no station to claim.
  const bool ground = static_cast<int>(heartbeat.role) == hq_msgs_ROLE_GROUND;
  if (ground && unverified(writer)) return reject(counters_.heartbeats_rejected, kUnverified);
  if (ground && intrudes("heartbeat", heartbeat.sender_id, writer)) {
    return reject(counters_.heartbeats_rejected,
                  "heartbeat claiming another station than its writer's certificate");
  }
  if (heartbeat.vehicle_id != config_.vehicle_id) {
    return reject(counters_.heartbeats_rejected, "heartbeat for another vehicle id");
  }
  const link::Validation v = link::validate(heartbeat);
  if (!v.ok) return reject(counters_.heartbeats_rejected, v.reason);
  if (static_cast<int>(heartbeat.role) != hq_msgs_ROLE_GROUND) {
    // A vehicle's heartbeat (our own among them: the topic is shared) is well-formed but says
    // nothing about the operator: ignored, not counted as a rejection.
    return {false, "heartbeat not from a ground station"};
  }
  if (!allowed(heartbeat.sender_id)) {
    return reject(counters_.heartbeats_rejected,
                  "heartbeat from a station not allowed to command (link.stations)");
  }
  if (commander_ == 0) take_command(t_ns, heartbeat.sender_id);  // the first station
  if (heartbeat.sender_id != commander_) {
    // Well-formed, but another station's: alive or not, it does not fly this vehicle.
    ++counters_.heartbeats_not_commander;
    return {false, "heartbeat not from the commanding station"};
  }
  last_heartbeat_t_ns_ = t_ns;
  have_heartbeat_ = true;
  ++counters_.heartbeats_accepted;
  return {true, ""};
}

const FailsafeState& Failsafe::update(std::int64_t t_ns) {
  FailsafeState& s = state_;
  s.t_ns = t_ns;
  s.have_command = have_command_;
  s.commanding_station_id = commander_;
  s.last_command_station_id = last_command_station_;
  s.commander_changed = commander_changed_;
  commander_changed_ = false;
  s.command_age_ns = have_command_ ? t_ns - last_command_t_ns_ : -1;
  s.heartbeat_age_ns = have_heartbeat_ ? t_ns - last_heartbeat_t_ns_ : -1;

  s.hold = !have_command_ || s.command_age_ns > config_.command_timeout_ns;
  s.hold_started = s.hold && !was_holding_;
  if (s.hold_started) ++counters_.holds;
  was_holding_ = s.hold;
  if (s.hold) {
    // Zero velocity stamped now, so the mode controller flies it as a fresh command (a held
    // vehicle, not its own teleop-timeout fallback).
    s.command = {};
    s.command.t_ns = t_ns;
  } else {
    s.command = last_command_;
  }

  // The heartbeat clock starts with the first commander: before that the vehicle sits on the
  // ground and there is nobody to lose. Until the commander's first heartbeat, its commands
  // (or the moment it took command) stand in for one.
  const bool armed = commander_ != 0;
  std::int64_t since_ns = 0;
  if (have_heartbeat_) {
    since_ns = s.heartbeat_age_ns;
  } else if (armed) {
    const std::int64_t alive_t_ns =
        have_command_ ? std::max(last_command_t_ns_, commander_since_t_ns_) : commander_since_t_ns_;
    since_ns = t_ns - alive_t_ns;
  }
  s.heartbeat_lost = armed && since_ns > config_.heartbeat_timeout_ns;
  // Escalation: a hold that outlasts hold_to_land lands. Only once a command was flown: a
  // vehicle that never had one was never flown by anybody.
  s.hold_expired = s.hold && have_command_ &&
                   s.command_age_ns > config_.command_timeout_ns + config_.hold_to_land_ns;
  s.land_for_heartbeat = s.heartbeat_lost && !was_lost_ && !was_expired_;
  s.land_for_hold = s.hold_expired && !was_expired_ && !was_lost_ && !s.land_for_heartbeat;
  s.request_land = s.land_for_heartbeat || s.land_for_hold;
  if (s.request_land) ++counters_.land_requests;
  if (s.land_for_hold) ++counters_.land_requests_hold;
  was_lost_ = s.heartbeat_lost;
  was_expired_ = s.hold_expired;
  return s;
}

}  // namespace hq::link_bridge
