#pragma once
/// The QoS of every link topic, in one place. Reader and writer of a topic get the same policies
/// (so requested and offered always match); writers add the ownership strength.
///
/// | topic            | reliability | history | durability      | other                      | why
/// |
/// |------------------|-------------|---------|-----------------|----------------------------|-----|
/// | velocity command | best-effort | last 1  | volatile        | deadline (100 ms), owner-  | a
/// late command is worse than none: a retransmission arrives after the next fresh sample; the
/// deadline tells the vehicle the stream stopped; EXCLUSIVE ownership + manual-by-topic liveliness
/// (500 ms lease, asserted by each write) lets a backup station take over only when the primary
/// stops commanding | |                  |             |         |                 | ship EXCLUSIVE
/// + strength, |     | |                  |             |         |                 | liveliness
/// manual-by-topic |     | | mode request     | reliable    | last 4  | transient-local | - | a
/// mode change must not be lost, and a vehicle that (re)joins must still see the last request | |
/// event            | reliable    | last 32 | transient-local | -                          | a
/// ground that joins late sees recent warnings; events are rare so reliability costs nothing | |
/// vehicle state    | best-effort | last 1  | volatile        | -                          |
/// streamed at the control rate; only the newest is of use to the haptic loop | | camera frame |
/// best-effort | last 1  | volatile        | -                          | large and periodic:
/// retransmitting a stale 40 KB frame would delay the next one | | heartbeat        | best-effort |
/// last 1  | volatile        | liveliness automatic,      | a lost heartbeat is replaced by the
/// next; liveliness-changed on the reader reports a dead peer process without parsing stamps | | |
/// |         |                 | lease heartbeat_lease_ms   |     |

#include "hq/link/config.hpp"

#include <dds/dds.h>

namespace hq::link {

/// Owns a dds_qos_t. Non-copyable, movable.
class Qos {
 public:
  Qos();
  ~Qos();
  Qos(Qos&& other) noexcept;
  Qos& operator=(Qos&& other) noexcept;
  Qos(const Qos&) = delete;
  Qos& operator=(const Qos&) = delete;

  [[nodiscard]] const dds_qos_t* get() const { return qos_; }
  [[nodiscard]] dds_qos_t* get() { return qos_; }
  /// A copy, to add policies to without changing this one.
  [[nodiscard]] Qos copy() const;

 private:
  dds_qos_t* qos_;
};

/// Which end of a topic the QoS is for: writers add ownership strength.
enum class End { kReader, kWriter };

/// Velocity commands: deadline config.command_deadline_ns, EXCLUSIVE ownership with
/// config.station_strength on the writer, manual-by-topic liveliness with config.command_lease_ns.
Qos command_qos(const LinkConfig& config, End end);
/// Mode requests: reliable, transient-local, keep-last 4.
Qos mode_request_qos();
/// Events: reliable, transient-local, keep-last 32.
Qos event_qos();
/// Vehicle state: best-effort, keep-last 1.
Qos vehicle_state_qos();
/// Camera frames: best-effort, keep-last 1.
Qos camera_qos();
/// Heartbeats: best-effort, keep-last 1, automatic liveliness with config.heartbeat_lease_ns.
Qos heartbeat_qos(const LinkConfig& config);

/// Depths used above, for tests and documentation.
inline constexpr int kModeRequestDepth = 4;
inline constexpr int kEventDepth = 32;

}  // namespace hq::link
