#pragma once
/// Where the routed messages of common.xml carry their target: the payload offsets (v2 wire
/// order) of target_system and target_component, with each message's CRC_EXTRA, so a router can
/// check and address frames it does not decode (mavlink.io "Routing"). Written from common.xml;
/// every entry is checked against node-mavlink by hq_mavlink_conformance. A message not listed
/// here and not decoded by the codec is forwarded as a broadcast with its CRC unchecked.

#include <cstdint>
#include <span>

namespace hq::mavlink {

inline constexpr std::int16_t kNoTargetField = -1;

struct MessageTargets {
  std::uint32_t id = 0;
  std::uint8_t crc_extra = 0;
  std::int16_t target_system_offset = kNoTargetField;     ///< Byte offset in the payload.
  std::int16_t target_component_offset = kNoTargetField;  ///< kNoTargetField: whole system.
  const char* name = "";                                  ///< common.xml's name.
};

/// The table, sorted by id.
std::span<const MessageTargets> routed_messages();
/// The entry for `id`, or null. Allocation-free (binary search).
const MessageTargets* find_message_targets(std::uint32_t id);

}  // namespace hq::mavlink
