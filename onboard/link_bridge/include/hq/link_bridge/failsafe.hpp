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
///   - no accepted command for command_timeout (200 ms): hold zero velocity;
///   - no heartbeat from any station for heartbeat_timeout (2 s) once a station has been seen:
///     request land, once per loss;
///   - a mode request with an unknown mode or for another vehicle is rejected and counted.
///
/// Sequence numbers are recorded, not used to drop samples: a hostile sample with a huge sequence
/// number would otherwise lock the real station out for good.

#include "hq/link/messages.hpp"
#include "hq/modes/mode_controller.hpp"

#include <cstdint>

namespace hq::link_bridge {

struct FailsafeConfig {
  std::uint32_t vehicle_id = 1;                        ///< Messages for other vehicles: rejected.
  std::int64_t command_timeout_ns = 200'000'000;       ///< Older command: hold zero velocity.
  std::int64_t heartbeat_timeout_ns = 2'000'000'000;   ///< No heartbeat this long: land.
  std::int64_t command_max_delay_ns = 250'000'000;     ///< Later than the least delay + this.
  std::int64_t command_reanchor_ns = 1'000'000'000;  ///< All stale this long: new clock.
  link::CommandEnvelope envelope;                      ///< Accepted command magnitudes.
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
  bool have_command = false;          ///< A command was ever accepted.
  bool hold = true;                   ///< No fresh command: zero velocity.
  bool heartbeat_lost = false;        ///< Stations were seen, none for heartbeat_timeout.
  bool request_land = false;          ///< True on the one step the heartbeat loss starts.
  bool hold_started = false;          ///< True on the step fresh commands stop.
  std::int64_t command_age_ns = -1;   ///< Since the last accepted command; -1 if none yet.
  std::int64_t heartbeat_age_ns = -1; ///< Since the last heartbeat; -1 if none yet.
};

struct FailsafeCounters {
  std::uint64_t commands_accepted = 0;
  std::uint64_t commands_rejected = 0;   ///< All rejections, the stale ones included.
  std::uint64_t commands_stale = 0;      ///< Older than their deadline or than one accepted.
  std::uint64_t mode_requests_accepted = 0;
  std::uint64_t mode_requests_rejected = 0;
  std::uint64_t heartbeats_accepted = 0;
  std::uint64_t heartbeats_rejected = 0;
  std::uint64_t holds = 0;        ///< Times fresh commands stopped.
  std::uint64_t land_requests = 0;
};

class Failsafe {
 public:
  /// @throws hq::InputError via check_config().
  explicit Failsafe(const FailsafeConfig& config);

  /// A received velocity command, at receipt time t_ns.
  Verdict on_command(std::int64_t t_ns, const link::VelocityCommand& command);
  /// A received mode request; on acceptance `mode` is the requested mode.
  Verdict on_mode_request(std::int64_t t_ns, const link::ModeRequest& request, modes::Mode& mode);
  /// A received heartbeat. Only ground stations' count; vehicles' are ignored without counting.
  Verdict on_heartbeat(std::int64_t t_ns, const link::Heartbeat& heartbeat);

  /// The fail-safe state at t_ns (non-decreasing). Allocates nothing.
  const FailsafeState& update(std::int64_t t_ns);

  [[nodiscard]] const FailsafeState& state() const { return state_; }
  [[nodiscard]] const FailsafeCounters& counters() const { return counters_; }
  [[nodiscard]] const FailsafeConfig& config() const { return config_; }
  /// Reason of the latest rejection (static text), "" if none.
  [[nodiscard]] const char* last_rejection() const { return last_rejection_; }
  /// Reason of the latest rejected velocity command, "" if none.
  [[nodiscard]] const char* last_command_rejection() const { return last_command_rejection_; }

 private:
  Verdict reject(std::uint64_t& counter, const char* reason);
  /// Why a command stamped stamp_ns received at t_ns is stale (static text), nullptr if it is
  /// not; updates the delay estimate.
  const char* stale(std::int64_t t_ns, std::int64_t stamp_ns);

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
  std::int64_t last_heartbeat_t_ns_ = 0;
  bool have_heartbeat_ = false;
  bool was_holding_ = true;
  bool was_lost_ = false;
  const char* last_rejection_ = "";
  const char* last_command_rejection_ = "";
};

/// The on-board mode of a link enum value; false for a value outside the enum.
bool to_mode(hq_msgs_Mode value, modes::Mode& mode);
/// The link enum of an on-board mode.
hq_msgs_Mode to_link_mode(modes::Mode mode);

}  // namespace hq::link_bridge
