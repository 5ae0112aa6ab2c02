#pragma once
/// The vehicle's fail-safes on the operator link, as pure logic: every received message and every
/// step comes with its receipt time t_ns on the vehicle's clock, so tests drive it with stamps and
/// need no DDS, no clock and no sleeps.
///
///   - a command is accepted only if it is for this vehicle, finite and inside the envelope;
///     otherwise it is rejected and counted (never clipped: a value outside the envelope means a
///     broken or hostile sender);
///   - a stamped command (t_ns > 0, the station's clock) is rejected as stale when it arrives
///     later than command_max_delay beyond the least delay seen, or is not newer than the last
///     accepted one: a burst of commands queued during a link stall moves nothing, the vehicle
///     holds and resumes on fresh commands. The clocks need not agree: the delay is measured
///     against the least (receipt - stamp) seen, which rises by 5 % of elapsed time so clock
///     drift is followed; if every command for command_reanchor is stale (the station
///     restarted with another clock, or a stamp from the future), the estimate is re-anchored.
///   - no accepted command for command_timeout (200 ms): hold zero velocity; still none
///     hold_to_land (5 s) later: request land, once per hold (the fail-safe escalates; a vehicle
///     whose operator went silent does not hover until its battery is flat);
///   - no heartbeat from the commanding station for heartbeat_timeout (2 s): request land, once
///     per loss;
///   - a mode request with an unknown mode or for another vehicle is rejected and counted.
///
/// Ownership. The vehicle follows one station, the commander (commanding_station_id):
///   - the station of the last accepted velocity command. DDS EXCLUSIVE ownership delivers
///     only the strongest live command writer's samples, so a stronger station's commands take
///     the vehicle over; when the commander dies its lease expires and the next one's commands
///     arrive and take over (it is then the commander: its own heartbeats keep the link);
///   - before any command was accepted, the first allowed station whose heartbeat or mode
///     request arrives, so the first station can ask for take-off and teleop before its hand
///     moves; a stronger station's commands still take over later;
///   - `stations` (config link.stations) lists the station ids allowed to command; empty: any.
///     A command, request or heartbeat from another id is rejected and counted.
/// Mode requests (marker tasks included) and heartbeats count only from the commander: another
/// station's requests are rejected and counted; its heartbeats are ignored (counted apart) and
/// never keep a vehicle whose commander was killed from landing.
///
/// Sessions. Each vehicle process draws a random session id (LinkBridge); a mode request
/// counts only if its vehicle_session_id is this session. A request made to a previous
/// instance of the vehicle (kept by DDS as a TRANSIENT_LOCAL sample, or replayed) is rejected
/// and counted, so a restarted vehicle obeys no stale request.
///
/// Identity. Each message comes with the station its writer is bound to (link::WriterStation,
/// from the writer's certificate on a secured link). A bound sample whose claimed station id is
/// not its writer's is an intrusion: rejected before any other check and counted (intrusions,
/// with the last claim and writer kept for the report), so an allowed station cannot speak for
/// another. A bound sample whose writer had left before it was checked cannot be verified: it is
/// rejected and counted apart (unverified), not called an intrusion. Without security nothing is
/// bound: any process on the domain can claim any id.
///
/// Sequence numbers are recorded, not used to drop samples: a hostile sample with a huge sequence
/// number would otherwise lock the real station out for good.

#include "hq/link/messages.hpp"
#include "hq/link/writer_binding.hpp"
#include "hq/modes/mode_controller.hpp"

#include <cstdint>
#include <vector>

namespace hq::link_bridge {

struct FailsafeConfig {
  std::uint32_t vehicle_id = 1;                       ///< Messages for other vehicles: rejected.
  std::int64_t command_timeout_ns = 200'000'000;      ///< Older command: hold zero velocity.
  std::int64_t heartbeat_timeout_ns = 2'000'000'000;  ///< No heartbeat this long: land.
  std::int64_t command_max_delay_ns = 250'000'000;    ///< Later than the least delay + this.
  std::int64_t command_reanchor_ns = 1'000'000'000;   ///< All stale this long: new clock.
  /// Holding (no fresh command) this long after the hold began: land. 0.1 s .. 600 s.
  std::int64_t hold_to_land_ns = 5'000'000'000;
  link::CommandEnvelope envelope;  ///< Accepted command magnitudes.
  /// This vehicle's session: mode requests must carry it (LinkBridge draws it at random).
  std::uint64_t session_id = 0;
  /// Station ids allowed to command (link.stations); empty: any station.
  std::vector<std::uint32_t> stations;
};

/// Throws hq::InputError naming the field, its value and the expectation.
void check_config(const FailsafeConfig& config);

/// Outcome of one received message (static reason text; no allocation).
struct Verdict {
  bool accepted = false;
  const char* reason = "";
};

/// What the vehicle does about the link at one step.
struct FailsafeState {
  std::int64_t t_ns = 0;
  /// The command to hand the chain: the last accepted one, or zero velocity while holding.
  modes::OperatorCommand command;
  bool have_command = false;    ///< A command was ever accepted.
  bool hold = true;             ///< No fresh command: zero velocity.
  bool heartbeat_lost = false;  ///< A commander was seen, silent for heartbeat_timeout.
  bool hold_expired = false;    ///< Holding for hold_to_land after a command was flown.
  /// True on the one step the vehicle must land: the heartbeat loss or the hold expiry starts
  /// (only the first of the two while both last: one land request per episode).
  bool request_land = false;
  bool land_for_heartbeat = false;  ///< request_land because of the heartbeat loss.
  bool land_for_hold = false;       ///< request_land because the hold expired.
  bool hold_started = false;        ///< True on the step fresh commands stop.
  /// The station followed (0: none yet) and the one whose well-formed command came last.
  std::uint32_t commanding_station_id = 0;
  std::uint32_t last_command_station_id = 0;
  bool commander_changed = false;      ///< True on the step the commander changed.
  std::int64_t command_age_ns = -1;    ///< Since the last accepted command; -1 if none yet.
  std::int64_t heartbeat_age_ns = -1;  ///< Since the last heartbeat; -1 if none yet.
};

struct FailsafeCounters {
  std::uint64_t commands_accepted = 0;
  std::uint64_t commands_rejected = 0;  ///< All rejections, the stale ones included.
  std::uint64_t commands_stale = 0;     ///< Older than their deadline or than one accepted.
  std::uint64_t mode_requests_accepted = 0;
  std::uint64_t mode_requests_rejected = 0;
  std::uint64_t heartbeats_accepted = 0;
  std::uint64_t heartbeats_rejected = 0;
  std::uint64_t holds = 0;  ///< Times fresh commands stopped.
  std::uint64_t land_requests = 0;
  std::uint64_t land_requests_hold = 0;  ///< Of land_requests: the hold expired.
  /// Of the rejections above: from a station not allowed to command (link.stations).
  std::uint64_t commands_not_allowed = 0;
  /// Of mode_requests_rejected: not from the commander / for another vehicle session.
  std::uint64_t mode_requests_not_commander = 0;
  std::uint64_t mode_requests_wrong_session = 0;
  /// Well-formed ground heartbeats not from the commander: ignored (not in _rejected).
  std::uint64_t heartbeats_not_commander = 0;
  std::uint64_t commander_changes = 0;
  /// Samples (commands, mode requests, heartbeats) claiming another station than the one their
  /// writer's certificate is: rejected (and also in the kind's _rejected count).
  std::uint64_t intrusions = 0;
  /// Of the rejections: samples whose writer had left before they were checked (secured link).
  std::uint64_t unverified = 0;
};

/// The latest intrusion: who was claimed and who wrote it (0: a writer bound to no station).
struct Intrusion {
  std::uint32_t claimed_station_id = 0;
  std::uint32_t writer_station_id = 0;
  const char* kind = "";  ///< "command", "mode request" or "heartbeat".
};

class Failsafe {
 public:
  /// @throws hq::InputError via check_config().
  explicit Failsafe(const FailsafeConfig& config);

  /// A received velocity command, at receipt time t_ns, written by `writer`.
  Verdict on_command(std::int64_t t_ns, const link::VelocityCommand& command,
                     link::WriterStation writer = {});
  /// A received mode request; on acceptance `mode` is the requested mode.
  Verdict on_mode_request(std::int64_t t_ns, const link::ModeRequest& request, modes::Mode& mode,
                          link::WriterStation writer = {});
  /// A received heartbeat. Only ground stations' count; vehicles' are ignored without counting.
  Verdict on_heartbeat(std::int64_t t_ns, const link::Heartbeat& heartbeat,
                       link::WriterStation writer = {});

  /// The fail-safe state at t_ns (non-decreasing). Allocates nothing.
  const FailsafeState& update(std::int64_t t_ns);

  [[nodiscard]] const FailsafeState& state() const { return state_; }
  [[nodiscard]] const FailsafeCounters& counters() const { return counters_; }
  [[nodiscard]] const FailsafeConfig& config() const { return config_; }
  /// Reason of the latest rejection (static text), "" if none.
  [[nodiscard]] const char* last_rejection() const { return last_rejection_; }
  /// Reason of the latest rejected velocity command, "" if none.
  [[nodiscard]] const char* last_command_rejection() const { return last_command_rejection_; }
  /// The latest intrusion (counters().intrusions says whether there was one).
  [[nodiscard]] const Intrusion& last_intrusion() const { return last_intrusion_; }

 private:
  Verdict reject(std::uint64_t& counter, const char* reason);
  /// Whether a sample of `kind` claiming `claimed` was written by another station's
  /// certificate; if so it is counted as an intrusion.
  bool intrudes(const char* kind, std::uint32_t claimed, link::WriterStation writer);
  /// Whether the sample's writer left before it could be checked (counted if so).
  bool unverified(link::WriterStation writer);
  /// Why a command stamped stamp_ns received at t_ns is stale (static text), nullptr if it is
  /// not; updates the delay estimate.
  const char* stale(std::int64_t t_ns, std::int64_t stamp_ns);
  [[nodiscard]] bool allowed(std::uint32_t station_id) const;
  /// Makes `station_id` the commander at t_ns (no-op if it is already).
  void take_command(std::int64_t t_ns, std::uint32_t station_id);

  FailsafeConfig config_;
  FailsafeState state_;
  FailsafeCounters counters_;
  modes::OperatorCommand last_command_;
  std::int64_t last_command_t_ns_ = 0;
  bool have_command_ = false;
  // Stamp ageing: least (receipt - stamp), when it was last relaxed, the newest accepted stamp
  // and since when every stamped command has been stale (-1: the last one was not).
  bool have_offset_ = false;
  std::int64_t min_offset_ns_ = 0;
  std::int64_t offset_relaxed_t_ns_ = 0;
  std::int64_t last_stamp_ns_ = 0;
  std::int64_t stale_since_t_ns_ = -1;
  // The commander's heartbeats only: reset when another station takes command.
  std::int64_t last_heartbeat_t_ns_ = 0;
  bool have_heartbeat_ = false;
  std::uint32_t commander_ = 0;
  std::uint32_t last_command_station_ = 0;
  std::int64_t commander_since_t_ns_ = 0;
  bool commander_changed_ = false;
  bool was_holding_ = true;
  bool was_lost_ = false;
  bool was_expired_ = false;
  const char* last_rejection_ = "";
  const char* last_command_rejection_ = "";
  Intrusion last_intrusion_;
};

/// What the vehicle does with the operator's input (VehicleState.operator_input), given the
/// fail-safe state, the mode flown and whether it is on the floor: NOT_OWNER when the last
/// well-formed command came from a station that is not the commander, FAILSAFE while holding
/// or landing for stale commands or a lost heartbeat, LANDED on the floor in teleop, MODE in any
/// other mode than teleop, NONE before any command, FLOWN otherwise.
hq_msgs_OperatorInput operator_input(const FailsafeState& state, modes::Mode mode, bool landed);

/// The on-board mode of a link enum value; false for a value outside the enum.
bool to_mode(hq_msgs_Mode value, modes::Mode& mode);
/// The link enum of an on-board mode.
hq_msgs_Mode to_link_mode(modes::Mode mode);

}  // namespace hq::link_bridge
