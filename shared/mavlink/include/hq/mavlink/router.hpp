#pragma once
/// A MAVLink router between a few links (this process, a flight controller, a GCS), following
/// mavlink.io "Routing": each sender (system, component) is learnt on the link it was heard on;
/// a frame with a target goes only to the links where that target was heard (target_component 0
/// or absent: any component of the system), a broadcast (target_system 0 or none) to every link
/// but the one it came from; never back to its source link, at most one copy per link. Frames
/// travel as received, byte for byte (sequence, signature and all), so the codec need not
/// decode them: targets are read at the offsets of message_targets.hpp, and an id known nowhere
/// is forwarded as a broadcast with its CRC unchecked. Pure: frames in, a set of links out; the
/// sockets are the caller's. Fixed-size tables; nothing allocates per frame.

#include "hq/mavlink/codec.hpp"

#include <array>
#include <cstddef>
#include <cstdint>

namespace hq::mavlink {

inline constexpr std::size_t kMaxRouterLinks = 4;
/// Senders remembered; a new sender beyond this is not learnt (counted routes_full).
inline constexpr std::size_t kMaxRoutes = 32;

/// Bit i set: send to link i.
using LinkMask = std::uint8_t;
constexpr LinkMask link_bit(std::size_t link) { return static_cast<LinkMask>(1u << link); }

struct RouterCounters {
  /// received[from]: frames routed from each link.
  std::array<std::uint64_t, kMaxRouterLinks> received{};
  /// forwarded[from][to]: copies decided from link `from` to link `to`.
  std::array<std::array<std::uint64_t, kMaxRouterLinks>, kMaxRouterLinks> forwarded{};
  std::uint64_t malformed = 0;  ///< Not one whole frame: its length disagrees with its header.
  std::uint64_t no_route = 0;   ///< Target system/component heard on no link.
  /// Target heard only on the link the frame came from: not sent back.
  std::uint64_t target_on_source = 0;
  /// A sender that belongs to the local link arriving on another: a loop or an impostor.
  std::uint64_t loop = 0;
  /// Of an id known nowhere: forwarded as a broadcast, its CRC unchecked.
  std::uint64_t unchecked_broadcast = 0;
  std::uint64_t routes_full = 0;  ///< A new sender not learnt: the table was full.
  std::uint64_t route_moves = 0;  ///< A known sender heard on another link than before.
  [[nodiscard]] std::uint64_t dropped() const {
    return malformed + no_route + target_on_source + loop;
  }
};

/// A frame's target, as read from its payload (0: broadcast or absent).
struct FrameTarget {
  std::uint8_t system = 0;
  std::uint8_t component = 0;
};

class Router {
 public:
  /// link_count links numbered 0..link_count-1 (at most kMaxRouterLinks); `local_link` is this
  /// process's own: a sender first heard there is never moved to another link.
  Router(std::size_t link_count, std::size_t local_link);

  /// Learns the sender of `frame` (a whole frame as Parser hands it) on link `from`, then returns
  /// the links it must be sent to. `from` is never in the result.
  LinkMask route(std::size_t from, const RawFrame& frame);

  /// The link (system, component) was last heard on, or -1.
  [[nodiscard]] int link_of(std::uint8_t system, std::uint8_t component) const;
  [[nodiscard]] const RouterCounters& counters() const { return counters_; }
  [[nodiscard]] std::size_t link_count() const { return link_count_; }

  /// Where `frame` points (target fields beyond a zero-trimmed payload read as 0); false when it
  /// is not one whole frame.
  static bool read_target(const RawFrame& frame, FrameTarget& target);

 private:
  struct Route {
    std::uint8_t system = 0;
    std::uint8_t component = 0;
    std::uint8_t link = 0;
  };
  /// False when the frame must not be routed (a loop).
  bool learn(std::size_t from, std::uint8_t system, std::uint8_t component);

  std::size_t link_count_;
  std::size_t local_link_;
  std::array<Route, kMaxRoutes> routes_{};
  std::size_t route_count_ = 0;
  RouterCounters counters_;
};

}  // namespace hq::mavlink
