#include "hq/link/link.hpp"
#include "hq/link/test_support.hpp"
#include "hq/testing/allocation_counter.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <string>

namespace hq::link {
namespace {

// One participant per side, as in the two processes, on the test's private domain.
struct Pair {
  Participant ground{test::private_domain_id()};
  Participant vehicle{test::private_domain_id()};
};

template <typename T>
void round_trip(const Qos& writer_qos, const Qos& reader_qos, const T& sent, T& received) {
  Pair pair;
  Topic<T> ground_topic(pair.ground);
  Topic<T> vehicle_topic(pair.vehicle);
  Reader<T> reader(pair.vehicle, vehicle_topic, reader_qos);
  Writer<T> writer(pair.ground, ground_topic, writer_qos);
  ASSERT_TRUE(test::wait_for_readers(pair.ground, writer, 1));
  ASSERT_TRUE(writer.write(sent)) << writer.last_error();
  ASSERT_TRUE(test::take_within(pair.vehicle, reader, received)) << "no " << ground_topic.name();
}

TEST(Topics, VelocityCommandRoundTrip) {
  LinkConfig config;
  VelocityCommand sent{};
  sent.vehicle_id = 3;
  sent.station_id = 11;
  sent.sequence_number = 123456789012ULL;
  sent.t_ns = -5;
  sent.v_H_mps = {0.5F, -0.25F, 0.125F};
  sent.yaw_rate_radps = -0.75F;
  VelocityCommand received{};
  round_trip(command_qos(config, End::kWriter), command_qos(config, End::kReader), sent, received);
  EXPECT_EQ(received.vehicle_id, 3u);
  EXPECT_EQ(received.station_id, 11u);
  EXPECT_EQ(received.sequence_number, 123456789012ULL);
  EXPECT_EQ(received.t_ns, -5);
  EXPECT_EQ(received.v_H_mps.x, 0.5F);
  EXPECT_EQ(received.v_H_mps.y, -0.25F);
  EXPECT_EQ(received.v_H_mps.z, 0.125F);
  EXPECT_EQ(received.yaw_rate_radps, -0.75F);
}

TEST(Topics, ModeRequestRoundTrip) {
  ModeRequest sent{};
  sent.vehicle_id = 2;
  sent.station_id = 5;
  sent.sequence_number = 9;
  sent.t_ns = 1'000;
  sent.requested_mode = hq_msgs_MODE_LAND;
  ModeRequest received{};
  round_trip(mode_request_qos(), mode_request_qos(), sent, received);
  EXPECT_EQ(received.vehicle_id, 2u);
  EXPECT_EQ(received.station_id, 5u);
  EXPECT_EQ(received.sequence_number, 9u);
  EXPECT_EQ(received.requested_mode, hq_msgs_MODE_LAND);
}

TEST(Topics, VehicleStateRoundTripWithFullObstacleCloud) {
  Sample<VehicleState> sent;
  sent->vehicle_id = 4;
  sent->sequence_number = 77;
  sent->t_ns = 123;
  sent->v_H_mps = {1.0F, 2.0F, 3.0F};
  sent->omega_B_radps = {0.1F, 0.2F, 0.3F};
  sent->roll_rad = 0.05F;
  sent->pitch_rad = -0.05F;
  sent->v_obs_H_mps = {-0.5F, 0.0F, 0.0F};
  sent->mode = hq_msgs_MODE_HOVER;
  sent->estimator_health = hq_msgs_HEALTH_DEGRADED;
  sent->link_health = hq_msgs_HEALTH_OK;
  reserve(sent->obstacle_points_B_m, hq_msgs_kMaxObstaclePoints);
  sent->obstacle_points_B_m._length = hq_msgs_kMaxObstaclePoints;
  for (std::uint32_t i = 0; i < hq_msgs_kMaxObstaclePoints; ++i) {
    sent->obstacle_points_B_m._buffer[i] = {static_cast<float>(i), 1.0F, -1.0F};
  }
  Sample<VehicleState> received;
  round_trip(vehicle_state_qos(), vehicle_state_qos(), *sent, *received);
  EXPECT_EQ(received->vehicle_id, 4u);
  EXPECT_EQ(received->v_H_mps.z, 3.0F);
  EXPECT_EQ(received->omega_B_radps.y, 0.2F);
  EXPECT_EQ(received->pitch_rad, -0.05F);
  EXPECT_EQ(received->v_obs_H_mps.x, -0.5F);
  EXPECT_EQ(received->mode, hq_msgs_MODE_HOVER);
  EXPECT_EQ(received->estimator_health, hq_msgs_HEALTH_DEGRADED);
  ASSERT_EQ(received->obstacle_points_B_m._length, hq_msgs_kMaxObstaclePoints);
  EXPECT_EQ(received->obstacle_points_B_m._buffer[2047].x, 2047.0F);
  EXPECT_EQ(received->obstacle_points_B_m._buffer[0].z, -1.0F);
}

TEST(Topics, CameraFrameRoundTripWith40KbJpeg) {
  Sample<CameraFrame> sent;
  sent->vehicle_id = 1;
  sent->sequence_number = 30;
  sent->width_px = 640;
  sent->height_px = 480;
  constexpr std::uint32_t kJpegBytes = 40'000;
  reserve(sent->rgb_jpeg, kJpegBytes);
  sent->rgb_jpeg._length = kJpegBytes;
  for (std::uint32_t i = 0; i < kJpegBytes; ++i)
    sent->rgb_jpeg._buffer[i] = static_cast<std::uint8_t>(i % 251);
  reserve(sent->depth_preview, 100);
  sent->depth_preview._length = 100;
  std::memset(sent->depth_preview._buffer, 0xAB, 100);
  Sample<CameraFrame> received;
  round_trip(camera_qos(), camera_qos(), *sent, *received);
  EXPECT_EQ(received->width_px, 640);
  EXPECT_EQ(received->height_px, 480);
  ASSERT_EQ(received->rgb_jpeg._length, kJpegBytes);
  EXPECT_EQ(std::memcmp(received->rgb_jpeg._buffer, sent->rgb_jpeg._buffer, kJpegBytes), 0);
  ASSERT_EQ(received->depth_preview._length, 100u);
  EXPECT_EQ(received->depth_preview._buffer[99], 0xAB);
}

TEST(Topics, HeartbeatRoundTrip) {
  LinkConfig config;
  Heartbeat sent{};
  sent.vehicle_id = 6;
  sent.role = hq_msgs_ROLE_GROUND;
  sent.sender_id = 12;
  sent.sequence_number = 1;
  sent.t_ns = 42;
  Heartbeat received{};
  round_trip(heartbeat_qos(config), heartbeat_qos(config), sent, received);
  EXPECT_EQ(received.vehicle_id, 6u);
  EXPECT_EQ(received.role, hq_msgs_ROLE_GROUND);
  EXPECT_EQ(received.sender_id, 12u);
  EXPECT_EQ(received.t_ns, 42);
}

TEST(Topics, EventRoundTripKeepsText) {
  Event sent{};
  sent.vehicle_id = 8;
  sent.sequence_number = 3;
  sent.severity = hq_msgs_SEVERITY_WARNING;
  sent.code = 17;
  std::strncpy(sent.text, "command rejected: v_H_mps.x is NaN or Inf", sizeof(sent.text) - 1);
  Event received{};
  round_trip(event_qos(), event_qos(), sent, received);
  EXPECT_EQ(received.severity, hq_msgs_SEVERITY_WARNING);
  EXPECT_EQ(received.code, 17u);
  EXPECT_STREQ(received.text, "command rejected: v_H_mps.x is NaN or Inf");
}

TEST(Topics, ModeRequestWrittenBeforeReaderExistsReachesLateReader) {
  // transient-local: a vehicle that (re)joins still gets the last requests.
  Pair pair;
  Topic<ModeRequest> ground_topic(pair.ground);
  Writer<ModeRequest> writer(pair.ground, ground_topic, mode_request_qos());
  ModeRequest sent{};
  sent.vehicle_id = 1;
  sent.sequence_number = 5;
  sent.requested_mode = hq_msgs_MODE_EXPLORE;
  ASSERT_TRUE(writer.write(sent));
  Topic<ModeRequest> vehicle_topic(pair.vehicle);
  Reader<ModeRequest> reader(pair.vehicle, vehicle_topic, mode_request_qos());
  ModeRequest received{};
  ASSERT_TRUE(test::take_within(pair.vehicle, reader, received));
  EXPECT_EQ(received.sequence_number, 5u);
  EXPECT_EQ(received.requested_mode, hq_msgs_MODE_EXPLORE);
}

TEST(Topics, ReaderTakesPerVehicleInstance) {
  // GIVEN one ground commanding vehicles 1 and 2
  LinkConfig config;
  Pair pair;
  Topic<VelocityCommand> ground_topic(pair.ground);
  Topic<VelocityCommand> vehicle_topic(pair.vehicle);
  Reader<VelocityCommand> reader(pair.vehicle, vehicle_topic, command_qos(config, End::kReader));
  Writer<VelocityCommand> writer(pair.ground, ground_topic, command_qos(config, End::kWriter));
  ASSERT_TRUE(test::wait_for_readers(pair.ground, writer, 1));
  VelocityCommand to_one{};
  to_one.vehicle_id = 1;
  to_one.v_H_mps.x = 1.0F;
  VelocityCommand to_two{};
  to_two.vehicle_id = 2;
  to_two.v_H_mps.x = 2.0F;
  ASSERT_TRUE(writer.write(to_one));
  ASSERT_TRUE(writer.write(to_two));
  // keep-last-1 is per instance: both vehicles' latest commands are held
  VelocityCommand key{};
  key.vehicle_id = 2;
  dds_instance_handle_t two = DDS_HANDLE_NIL;
  WaitSet waitset(pair.vehicle);
  ReadCondition condition(reader);
  waitset.attach(condition.handle(), 1);
  std::array<dds_attach_t, 1> triggered{};
  for (int attempt = 0; attempt < 50 && two == DDS_HANDLE_NIL; ++attempt) {
    waitset.wait(triggered, DDS_MSECS(100));
    two = reader.lookup_instance(key);
  }
  ASSERT_NE(two, DDS_HANDLE_NIL);
  // WHEN vehicle 2 takes its instance THEN it gets only its own command
  VelocityCommand received{};
  dds_sample_info_t info{};
  ASSERT_TRUE(reader.take_instance(received, info, two));
  EXPECT_EQ(received.vehicle_id, 2u);
  EXPECT_EQ(received.v_H_mps.x, 2.0F);
  EXPECT_FALSE(reader.take_instance(received, info, two));
  // AND vehicle 1's command is still there for it
  ASSERT_TRUE(test::take_within(pair.vehicle, reader, received));
  EXPECT_EQ(received.vehicle_id, 1u);
  EXPECT_EQ(received.v_H_mps.x, 1.0F);
}

TEST(Topics, WriteAndTakeIntoPreallocatedSampleDoNotCallNew) {
  // Counts C++ operator new only (the wrappers' own cost); Cyclone's C internals use malloc,
  // which this counter does not see.
  LinkConfig config;
  Pair pair;
  Topic<VelocityCommand> ground_topic(pair.ground);
  Topic<VelocityCommand> vehicle_topic(pair.vehicle);
  Reader<VelocityCommand> reader(pair.vehicle, vehicle_topic, command_qos(config, End::kReader));
  Writer<VelocityCommand> writer(pair.ground, ground_topic, command_qos(config, End::kWriter));
  ASSERT_TRUE(test::wait_for_readers(pair.ground, writer, 1));
  WaitSet waitset(pair.vehicle);
  ReadCondition condition(reader);
  waitset.attach(condition.handle(), 1);
  std::array<dds_attach_t, 1> triggered{};
  VelocityCommand command{};
  VelocityCommand received{};
  dds_sample_info_t info{};
  int taken = 0;
  const long before = hq::testing::allocation_count();
  for (std::uint64_t i = 0; i < 100; ++i) {
    command.sequence_number = i;
    ASSERT_TRUE(writer.write(command));
    if (waitset.wait(triggered, test::kPatience) > 0) {
      while (reader.take(received, info)) ++taken;
    }
  }
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
  EXPECT_GT(taken, 0);
}

}  // namespace
}  // namespace hq::link
