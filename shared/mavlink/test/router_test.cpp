// The router on frames from the parser, three links as in hq-onboard: 0 this process (the
// companion, 1/191), 1 the flight controller (1/1), 2 a GCS (255/190).
#include "hq/mavlink/router.hpp"

#include "hq/mavlink/codec.hpp"
#include "hq/mavlink/message_targets.hpp"
#include "hq/testing/allocation_counter.hpp"

#include <gtest/gtest.h>

#include <array>
#include <span>
#include <variant>
#include <vector>

namespace hq::mavlink {
namespace {

using Bytes = std::vector<std::uint8_t>;

constexpr std::size_t kLocal = 0;
constexpr std::size_t kFc = 1;
constexpr std::size_t kGcs = 2;

/// A v2 (or v1) frame of any id, built by hand from the specification's layout, so ids the
/// codec does not decode can be made; trailing zeros of the payload trimmed as v2 requires.
Bytes frame_of(std::uint32_t id, std::uint8_t crc_extra, std::uint8_t system,
               std::uint8_t component, Bytes payload, bool v1 = false) {
  if (!v1) {
    while (payload.size() > 1 && payload.back() == 0) payload.pop_back();
  }
  Bytes f;
  if (v1) {
    f = {kStxV1,    static_cast<std::uint8_t>(payload.size()),
         0,         system,
         component, static_cast<std::uint8_t>(id)};
  } else {
    f = {kStxV2,
         static_cast<std::uint8_t>(payload.size()),
         0,
         0,
         0,
         system,
         component,
         static_cast<std::uint8_t>(id & 0xFF),
         static_cast<std::uint8_t>((id >> 8) & 0xFF),
         static_cast<std::uint8_t>(id >> 16)};
  }
  f.insert(f.end(), payload.begin(), payload.end());
  std::uint16_t crc = crc16_mcrf4xx(std::span<const std::uint8_t>(f.data() + 1, f.size() - 1));
  const std::uint8_t extra[1] = {crc_extra};
  crc = crc16_mcrf4xx(extra, crc);
  f.push_back(static_cast<std::uint8_t>(crc & 0xFF));
  f.push_back(static_cast<std::uint8_t>(crc >> 8));
  return f;
}

Bytes encode(std::uint8_t system, std::uint8_t component, const Message& message) {
  Encoder encoder(system, component);
  std::array<std::uint8_t, kMaxFrameSize> buffer{};
  const std::size_t n = encoder.encode(message, buffer);
  return Bytes(buffer.begin(), buffer.begin() + static_cast<std::ptrdiff_t>(n));
}

Heartbeat heartbeat(std::uint8_t type) {
  Heartbeat h;
  h.type = type;
  return h;
}

CommandLong command_to(std::uint8_t system, std::uint8_t component) {
  CommandLong c;
  c.command = kMavCmdComponentArmDisarm;
  c.target_system = system;
  c.target_component = component;
  return c;
}

/// MISSION_REQUEST_LIST (43): target_system, target_component (mission_type trimmed); not
/// decoded by the codec.
Bytes mission_request_list(std::uint8_t system, std::uint8_t component, std::uint8_t target_system,
                           std::uint8_t target_component) {
  return frame_of(43, 132, system, component, {target_system, target_component, 0});
}

class RouterTest : public ::testing::Test {
 protected:
  /// Parses `bytes` as arriving on `from` and routes every frame the parser hands on; returns
  /// the masks, one per frame.
  std::vector<LinkMask> arrive(std::size_t from, const Bytes& bytes) {
    std::vector<LinkMask> masks;
    parsers_[from].feed(
        bytes, [](const FrameHeader&, const Message&) {},
        [&](const RawFrame& frame) {
          last_crc_checked_ = frame.crc_checked;
          masks.push_back(router_.route(from, frame));
        });
    return masks;
  }
  LinkMask arrive_one(std::size_t from, const Bytes& bytes) {
    const std::vector<LinkMask> masks = arrive(from, bytes);
    EXPECT_EQ(masks.size(), 1u);
    return masks.empty() ? LinkMask{0xFF} : masks.front();
  }
  /// The three parties each say who they are.
  void introduce_all() {
    arrive_one(kLocal, encode(1, kMavCompIdOnboardComputer, heartbeat(kMavTypeOnboardController)));
    arrive_one(kFc, encode(1, kMavCompIdAutopilot1, heartbeat(kMavTypeQuadrotor)));
    arrive_one(kGcs, encode(255, 190, heartbeat(6)));
  }

  Router router_{3, kLocal};
  std::array<Parser, 3> parsers_;
  bool last_crc_checked_ = false;
};

TEST_F(RouterTest, BroadcastGoesToEveryLinkButItsSource) {
  EXPECT_EQ(arrive_one(kFc, encode(1, 1, heartbeat(kMavTypeQuadrotor))),
            link_bit(kLocal) | link_bit(kGcs));
  EXPECT_EQ(arrive_one(kGcs, encode(255, 190, heartbeat(6))), link_bit(kLocal) | link_bit(kFc));
  EXPECT_EQ(arrive_one(kLocal, encode(1, 191, Attitude{})), link_bit(kFc) | link_bit(kGcs));
  EXPECT_EQ(router_.counters().forwarded[kFc][kGcs], 1u);
  EXPECT_EQ(router_.counters().forwarded[kGcs][kFc], 1u);
  EXPECT_EQ(router_.counters().dropped(), 0u);
}

TEST_F(RouterTest, LearnsEachSenderOnTheLinkItWasHeardOn) {
  introduce_all();
  EXPECT_EQ(router_.link_of(1, 191), static_cast<int>(kLocal));
  EXPECT_EQ(router_.link_of(1, 1), static_cast<int>(kFc));
  EXPECT_EQ(router_.link_of(255, 190), static_cast<int>(kGcs));
  EXPECT_EQ(router_.link_of(42, 1), -1);
}

TEST_F(RouterTest, TargetedFramesGoOnlyToTheTargetsLink) {
  introduce_all();
  // GIVEN the FC on link 1 WHEN the GCS commands it THEN only the FC's link gets the command.
  EXPECT_EQ(arrive_one(kGcs, encode(255, 190, command_to(1, 1))), link_bit(kFc));
  // ... and the FC's ack addressed to the GCS goes to the GCS alone, not to the companion.
  CommandAck ack;
  ack.command = kMavCmdComponentArmDisarm;
  ack.target_system = 255;
  ack.target_component = 190;
  EXPECT_EQ(arrive_one(kFc, encode(1, 1, ack)), link_bit(kGcs));
  // The companion's setpoints and commands to the FC are not sent to the GCS.
  SetAttitudeTarget setpoint;
  setpoint.target_system = 1;
  setpoint.target_component = 1;
  EXPECT_EQ(arrive_one(kLocal, encode(1, 191, setpoint)), link_bit(kFc));
}

TEST_F(RouterTest, OdometryAndTimesyncAreDecodedCheckedAndRoutedByTheirTargets) {
  introduce_all();
  // The companion's ODOMETRY addresses nobody: a broadcast, to the FC and the GCS alike, its CRC
  // checked by the codec that decodes it (no longer an id known nowhere).
  Odometry odometry;
  odometry.vx_mps = 0.5f;
  EXPECT_EQ(arrive_one(kLocal, encode(1, kMavCompIdOnboardComputer, odometry)),
            link_bit(kFc) | link_bit(kGcs));
  EXPECT_TRUE(last_crc_checked_);
  // Its TIMESYNC request addressed to the FC goes to the FC alone; the FC's answer addressed to
  // the companion stays with the companion (not the GCS).
  EXPECT_EQ(arrive_one(kLocal, encode(1, kMavCompIdOnboardComputer, Timesync{0, 42, 1, 1})),
            link_bit(kFc));
  EXPECT_EQ(arrive_one(kFc, encode(1, 1, Timesync{7, 42, 1, kMavCompIdOnboardComputer})),
            link_bit(kLocal));
  // The FC's own request, and an answer of the older protocol (no targets), are broadcasts.
  EXPECT_EQ(arrive_one(kFc, encode(1, 1, Timesync{0, 43, 0, 0})),
            link_bit(kLocal) | link_bit(kGcs));
  EXPECT_EQ(arrive_one(kFc, encode(1, 1, Timesync{9, 44, 0, 0})),
            link_bit(kLocal) | link_bit(kGcs));
  EXPECT_EQ(router_.counters().unchecked_broadcast, 0u);
  EXPECT_EQ(router_.counters().dropped(), 0u);
  for (const std::size_t link : {kLocal, kFc}) {
    EXPECT_EQ(parsers_[link].counters().unknown_id, 0u);
    EXPECT_EQ(parsers_[link].counters().undecoded, 0u);
  }
}

TEST_F(RouterTest, ComponentZeroReachesEveryLinkOfThatSystemOnce) {
  introduce_all();
  // System 1 is both the companion (local) and the FC: one copy to each, none back to the GCS.
  EXPECT_EQ(arrive_one(kGcs, mission_request_list(255, 190, 1, 0)),
            link_bit(kLocal) | link_bit(kFc));
  EXPECT_TRUE(last_crc_checked_) << "MISSION_REQUEST_LIST is in the table: its CRC is checked";
  EXPECT_EQ(parsers_[kGcs].counters().undecoded, 1u);
}

TEST_F(RouterTest, NeverSendsAFrameBackToItsSource) {
  introduce_all();
  // A GCS addressing itself (or a second GCS on the same link): nothing to forward.
  EXPECT_EQ(arrive_one(kGcs, encode(255, 190, command_to(255, 190))), 0);
  EXPECT_EQ(router_.counters().target_on_source, 1u);
  // Heard on two links: every link but the source's.
  arrive_one(kLocal, encode(7, 1, heartbeat(kMavTypeQuadrotor)));
  arrive_one(kFc, encode(7, 2, heartbeat(kMavTypeQuadrotor)));
  EXPECT_EQ(arrive_one(kFc, mission_request_list(1, 1, 7, 0)), link_bit(kLocal));
}

TEST_F(RouterTest, TargetHeardNowhereIsDroppedAndCounted) {
  introduce_all();
  EXPECT_EQ(arrive_one(kGcs, encode(255, 190, command_to(9, 1))), 0);
  EXPECT_EQ(arrive_one(kGcs, encode(255, 190, command_to(1, 99))), 0);
  EXPECT_EQ(router_.counters().no_route, 2u);
}

TEST_F(RouterTest, UnknownIdIsForwardedAsABroadcastWithItsCrcUnchecked) {
  introduce_all();
  // Message 9999 (not in common.xml): a payload whose byte 0 would read as a target elsewhere.
  const Bytes unknown = frame_of(9999, 0x55, 1, 1, {1, 1, 7, 7});
  EXPECT_EQ(arrive_one(kFc, unknown), link_bit(kLocal) | link_bit(kGcs));
  EXPECT_FALSE(last_crc_checked_);
  EXPECT_EQ(parsers_[kFc].counters().unknown_id, 1u);
  EXPECT_EQ(router_.counters().unchecked_broadcast, 1u);
}

TEST_F(RouterTest, RoutedMessageWithABadCrcNeverReachesTheRouter) {
  introduce_all();
  const std::uint64_t routed_before = router_.counters().received[kGcs];
  Bytes broken = mission_request_list(255, 190, 1, 1);
  broken[broken.size() - 1] ^= 0x5A;
  EXPECT_TRUE(arrive(kGcs, broken).empty());
  EXPECT_EQ(parsers_[kGcs].counters().bad_crc, 1u);
  // A frame truncated by the end of its datagram is dropped by the parser too.
  const Bytes whole = encode(255, 190, command_to(1, 1));
  EXPECT_TRUE(arrive(kGcs, Bytes(whole.begin(), whole.end() - 3)).empty());
  parsers_[kGcs].end_of_datagram();
  EXPECT_EQ(parsers_[kGcs].counters().truncated, 1u);
  EXPECT_EQ(router_.counters().received[kGcs], routed_before);
}

TEST_F(RouterTest, AFrameThatIsNotWholeIsMalformed) {
  const Bytes whole = encode(1, 1, heartbeat(kMavTypeQuadrotor));
  RawFrame frame;
  frame.header.system_id = 1;
  frame.header.component_id = 1;
  frame.bytes = std::span<const std::uint8_t>(whole.data(), whole.size() - 1);
  EXPECT_EQ(router_.route(kFc, frame), 0);
  frame.bytes = std::span<const std::uint8_t>(whole.data(), 3);
  EXPECT_EQ(router_.route(kFc, frame), 0);
  EXPECT_EQ(router_.route(7, RawFrame{whole, frame.header, true}), 0) << "no such link";
  EXPECT_EQ(router_.counters().malformed, 3u);
  EXPECT_EQ(router_.link_of(1, 1), -1) << "nothing learnt from a malformed frame";
}

TEST_F(RouterTest, ZeroTrimmedTargetsReadAsZero) {
  introduce_all();
  // COMMAND_ACK's targets are extensions: absent from a short ack, which is then a broadcast.
  CommandAck ack;
  ack.command = kMavCmdComponentArmDisarm;
  ack.result = 4;
  const Bytes short_ack = encode(1, 1, ack);
  ASSERT_LT(short_ack[1], 8) << "payload trimmed before target_system";
  EXPECT_EQ(arrive_one(kFc, short_ack), link_bit(kLocal) | link_bit(kGcs));
}

TEST_F(RouterTest, MavlinkOneFramesAreRoutedByTheSameTable) {
  introduce_all();
  Bytes payload(33, 0);
  payload[30] = 1;  // target_system
  payload[31] = 1;  // target_component
  EXPECT_EQ(arrive_one(kGcs, frame_of(76, 152, 255, 190, payload, /*v1=*/true)), link_bit(kFc));
}

TEST_F(RouterTest, TheCompanionsIdentityArrivingFromOutsideIsALoop) {
  introduce_all();
  EXPECT_EQ(arrive_one(kGcs, encode(1, 191, heartbeat(kMavTypeOnboardController))), 0);
  EXPECT_EQ(router_.counters().loop, 1u);
  EXPECT_EQ(router_.link_of(1, 191), static_cast<int>(kLocal));
  // Another party may move: a GCS heard again on another link is followed there.
  arrive_one(kFc, encode(255, 190, heartbeat(6)));
  EXPECT_EQ(router_.link_of(255, 190), static_cast<int>(kFc));
  EXPECT_EQ(router_.counters().route_moves, 1u);
}

TEST_F(RouterTest, AFullTableStillRoutesBroadcastsAndCountsWhatItCouldNotLearn) {
  for (std::size_t i = 0; i < kMaxRoutes + 3; ++i) {
    arrive_one(kGcs, encode(static_cast<std::uint8_t>(10 + i), 1, heartbeat(6)));
  }
  EXPECT_EQ(router_.counters().routes_full, 3u);
  EXPECT_EQ(arrive_one(kFc, encode(1, 1, heartbeat(2))), link_bit(kLocal) | link_bit(kGcs));
}

TEST_F(RouterTest, RoutingAllocatesNothing) {
  introduce_all();
  const Bytes command = encode(255, 190, command_to(1, 1));
  const Bytes unknown = frame_of(9999, 0x55, 1, 1, {1, 2, 3});
  const long before = hq::testing::allocation_count();
  LinkMask all = 0;
  for (int i = 0; i < 100; ++i) {
    parsers_[kGcs].feed(
        command, [](const FrameHeader&, const Message&) {},
        [&](const RawFrame& f) { all |= router_.route(kGcs, f); });
    parsers_[kFc].feed(
        unknown, [](const FrameHeader&, const Message&) {},
        [&](const RawFrame& f) { all |= router_.route(kFc, f); });
  }
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
  EXPECT_EQ(all, link_bit(kLocal) | link_bit(kFc) | link_bit(kGcs));
}

TEST(MessageTargets, TableIsSortedAndFindsEveryEntry) {
  for (const MessageTargets& m : routed_messages()) {
    const MessageTargets* found = find_message_targets(m.id);
    ASSERT_NE(found, nullptr) << m.name;
    EXPECT_EQ(found->id, m.id);
  }
  EXPECT_EQ(find_message_targets(0), nullptr) << "HEARTBEAT addresses nobody";
  EXPECT_EQ(find_message_targets(9999), nullptr);
}

template <typename M>
concept HasTargetSystem = requires(M m) {
  m.target_system;
};
template <typename M>
concept HasTargetComponent = requires(M m) {
  m.target_component;
};

/// One message the codec decodes against the table: a message with a target must be listed
/// (else the router would broadcast it), and a listed one must have the codec's CRC_EXTRA and
/// target offsets, so the two sources cannot drift apart (TIMESYNC, COMMAND_*, PARAM_* are in
/// both: the codec decodes them, the router reads their targets from the table).
template <typename M>
void expect_table_agrees_with_codec() {
  M m{};
  if constexpr (HasTargetSystem<M>) m.target_system = 0xA5;
  if constexpr (HasTargetComponent<M>) m.target_component = 0x5A;
  const Bytes bytes = encode(255, 190, m);
  const MessageTargets* entry = find_message_targets(M::kId);
  if constexpr (HasTargetSystem<M>) {
    ASSERT_NE(entry, nullptr) << "message " << M::kId << " has a target: it must be in the table";
  }
  if (entry == nullptr) return;
  SCOPED_TRACE(entry->name);
  const std::size_t n = bytes.size();
  std::uint16_t crc = crc16_mcrf4xx(std::span<const std::uint8_t>(bytes.data() + 1, n - 3));
  crc = crc16_mcrf4xx(std::span<const std::uint8_t>(&entry->crc_extra, 1), crc);
  EXPECT_EQ(crc, static_cast<std::uint16_t>(bytes[n - 2] | (bytes[n - 1] << 8)))
      << "CRC_EXTRA " << static_cast<int>(entry->crc_extra) << " differs from the codec's";
  RawFrame frame;
  frame.bytes = bytes;
  frame.header.message_id = M::kId;
  FrameTarget target;
  ASSERT_TRUE(Router::read_target(frame, target));
  EXPECT_EQ(target.system, HasTargetSystem<M> ? 0xA5 : 0);
  EXPECT_EQ(target.component, HasTargetComponent<M> ? 0x5A : 0);
}

template <typename... Ms>
void expect_table_agrees_with_codec(std::variant<Ms...>* /*every message*/) {
  (expect_table_agrees_with_codec<Ms>(), ...);
}

TEST(MessageTargets, AgreesWithTheCodecOnEveryMessageItDecodes) {
  expect_table_agrees_with_codec(static_cast<Message*>(nullptr));
}

TEST(MessageTargets, AgreesWithTheCodecOnTheMessagesBothKnow) {
  // COMMAND_LONG decoded by the codec and read at the table's offsets give the same target.
  const Bytes bytes = encode(255, 190, command_to(3, 4));
  Parser parser;
  FrameTarget target;
  bool seen = false;
  parser.feed(
      bytes, [](const FrameHeader&, const Message&) {},
      [&](const RawFrame& frame) { seen = Router::read_target(frame, target); });
  ASSERT_TRUE(seen);
  EXPECT_EQ(target.system, 3);
  EXPECT_EQ(target.component, 4);
}

}  // namespace
}  // namespace hq::mavlink
