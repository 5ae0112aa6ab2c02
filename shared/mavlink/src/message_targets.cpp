#include "hq/mavlink/message_targets.hpp"

#include <algorithm>
#include <array>

namespace hq::mavlink {
namespace {

// common.xml, fields in wire order (base fields sorted by type size, extensions last): e.g.
// COMMAND_LONG is param1..7 (28 bytes), command (2), target_system at 28 + 2 = 30. Messages that
// address a system only (SET_MODE, MANUAL_CONTROL) have no component offset. The non-targeted
// ones listed (PARAM_VALUE, LOG_DATA, ...) are here for their CRC_EXTRA: the parameter and log
// protocols a GCS runs through the companion are then checked, not only forwarded. Messages the
// codec decodes as well (PARAM_*, COMMAND_LONG, COMMAND_ACK, SET_ATTITUDE_TARGET, TIMESYNC) are
// listed for their target offsets; the parser checks them with the codec's CRC_EXTRA, and
// router_test (MessageTargets.AgreesWithTheCodecOnEveryMessageItDecodes) holds the two equal.
constexpr std::array kTable{
    MessageTargets{4, 237, 12, 13, "PING"},
    MessageTargets{5, 217, 0, kNoTargetField, "CHANGE_OPERATOR_CONTROL"},
    MessageTargets{11, 89, 4, kNoTargetField, "SET_MODE"},
    MessageTargets{20, 214, 2, 3, "PARAM_REQUEST_READ"},
    MessageTargets{21, 159, 0, 1, "PARAM_REQUEST_LIST"},
    MessageTargets{22, 220, kNoTargetField, kNoTargetField, "PARAM_VALUE"},
    MessageTargets{23, 168, 4, 5, "PARAM_SET"},
    MessageTargets{37, 212, 4, 5, "MISSION_REQUEST_PARTIAL_LIST"},
    MessageTargets{38, 9, 4, 5, "MISSION_WRITE_PARTIAL_LIST"},
    MessageTargets{39, 254, 32, 33, "MISSION_ITEM"},
    MessageTargets{40, 230, 2, 3, "MISSION_REQUEST"},
    MessageTargets{41, 28, 2, 3, "MISSION_SET_CURRENT"},
    MessageTargets{42, 28, kNoTargetField, kNoTargetField, "MISSION_CURRENT"},
    MessageTargets{43, 132, 0, 1, "MISSION_REQUEST_LIST"},
    MessageTargets{44, 221, 2, 3, "MISSION_COUNT"},
    MessageTargets{45, 232, 0, 1, "MISSION_CLEAR_ALL"},
    MessageTargets{47, 153, 0, 1, "MISSION_ACK"},
    MessageTargets{48, 41, 12, kNoTargetField, "SET_GPS_GLOBAL_ORIGIN"},
    MessageTargets{51, 196, 2, 3, "MISSION_REQUEST_INT"},
    MessageTargets{66, 148, 2, 3, "REQUEST_DATA_STREAM"},
    MessageTargets{69, 243, 10, kNoTargetField, "MANUAL_CONTROL"},
    MessageTargets{70, 124, 16, 17, "RC_CHANNELS_OVERRIDE"},
    MessageTargets{73, 38, 32, 33, "MISSION_ITEM_INT"},
    MessageTargets{75, 158, 30, 31, "COMMAND_INT"},
    MessageTargets{76, 152, 30, 31, "COMMAND_LONG"},
    MessageTargets{77, 143, 8, 9, "COMMAND_ACK"},
    MessageTargets{82, 49, 36, 37, "SET_ATTITUDE_TARGET"},
    MessageTargets{84, 143, 50, 51, "SET_POSITION_TARGET_LOCAL_NED"},
    MessageTargets{86, 5, 50, 51, "SET_POSITION_TARGET_GLOBAL_INT"},
    MessageTargets{110, 84, 1, 2, "FILE_TRANSFER_PROTOCOL"},
    MessageTargets{111, 34, 16, 17, "TIMESYNC"},
    MessageTargets{117, 128, 4, 5, "LOG_REQUEST_LIST"},
    MessageTargets{118, 56, kNoTargetField, kNoTargetField, "LOG_ENTRY"},
    MessageTargets{119, 116, 10, 11, "LOG_REQUEST_DATA"},
    MessageTargets{120, 134, kNoTargetField, kNoTargetField, "LOG_DATA"},
    MessageTargets{121, 237, 0, 1, "LOG_ERASE"},
    MessageTargets{122, 203, 0, 1, "LOG_REQUEST_END"},
    MessageTargets{123, 250, 0, 1, "GPS_INJECT_DATA"},
    MessageTargets{243, 85, 52, kNoTargetField, "SET_HOME_POSITION"},
    MessageTargets{248, 8, 3, 4, "V2_EXTENSION"},
    MessageTargets{320, 243, 2, 3, "PARAM_EXT_REQUEST_READ"},
    MessageTargets{321, 88, 0, 1, "PARAM_EXT_REQUEST_LIST"},
    MessageTargets{322, 243, kNoTargetField, kNoTargetField, "PARAM_EXT_VALUE"},
    MessageTargets{323, 78, 0, 1, "PARAM_EXT_SET"},
    MessageTargets{324, 132, kNoTargetField, kNoTargetField, "PARAM_EXT_ACK"},
};

constexpr bool sorted_by_id() {
  for (std::size_t i = 1; i < kTable.size(); ++i) {
    if (kTable[i - 1].id >= kTable[i].id) return false;
  }
  return true;
}
static_assert(sorted_by_id(), "find_message_targets() searches by id");

}  // namespace

std::span<const MessageTargets> routed_messages() { return kTable; }

const MessageTargets* find_message_targets(std::uint32_t id) {
  const auto* it =
      std::lower_bound(kTable.begin(), kTable.end(), id,
                       [](const MessageTargets& m, std::uint32_t v) { return m.id < v; });
  return it != kTable.end() && it->id == id ? &*it : nullptr;
}

}  // namespace hq::mavlink
