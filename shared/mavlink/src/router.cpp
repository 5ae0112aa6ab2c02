#include "hq/mavlink/router.hpp"

#include "hq/base/error.hpp"
#include "hq/mavlink/message_targets.hpp"

#include <string>

namespace hq::mavlink {
namespace {

constexpr std::size_t kHeaderV2 = 10;
constexpr std::size_t kHeaderV1 = 6;
constexpr std::size_t kCrcSize = 2;
constexpr std::uint8_t kIncompatSigned = 0x01;

}  // namespace

Router::Router(std::size_t link_count, std::size_t local_link)
    : link_count_(link_count), local_link_(local_link) {
  if (link_count == 0 || link_count > kMaxRouterLinks || local_link >= link_count) {
    throw InputError("mavlink::Router: " + std::to_string(link_count) + " links, local link " +
                     std::to_string(local_link) + ", expected 1.." +
                     std::to_string(kMaxRouterLinks) + " links and local < links");
  }
}

bool Router::read_target(const RawFrame& frame, FrameTarget& target) {
  const std::span<const std::uint8_t> bytes = frame.bytes;
  if (bytes.size() < kHeaderV1 + kCrcSize) return false;
  const bool v2 = bytes[0] == kStxV2;
  if (!v2 && bytes[0] != kStxV1) return false;
  const std::size_t header = v2 ? kHeaderV2 : kHeaderV1;
  const std::size_t length = bytes[1];
  const bool is_signed = v2 && bytes.size() > 2 && (bytes[2] & kIncompatSigned) != 0;
  if (bytes.size() != header + length + kCrcSize + (is_signed ? kSignatureSize : 0)) return false;
  target = {};
  const MessageTargets* where = find_message_targets(frame.header.message_id);
  if (where == nullptr) return true;
  // MAVLink 2 trims trailing zero bytes: a target beyond the payload was zero.
  auto byte_at = [&](std::int16_t offset) -> std::uint8_t {
    if (offset < 0 || static_cast<std::size_t>(offset) >= length) return 0;
    return bytes[header + static_cast<std::size_t>(offset)];
  };
  target.system = byte_at(where->target_system_offset);
  target.component = byte_at(where->target_component_offset);
  return true;
}

bool Router::learn(std::size_t from, std::uint8_t system, std::uint8_t component) {
  if (system == 0) return true;  // not a sender anyone can address
  for (std::size_t i = 0; i < route_count_; ++i) {
    Route& r = routes_[i];
    if (r.system != system || r.component != component) continue;
    if (r.link == from) return true;
    if (r.link == local_link_) {
      ++counters_.loop;
      return false;
    }
    r.link = static_cast<std::uint8_t>(from);
    ++counters_.route_moves;
    return true;
  }
  if (route_count_ == kMaxRoutes) {
    ++counters_.routes_full;
    return true;
  }
  routes_[route_count_++] = {system, component, static_cast<std::uint8_t>(from)};
  return true;
}

LinkMask Router::route(std::size_t from, const RawFrame& frame) {
  if (from >= link_count_) {
    ++counters_.malformed;
    return 0;
  }
  ++counters_.received[from];
  FrameTarget target;
  if (!read_target(frame, target)) {
    ++counters_.malformed;
    return 0;
  }
  if (!learn(from, frame.header.system_id, frame.header.component_id)) return 0;

  const LinkMask source = link_bit(from);
  LinkMask out = 0;
  if (target.system == 0) {
    out = static_cast<LinkMask>(link_bit(link_count_) - 1u);
    if (!frame.crc_checked) ++counters_.unchecked_broadcast;
  } else {
    for (std::size_t i = 0; i < route_count_; ++i) {
      const Route& r = routes_[i];
      if (r.system == target.system && (target.component == 0 || r.component == target.component)) {
        out |= link_bit(r.link);
      }
    }
    if (out == source) {
      ++counters_.target_on_source;
      return 0;
    }
    if (out == 0) {
      ++counters_.no_route;
      return 0;
    }
  }
  out = static_cast<LinkMask>(out & ~source);
  for (std::size_t to = 0; to < link_count_; ++to) {
    if ((out & link_bit(to)) != 0) ++counters_.forwarded[from][to];
  }
  return out;
}

int Router::link_of(std::uint8_t system, std::uint8_t component) const {
  for (std::size_t i = 0; i < route_count_; ++i) {
    if (routes_[i].system == system && routes_[i].component == component) return routes_[i].link;
  }
  return -1;
}

}  // namespace hq::mavlink
