#include "hq/mavlink/codec.hpp"

#include "hq/testing/allocation_counter.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace hq::mavlink {
namespace {

using Frame = std::array<std::uint8_t, kMaxFrameSize>;
using Bytes = std::vector<std::uint8_t>;

Bytes encode(Encoder& encoder, const Message& message) {
  Frame frame{};
  const std::size_t n = encoder.encode(message, frame);
  return Bytes(frame.begin(), frame.begin() + static_cast<std::ptrdiff_t>(n));
}

Bytes encode(const Message& message) {
  Encoder encoder(7, 42);
  return encode(encoder, message);
}

struct Received {
  FrameHeader header;
  Message message;
};

std::vector<Received> feed(Parser& parser, const Bytes& bytes) {
  std::vector<Received> out;
  parser.feed(bytes, [&](const FrameHeader& h, const Message& m) { out.push_back({h, m}); });
  return out;
}

// Recomputes the CRC of a v2 frame after a test edited its header or payload.
void fix_crc_v2(Bytes& frame, std::uint8_t crc_extra) {
  const std::size_t length = frame[1];
  std::uint16_t crc = crc16_mcrf4xx(std::span<const std::uint8_t>(frame.data() + 1, 9 + length));
  crc = crc16_mcrf4xx(std::span<const std::uint8_t>(&crc_extra, 1), crc);
  frame[10 + length] = static_cast<std::uint8_t>(crc & 0xFF);
  frame[11 + length] = static_cast<std::uint8_t>(crc >> 8);
}

// One of each message with every field non-zero and distinct (extensions included).
std::vector<Message> every_message() {
  Heartbeat hb{0x00060000u | 0x12u, kMavTypeQuadrotor, kMavAutopilotPx4, 0x81, kMavStateActive, 3};
  SysStatus ss;
  ss.onboard_control_sensors_present = 0x1234567;
  ss.onboard_control_sensors_enabled = 0x2345678;
  ss.onboard_control_sensors_health = 0x3456789;
  ss.load_permille = 512;
  ss.voltage_battery_mv = 15800;
  ss.current_battery_ca = -1234;
  ss.battery_remaining_pct = 87;
  ss.drop_rate_comm_cpct = 3;
  ss.errors_comm = 4;
  ss.errors_count = {5, 6, 7, 8};
  ss.onboard_control_sensors_present_extended = 9;
  ss.onboard_control_sensors_enabled_extended = 10;
  ss.onboard_control_sensors_health_extended = 11;
  Attitude att{123456, 0.1f, -0.2f, 3.0f, 0.01f, -0.02f, 0.03f};
  CommandLong cl;
  cl.param = {1.f, 6.f, -3.5f, 4.25f, 1e6f, -7.f, 0.125f};
  cl.command = kMavCmdDoSetMode;
  cl.target_system = 1;
  cl.target_component = 1;
  cl.confirmation = 2;
  CommandAck ack{kMavCmdComponentArmDisarm, 4, 50, -77, 7, 42};
  SetAttitudeTarget sat;
  sat.time_boot_ms = 987654;
  sat.q = {0.9f, 0.1f, -0.2f, 0.3f};
  sat.body_roll_rate_radps = 0.4f;
  sat.body_pitch_rate_radps = -0.5f;
  sat.body_yaw_rate_radps = 0.6f;
  sat.thrust = 0.55f;
  sat.target_system = 1;
  sat.target_component = 1;
  sat.type_mask = kAttitudeTargetIgnoreBodyRollRate | kAttitudeTargetIgnoreBodyPitchRate;
  sat.thrust_body = {0.1f, 0.2f, -0.7f};
  VisionSpeedEstimate vse;
  vse.usec = 0x0123456789ABull;
  vse.x_mps = 1.5f;
  vse.y_mps = -2.5f;
  vse.z_mps = 0.25f;
  for (int i = 0; i < 9; ++i)
    vse.covariance[static_cast<std::size_t>(i)] = 0.01f * static_cast<float>(i + 1);
  vse.reset_counter = 3;
  HighresImu imu{0x1122334455667ull, 0.1f, -0.2f, -9.81f, 0.01f,  0.02f, -0.03f, 0.2f, 0.0f, 0.4f,
                 1013.25f,           0.5f, 120.f, 25.5f,  0x1FFF, 2};
  Statustext st;
  st.severity = 4;
  const char* text = "Preflight Fail: accel uncalibrated";
  std::memcpy(st.text.data(), text, std::strlen(text));
  st.id = 513;
  st.chunk_seq = 1;
  const Timesync ts{-1234567890123LL, 9876543210987LL, 1, 191};
  Odometry od;
  od.time_usec = 0x0123456789ABCull;
  od.x_m = 1.f, od.y_m = -2.f, od.z_m = -0.5f;
  od.q = {0.5f, 0.5f, -0.5f, 0.5f};
  od.vx_mps = 0.25f, od.vy_mps = -0.125f, od.vz_mps = 0.0625f;
  od.rollspeed_radps = 0.1f, od.pitchspeed_radps = -0.2f, od.yawspeed_radps = 0.3f;
  for (std::size_t i = 0; i < 21; ++i) {
    od.pose_covariance[i] = 0.001f * static_cast<float>(i + 1);
    od.velocity_covariance[i] = -0.002f * static_cast<float>(i + 1);
  }
  od.frame_id = kMavFrameLocalFrd;
  od.child_frame_id = kMavFrameBodyFrd;
  od.reset_counter = 9;
  od.estimator_type = kMavEstimatorTypeVio;
  od.quality_pct = -1;
  return {hb, ss, att, cl, ack, sat, vse, imu, st, ts, od};
}

TEST(Crc, Mcrf4xxCheckValue) {
  const char* check = "123456789";
  EXPECT_EQ(
      crc16_mcrf4xx(std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(check), 9)),
      0x6F91);
}

TEST(Codec, EveryMessageRoundTripsWithItsHeader) {
  Encoder encoder(7, 42);
  Parser parser;
  std::uint8_t expected_sequence = 0;
  for (const Message& message : every_message()) {
    const auto got = feed(parser, encode(encoder, message));
    ASSERT_EQ(got.size(), 1u) << "message index " << message.index();
    EXPECT_EQ(got[0].message, message) << "message index " << message.index();
    EXPECT_EQ(got[0].header.system_id, 7);
    EXPECT_EQ(got[0].header.component_id, 42);
    EXPECT_EQ(got[0].header.sequence, expected_sequence++);
    EXPECT_FALSE(got[0].header.v1);
    EXPECT_FALSE(got[0].header.is_signed);
    std::visit([&](const auto& m) { EXPECT_EQ(got[0].header.message_id, m.kId); }, message);
  }
  EXPECT_EQ(parser.counters().frames, every_message().size());
  EXPECT_EQ(parser.counters().dropped(), 0u);
  EXPECT_EQ(parser.counters().garbage_bytes, 0u);
}

TEST(Codec, OdometryFieldsSitAtTheirSpecOffsets) {
  // common.xml ODOMETRY: time_usec at 0, q at 20, vx at 36, pose_covariance at 60,
  // velocity_covariance at 144, frame_id 228, child_frame_id 229; extensions reset_counter 230,
  // estimator_type 231, quality 232 (int8).
  Odometry od;
  od.time_usec = 0x0807060504030201ull;
  od.q = {2.f, 0.f, 0.f, 0.f};
  od.vx_mps = -1.f;
  od.pose_covariance[0] = 4.f;
  od.velocity_covariance[20] = 8.f;
  od.frame_id = kMavFrameLocalFrd;
  od.child_frame_id = kMavFrameBodyFrd;
  od.reset_counter = 3;
  od.estimator_type = kMavEstimatorTypeVio;
  od.quality_pct = -1;
  const Bytes frame = encode(od);
  ASSERT_EQ(frame[1], 233);
  const std::uint8_t* payload = frame.data() + 10;
  auto f32 = [&](std::size_t offset) {
    float v = 0;
    std::memcpy(&v, payload + offset, 4);
    return v;
  };
  EXPECT_EQ(payload[0], 0x01);
  EXPECT_EQ(payload[7], 0x08);
  EXPECT_EQ(f32(20), 2.f);
  EXPECT_EQ(f32(36), -1.f);
  EXPECT_EQ(f32(60), 4.f);
  EXPECT_EQ(f32(144 + 20 * 4), 8.f);
  EXPECT_EQ(payload[228], kMavFrameLocalFrd);
  EXPECT_EQ(payload[229], kMavFrameBodyFrd);
  EXPECT_EQ(payload[230], 3);
  EXPECT_EQ(payload[231], kMavEstimatorTypeVio);
  EXPECT_EQ(payload[232], 0xFF);
  EXPECT_EQ(upper_triangle_index(1, 1), 6u);
  EXPECT_EQ(upper_triangle_index(2, 2), 11u);
  EXPECT_EQ(upper_triangle_index(5, 5), 20u);
}

TEST(Codec, OdometryNanFieldsSurviveBitForBit) {
  Odometry od;
  od.x_m = od.y_m = od.z_m = std::numeric_limits<float>::quiet_NaN();
  od.q.fill(std::numeric_limits<float>::quiet_NaN());
  od.pose_covariance.fill(std::numeric_limits<float>::quiet_NaN());
  od.vx_mps = 0.5f;
  Parser parser;
  const auto got = feed(parser, encode(od));
  ASSERT_EQ(got.size(), 1u);
  const auto& back = std::get<Odometry>(got[0].message);
  EXPECT_TRUE(std::isnan(back.x_m) && std::isnan(back.q[3]) && std::isnan(back.pose_covariance[0]));
  EXPECT_EQ(back.vx_mps, 0.5f);
}

TEST(Codec, OldTimesyncWithoutTargetsDecodesWithTargetsZero) {
  // The protocol before the target fields: a 16-byte payload, as an old autopilot sends it.
  Timesync ts{42, 0x0123456789ABCDEFLL, 0, 0};
  const Bytes frame = encode(ts);
  EXPECT_EQ(frame[1], 16);
  Parser parser;
  const auto got = feed(parser, frame);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(std::get<Timesync>(got[0].message), ts);
}

TEST(Codec, SequenceWrapsAfter255) {
  Encoder encoder(1, 1);
  Parser parser;
  std::vector<std::uint8_t> sequences;
  for (int i = 0; i < 258; ++i) {
    for (const auto& r : feed(parser, encode(encoder, Heartbeat{}))) {
      sequences.push_back(r.header.sequence);
    }
  }
  ASSERT_EQ(sequences.size(), 258u);
  EXPECT_EQ(sequences[255], 255);
  EXPECT_EQ(sequences[256], 0);
  EXPECT_EQ(sequences[257], 1);
}

TEST(Codec, HeartbeatMatchesAnIndependentlyComputedFrame) {
  // Bytes computed outside this codec with a bit-wise CRC-16/MCRF4XX (poly 0x8408 reflected,
  // init 0xFFFF) over header[1..9] + payload + CRC_EXTRA 50, laid out per serialization.html:
  // PX4 quadrotor, armed (0x81), OFFBOARD (custom_mode 6 << 16), MAV_STATE_ACTIVE.
  const Bytes expected = {0xFD, 0x09, 0x00, 0x00, 0x00, 0x01, 0x01, 0x00, 0x00, 0x00, 0x00,
                          0x00, 0x06, 0x00, 0x02, 0x0C, 0x81, 0x04, 0x03, 0xD2, 0x91};
  Encoder encoder(1, 1);
  const Heartbeat hb{6u << 16, kMavTypeQuadrotor, kMavAutopilotPx4, 0x81, kMavStateActive, 3};
  EXPECT_EQ(encode(encoder, hb), expected);
}

TEST(Codec, TrailingZeroBytesAreTrimmedAndRestored) {
  Heartbeat hb;  // type .. system_status zero, mavlink_version 3
  hb.mavlink_version = 0;
  const Bytes all_zero = encode(hb);
  EXPECT_EQ(all_zero[1], 1) << "an all-zero payload keeps one byte";
  hb.custom_mode = 5;
  const Bytes trimmed = encode(hb);
  EXPECT_EQ(trimmed[1], 1) << "custom_mode's first byte is the last non-zero byte";
  hb.system_status = 4;
  EXPECT_EQ(encode(hb)[1], 8);
  hb.mavlink_version = 3;
  EXPECT_EQ(encode(hb)[1], 9);

  Parser parser;
  hb.system_status = 0;
  hb.mavlink_version = 0;
  const auto got = feed(parser, encode(hb));
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].message, Message(hb));
}

TEST(Codec, ZeroExtensionsAreOmitted) {
  HighresImu imu;
  imu.time_usec = 1;
  imu.fields_updated = 0x0101;
  EXPECT_EQ(encode(imu)[1], 62) << "base payload only";
  imu.id = 3;
  EXPECT_EQ(encode(imu)[1], 63) << "the extension id is carried when non-zero";

  SetAttitudeTarget sat;
  sat.type_mask = 7;
  EXPECT_EQ(encode(sat)[1], 39);
  sat.thrust_body[2] = -0.5f;
  EXPECT_EQ(encode(sat)[1], 51);

  // A short payload is padded with zeros on receipt, extensions included.
  Parser parser;
  const auto got = feed(parser, encode(imu));
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(std::get<HighresImu>(got[0].message), imu);
}

TEST(Codec, V1FrameIsDecodedAndCounted) {
  // ATTITUDE as a MAVLink 1 frame: STX 0xFE, len, seq, sys, comp, msgid (1 byte), payload, CRC.
  const Attitude att{1000, 0.5f, -0.25f, 1.0f, 0.f, 0.f, 2.f};
  Bytes frame = {0xFE, 28, 9, 3, 1, 30};
  std::uint8_t payload[28];
  std::memcpy(payload, &att.time_boot_ms, 4);
  const float values[6] = {att.roll_rad,        att.pitch_rad,        att.yaw_rad,
                           att.rollspeed_radps, att.pitchspeed_radps, att.yawspeed_radps};
  std::memcpy(payload + 4, values, sizeof(values));
  frame.insert(frame.end(), payload, payload + 28);
  std::uint16_t crc = crc16_mcrf4xx(std::span<const std::uint8_t>(frame.data() + 1, 5 + 28));
  const std::uint8_t crc_extra = 39;
  crc = crc16_mcrf4xx(std::span<const std::uint8_t>(&crc_extra, 1), crc);
  frame.push_back(static_cast<std::uint8_t>(crc & 0xFF));
  frame.push_back(static_cast<std::uint8_t>(crc >> 8));

  Parser parser;
  const auto got = feed(parser, frame);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_TRUE(got[0].header.v1);
  EXPECT_EQ(got[0].header.sequence, 9);
  EXPECT_EQ(got[0].header.system_id, 3);
  EXPECT_EQ(got[0].message, Message(att));
  EXPECT_EQ(parser.counters().v1_frames, 1u);
  EXPECT_EQ(parser.counters().frames, 1u);
}

TEST(Codec, V1FrameExtensionBytesAreIgnored) {
  // node-mavlink writes extension fields into v1 frames; MAVLink 1 has none, so they are dropped.
  HighresImu imu{};
  imu.time_usec = 99;
  imu.fields_updated = 7;
  imu.id = 5;
  const Bytes v2 = encode(imu);
  ASSERT_EQ(v2[1], 63);
  Bytes frame = {0xFE, 63, 0, 1, 1, 105};
  frame.insert(frame.end(), v2.begin() + 10, v2.begin() + 10 + 63);
  std::uint16_t crc = crc16_mcrf4xx(std::span<const std::uint8_t>(frame.data() + 1, 5 + 63));
  const std::uint8_t crc_extra = 93;
  crc = crc16_mcrf4xx(std::span<const std::uint8_t>(&crc_extra, 1), crc);
  frame.push_back(static_cast<std::uint8_t>(crc & 0xFF));
  frame.push_back(static_cast<std::uint8_t>(crc >> 8));
  Parser parser;
  const auto got = feed(parser, frame);
  ASSERT_EQ(got.size(), 1u);
  const auto& decoded = std::get<HighresImu>(got[0].message);
  EXPECT_EQ(decoded.time_usec, 99u);
  EXPECT_EQ(decoded.fields_updated, 7);
  EXPECT_EQ(decoded.id, 0);
}

TEST(Codec, SignedFrameSignatureIsSkipped) {
  Bytes frame = encode(Attitude{5, 0.1f, 0.2f, 0.3f, 0, 0, 0});
  frame[2] = 0x01;  // MAVLINK_IFLAG_SIGNED: the CRC covers the flags
  fix_crc_v2(frame, 39);
  for (int i = 0; i < 13; ++i)
    frame.push_back(static_cast<std::uint8_t>(0xFD - i));  // start bytes inside
  const Bytes next = encode(Heartbeat{});
  frame.insert(frame.end(), next.begin(), next.end());

  Parser parser;
  const auto got = feed(parser, frame);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_TRUE(got[0].header.is_signed);
  EXPECT_FLOAT_EQ(std::get<Attitude>(got[0].message).yaw_rad, 0.3f);
  EXPECT_FALSE(got[1].header.is_signed);
  EXPECT_EQ(parser.counters().garbage_bytes, 0u);
}

TEST(Codec, UnknownIncompatFlagIsDroppedAsBadLength) {
  Bytes frame = encode(Heartbeat{});
  frame[2] = 0x02;
  fix_crc_v2(frame, 50);
  const Bytes next = encode(Attitude{});
  frame.insert(frame.end(), next.begin(), next.end());
  Parser parser;
  const auto got = feed(parser, frame);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].message.index(), Message(Attitude{}).index());
  EXPECT_EQ(parser.counters().bad_length, 1u);
}

TEST(Codec, PayloadLongerThanTheMessageIsBadLength) {
  // A HEARTBEAT claiming 12 payload bytes with a valid CRC.
  Bytes frame = {0xFD, 12, 0, 0, 0, 1, 1, 0, 0, 0};
  for (int i = 0; i < 12; ++i) frame.push_back(static_cast<std::uint8_t>(i + 1));
  frame.push_back(0);
  frame.push_back(0);
  fix_crc_v2(frame, 50);
  Parser parser;
  EXPECT_TRUE(feed(parser, frame).empty());
  EXPECT_EQ(parser.counters().bad_length, 1u);
}

TEST(Codec, BadCrcIsCountedAndTheNextFrameDecodes) {
  Bytes stream = encode(Attitude{1, 0.1f, 0, 0, 0, 0, 0});
  stream[12] ^= 0x40;
  const Bytes good = encode(Attitude{2, 0.2f, 0, 0, 0, 0, 0});
  stream.insert(stream.end(), good.begin(), good.end());
  Parser parser;
  const auto got = feed(parser, stream);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(std::get<Attitude>(got[0].message).time_boot_ms, 2u);
  EXPECT_EQ(parser.counters().bad_crc, 1u);
}

TEST(Codec, BadCrcResynchronisesInsideTheFailedFrame) {
  // A stray start byte claims 200 payload bytes and swallows a real frame: the CRC fails and the
  // parser restarts one byte after the stray start, finding the real frame inside.
  Bytes stream = {0xFD, 200, 0, 0, 0, 1, 1, 0, 0, 0};
  const Bytes good = encode(HighresImu{77, 1, 2, 3, 4, 5, 6, 0, 0, 0, 0, 0, 0, 0, 1, 0});
  stream.insert(stream.end(), good.begin(), good.end());
  const Bytes second = encode(Heartbeat{9, 2, 12, 0, 3, 3});
  stream.insert(stream.end(), second.begin(), second.end());
  stream.resize(10 + 200 + 2, 0x55);
  Parser parser;
  const auto got = feed(parser, stream);
  ASSERT_EQ(got.size(), 2u) << "both frames inside the failed candidate are found";
  EXPECT_EQ(std::get<HighresImu>(got[0].message).time_usec, 77u);
  EXPECT_EQ(std::get<Heartbeat>(got[1].message).custom_mode, 9u);
  EXPECT_EQ(parser.counters().bad_crc, 1u);
  EXPECT_EQ(parser.counters().garbage_bytes, 9u + (212u - 10u - good.size() - second.size()));
}

TEST(Codec, UnknownMessageIdIsSkippedWhole) {
  // Message 9999 with a payload full of start bytes: skipped by its length, not rescanned.
  Bytes stream = {0xFD, 6,    0,    0,    0,    1,    1,    0x0F, 0x27,
                  0x00, 0xFD, 0xFE, 0xFD, 0xFE, 0xFD, 0xFE, 0x12, 0x34};
  const Bytes good = encode(Heartbeat{});
  stream.insert(stream.end(), good.begin(), good.end());
  Parser parser;
  const auto got = feed(parser, stream);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(parser.counters().unknown_id, 1u);
  EXPECT_EQ(parser.counters().bad_crc, 0u);
  EXPECT_EQ(parser.counters().garbage_bytes, 0u);
}

TEST(Codec, GarbageBetweenFramesIsCounted) {
  const Bytes a = encode(Heartbeat{});
  const Bytes b = encode(Attitude{3, 0, 0, 0, 0, 0, 0});
  Bytes stream = {0x00, 0x11, 0x22};
  stream.insert(stream.end(), a.begin(), a.end());
  for (int i = 0; i < 10; ++i) stream.push_back(static_cast<std::uint8_t>(0x30 + i));
  stream.insert(stream.end(), b.begin(), b.end());
  stream.push_back(0x7F);
  Parser parser;
  EXPECT_EQ(feed(parser, stream).size(), 2u);
  EXPECT_EQ(parser.counters().garbage_bytes, 14u);
  EXPECT_EQ(parser.counters().dropped(), 0u);
}

TEST(Codec, FramesSplitByteByByteDecode) {
  Encoder encoder(1, 1);
  Bytes stream;
  for (const Message& m : every_message()) {
    const Bytes f = encode(encoder, m);
    stream.insert(stream.end(), f.begin(), f.end());
  }
  Parser parser;
  std::vector<Message> got;
  for (const std::uint8_t byte : stream) {
    parser.feed(std::span<const std::uint8_t>(&byte, 1),
                [&](const FrameHeader&, const Message& m) { got.push_back(m); });
  }
  EXPECT_EQ(got, every_message());
}

TEST(Codec, EndOfDatagramDropsAPartialFrame) {
  const Bytes frame = encode(every_message()[7]);  // HIGHRES_IMU, 75 bytes
  Parser parser;
  EXPECT_TRUE(feed(parser, Bytes(frame.begin(), frame.begin() + 15)).empty());
  parser.end_of_datagram();
  EXPECT_EQ(parser.counters().truncated, 1u);
  // The rest of that frame must not complete it: it is garbage now, and the next frame decodes.
  EXPECT_TRUE(feed(parser, Bytes(frame.begin() + 15, frame.end())).empty());
  parser.end_of_datagram();
  EXPECT_EQ(feed(parser, frame).size(), 1u);
  parser.end_of_datagram();
  EXPECT_EQ(parser.counters().frames, 1u);
}

TEST(Codec, RandomBytesNeverCrashAndCountersAddUp) {
  std::mt19937 rng(12345);
  std::uniform_int_distribution<int> byte(0, 255);
  std::uniform_int_distribution<int> chunk_size(0, 64);
  std::bernoulli_distribution start_byte(0.05);
  std::bernoulli_distribution datagram_end(0.3);
  Parser parser;
  std::uint64_t total = 0;
  std::uint64_t delivered = 0;
  std::uint8_t chunk[64];
  for (int i = 0; i < 100'000; ++i) {
    const int n = chunk_size(rng);
    for (int k = 0; k < n; ++k) {
      // Enough start bytes that headers, lengths and CRCs get exercised.
      chunk[k] = start_byte(rng) ? (byte(rng) & 1 ? kStxV2 : kStxV1)
                                 : static_cast<std::uint8_t>(byte(rng));
    }
    total += static_cast<std::uint64_t>(n);
    parser.feed(std::span<const std::uint8_t>(chunk, static_cast<std::size_t>(n)),
                [&](const FrameHeader&, const Message&) { ++delivered; });
    if (datagram_end(rng)) parser.end_of_datagram();
  }
  const ParserCounters& c = parser.counters();
  EXPECT_EQ(delivered, c.frames);
  EXPECT_LE(c.v1_frames, c.frames);
  EXPECT_GT(c.garbage_bytes, 0u);
  EXPECT_LE(c.garbage_bytes + c.dropped() + c.frames, total) << "every event consumed a byte";
  EXPECT_GT(c.bad_crc + c.unknown_id + c.truncated, 0u);
  // Recovery: after the noise, a real frame still decodes.
  parser.end_of_datagram();
  EXPECT_EQ(feed(parser, encode(Heartbeat{})).size(), 1u);
}

TEST(Codec, EncoderAndParserAllocateNothing) {
  const auto messages = every_message();
  Encoder encoder(1, 1);
  Parser parser;
  Frame frame{};
  std::size_t delivered = 0;
  const long before = hq::testing::allocation_count();
  for (int round = 0; round < 100; ++round) {
    for (const Message& m : messages) {
      const std::size_t n = encoder.encode(m, frame);
      parser.feed(std::span<const std::uint8_t>(frame.data(), n),
                  [&](const FrameHeader&, const Message&) { ++delivered; });
      parser.feed(std::span<const std::uint8_t>(frame.data(), n / 2),
                  [&](const FrameHeader&, const Message&) { ++delivered; });
      parser.end_of_datagram();
    }
  }
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
  EXPECT_EQ(delivered, 100 * messages.size());
}

}  // namespace
}  // namespace hq::mavlink
