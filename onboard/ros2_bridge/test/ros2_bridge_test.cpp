// The bridge on a private loopback domain: the DDS names and types a ROS 2 machine sees, the
// values in ROS frames, XCDR1 on the wire, and cmd_vel_in as the link's command.
#include "hq/ros2_bridge/ros2_bridge.hpp"

#include "hq/geometry/ros_frames.hpp"
#include "hq/link/test_support.hpp"

#include <dds/ddsi/ddsi_serdata.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

namespace hq::ros2_bridge {
namespace {

using link::test::private_domain_id;
using link::test::take_within;

link::LinkConfig ros2_config() {
  link::LinkConfig config;
  config.domain_id = private_domain_id();
  config.vehicle_id = 3;
  config.security.enabled = false;
  config.ros2.enabled = true;
  return config;
}

std::string type_name(dds_entity_t topic) {
  std::array<char, 256> name{};
  dds_get_type_name(topic, name.data(), name.size());
  return name.data();
}

// "" for an entity that is not a topic (dds_get_name fails on it).
std::string topic_name(dds_entity_t topic) {
  std::array<char, 256> name{};
  if (dds_get_name(topic, name.data(), name.size()) < 0) return "";
  return name.data();
}

struct Fixture {
  Fixture() { bridge.set_clock(RosClock::simulated_time()); }  // stamps = the states' t_ns
  link::LinkConfig config = ros2_config();
  link::Participant participant{config.domain_id};
  Ros2Bridge bridge{participant, config};
};

template <typename T>
struct Probe {
  Probe(const link::Participant& p, const std::string& name)
      : topic(p, name), reader(p, topic, ros2_qos()) {}
  link::Topic<T> topic;
  link::Reader<T> reader;
  link::Sample<T> sample;
};

link::VehicleState level_state() {
  link::VehicleState s{};
  s.vehicle_id = 3;
  s.t_ns = 12'345'678'901;
  s.v_H_mps = {1.0F, 0.5F, -0.25F};  // forward, right, up (NED z -)
  s.omega_B_radps = {0.1F, 0.2F, 0.3F};
  s.estimator_health = hq_msgs_HEALTH_OK;
  return s;
}

// The DDS topic and type names are rmw_cyclonedds's: rt/<ns>/<topic>, pkg::msg::dds_::Type_.
TEST(Ros2Bridge, TopicAndTypeNamesAreThoseRos2Uses) {
  Fixture f;
  EXPECT_EQ(f.bridge.ros_namespace(), "hq3");
  const std::pair<const char*, const char*> expected[] = {
      {"rt/hq3/odom", "nav_msgs::msg::dds_::Odometry_"},
      {"rt/hq3/imu", "sensor_msgs::msg::dds_::Imu_"},
      {"rt/tf", "tf2_msgs::msg::dds_::TFMessage_"},
      {"rt/hq3/obstacles", "sensor_msgs::msg::dds_::PointCloud2_"},
      {"rt/hq3/camera/image/compressed", "sensor_msgs::msg::dds_::CompressedImage_"},
      {"rt/hq3/camera/camera_info", "sensor_msgs::msg::dds_::CameraInfo_"},
      {"rt/hq3/cmd_vel_in", "geometry_msgs::msg::dds_::TwistStamped_"},
      {"rt/clock", "rosgraph_msgs::msg::dds_::Clock_"},
      {"rt/tf_static", "tf2_msgs::msg::dds_::TFMessage_"},
      {"rt/hq3/mode_request", "std_msgs::msg::dds_::String_"},
      {"rt/hq3/mode_status", "std_msgs::msg::dds_::String_"},
      {"ros_discovery_info", "rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"}};
  // The participant's topics are among its children.
  std::array<dds_entity_t, 64> children{};
  const dds_return_t n = dds_get_children(f.participant.handle(), children.data(), children.size());
  ASSERT_GT(n, 0);
  for (const auto& [name, type] : expected) {
    bool found = false;
    for (std::size_t i = 0; i < static_cast<std::size_t>(n); ++i) {
      if (topic_name(children[i]) != name) continue;
      found = true;
      EXPECT_EQ(type_name(children[i]), type) << name;
    }
    EXPECT_TRUE(found) << name;
  }
}

// On a real vehicle ROS time is the epoch: the chain's monotonic stamp plus one offset, within
// a few milliseconds of the system clock read now; stamps split into sec and nanosec in
// [0, 1e9) for negative times too, and read back exactly.
TEST(RosClock, RealVehicleStampsAreTheEpochAndSimulatedOnesTheSimulatedTime) {
  const RosClock epoch = RosClock::epoch_from_monotonic();
  EXPECT_FALSE(epoch.is_simulated());
  const auto ns = [](auto d) {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(d.time_since_epoch()).count();
  };
  const std::int64_t monotonic_ns = ns(std::chrono::steady_clock::now());
  const std::int64_t system_ns = ns(std::chrono::system_clock::now());
  EXPECT_NEAR(static_cast<double>(epoch.ros_ns(monotonic_ns) - system_ns), 0.0, 5e6);
  EXPECT_EQ(epoch.chain_ns(epoch.ros_ns(monotonic_ns)), monotonic_ns);
  const RosClock sim = RosClock::simulated_time();
  EXPECT_TRUE(sim.is_simulated());
  EXPECT_EQ(sim.ros_ns(12'345), 12'345);
  const auto t = to_ros_time(-1'500'000'000);
  EXPECT_EQ(t.sec, -2);
  EXPECT_EQ(t.nanosec, 500'000'000U);
  EXPECT_EQ(from_ros_time(t), -1'500'000'000);
  EXPECT_EQ(from_ros_time(to_ros_time(1'797'000'000'123'456'789)), 1'797'000'000'123'456'789);
}

// Simulated: every state's stamp goes out on /clock too, and the stamps are that time; a real
// vehicle publishes no /clock (ROS nodes use their system clock) and stamps in the epoch.
TEST(Ros2Bridge, PublishesClockOnlyWhenSimulated) {
  Fixture f;
  Probe<RosClockMsg> clock(f.participant, "rt/clock");
  Probe<Odometry> odom(f.participant, "rt/hq3/odom");
  f.bridge.publish_state(level_state());
  ASSERT_TRUE(take_within(f.participant, clock.reader, *clock.sample));
  EXPECT_EQ(clock.sample->clock.sec, 12);
  EXPECT_EQ(clock.sample->clock.nanosec, 345'678'901U);
  EXPECT_EQ(f.bridge.counters().clocks_published, 1U);

  f.bridge.set_clock(RosClock(1'797'000'000'000'000'000, false));
  f.bridge.publish_state(level_state());
  ASSERT_TRUE(take_within(f.participant, odom.reader, *odom.sample));  // the first state's
  ASSERT_TRUE(take_within(f.participant, odom.reader, *odom.sample));
  EXPECT_EQ(odom.sample->header.stamp.sec, 1'797'000'012);
  EXPECT_EQ(odom.sample->header.stamp.nanosec, 345'678'901U);
  EXPECT_EQ(f.bridge.counters().clocks_published, 1U);
  dds_sample_info_t info{};
  EXPECT_FALSE(clock.reader.take(*clock.sample, info));
}

// GIVEN a level vehicle flying forward-right and climbing WHEN its state is published THEN the
// odometry's twist is that velocity in FLU, the rates flipped likewise, the stamp split into
// sec and nanosec, and the unknown pose marked with covariance[0] = -1.
TEST(Ros2Bridge, OdometryIsInRosFramesAndMarksTheUnknownPose) {
  Fixture f;
  Probe<Odometry> odom(f.participant, "rt/hq3/odom");
  Probe<Imu> imu(f.participant, "rt/hq3/imu");
  Probe<TfMessage> tf(f.participant, "rt/tf");
  f.bridge.publish_state(level_state());
  ASSERT_TRUE(take_within(f.participant, odom.reader, *odom.sample));
  const Odometry& o = *odom.sample;
  EXPECT_EQ(o.header.stamp.sec, 12);
  EXPECT_EQ(o.header.stamp.nanosec, 345'678'901U);
  EXPECT_STREQ(o.header.frame_id, "hq3/odom");
  EXPECT_STREQ(o.child_frame_id, "hq3/base_link");
  EXPECT_DOUBLE_EQ(o.twist.twist.linear.x, 1.0);
  EXPECT_DOUBLE_EQ(o.twist.twist.linear.y, -0.5);  // right -> -left
  EXPECT_DOUBLE_EQ(o.twist.twist.linear.z, 0.25);  // up
  EXPECT_NEAR(o.twist.twist.angular.z, -0.3, 1e-6);
  EXPECT_EQ(o.pose.covariance[0], -1.0);
  EXPECT_EQ(o.twist.covariance[0], 0.0);
  EXPECT_EQ(o.pose.pose.position.x, 0.0);
  // Yaw unknown, taken as 0: NED yaw 0 faces north, ENU's y.
  const Eigen::Quaterniond q(o.pose.pose.orientation.w, o.pose.pose.orientation.x,
                             o.pose.pose.orientation.y, o.pose.pose.orientation.z);
  EXPECT_LT((q * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 1e-9);

  ASSERT_TRUE(take_within(f.participant, imu.reader, *imu.sample));
  EXPECT_STREQ(imu.sample->header.frame_id, "hq3/base_link");
  EXPECT_NEAR(imu.sample->angular_velocity.y, -0.2, 1e-6);
  EXPECT_EQ(imu.sample->linear_acceleration_covariance[0], -1.0);
  EXPECT_DOUBLE_EQ(imu.sample->orientation_covariance[8], kUnknownYawVariance_rad2);

  ASSERT_TRUE(take_within(f.participant, tf.reader, *tf.sample));
  ASSERT_EQ(tf.sample->transforms._length, 1U);
  const TransformStamped& t = tf.sample->transforms._buffer[0];
  EXPECT_STREQ(t.header.frame_id, "hq3/odom");
  EXPECT_STREQ(t.child_frame_id, "hq3/base_link");
  EXPECT_DOUBLE_EQ(t.transform.rotation.w, o.pose.pose.orientation.w);
}

// GIVEN the odometry's integrated pose (2 m north, 1 m west, 1.5 m up, facing east) and the
// marker filter anchored 1 m further north THEN the odometry is that pose in ENU with its
// covariances (position and yaw sigma, the estimator's velocity sigma), /tf carries
// odom -> base_link and map -> odom (1 m north, no turn), and a lost estimator marks the twist.
TEST(Ros2Bridge, OdomPoseGoesOutInEnuWithItsCovariancesAndMapToOdom) {
  Fixture f;
  Probe<Odometry> odom(f.participant, "rt/hq3/odom");
  Probe<Imu> imu(f.participant, "rt/hq3/imu");
  Probe<TfMessage> tf(f.participant, "rt/tf");
  link::VehicleState s = level_state();
  s.odom_valid = true;
  s.p_odom_m = {2.0F, -1.0F, -1.5F};
  s.yaw_odom_rad = static_cast<float>(M_PI / 2);
  s.odom_position_sigma_m = 0.3F;
  s.odom_yaw_sigma_rad = 0.05F;
  s.v_H_sigma_mps = {0.02F, 0.03F, 0.04F};
  s.position_valid = true;
  s.p_W_m = {3.0F, -1.0F, -1.5F};
  s.yaw_W_rad = static_cast<float>(M_PI / 2);
  f.bridge.publish_state(s);
  ASSERT_TRUE(take_within(f.participant, odom.reader, *odom.sample));
  const Odometry& o = *odom.sample;
  EXPECT_DOUBLE_EQ(o.pose.pose.position.x, -1.0);
  EXPECT_DOUBLE_EQ(o.pose.pose.position.y, 2.0);
  EXPECT_DOUBLE_EQ(o.pose.pose.position.z, 1.5);
  EXPECT_NEAR(o.pose.covariance[0], 0.09, 1e-6);
  EXPECT_NEAR(o.pose.covariance[7], 0.09, 1e-6);
  EXPECT_NEAR(o.pose.covariance[35], 0.0025, 1e-7);
  EXPECT_DOUBLE_EQ(o.pose.covariance[21], kRollPitchVariance_rad2);
  EXPECT_NEAR(o.twist.covariance[0], 0.0004, 1e-8);
  EXPECT_NEAR(o.twist.covariance[7], 0.0009, 1e-8);
  EXPECT_NEAR(o.twist.covariance[14], 0.0016, 1e-8);
  EXPECT_DOUBLE_EQ(o.twist.covariance[35], kRateVariance_rad2ps2);
  const Eigen::Quaterniond q(o.pose.pose.orientation.w, o.pose.pose.orientation.x,
                             o.pose.pose.orientation.y, o.pose.pose.orientation.z);
  EXPECT_LT((q * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitX()).norm(), 1e-6);  // east

  ASSERT_TRUE(take_within(f.participant, imu.reader, *imu.sample));
  EXPECT_DOUBLE_EQ(imu.sample->orientation_covariance[8], kUnknownYawVariance_rad2);
  EXPECT_DOUBLE_EQ(imu.sample->orientation_covariance[0], kRollPitchVariance_rad2);
  EXPECT_DOUBLE_EQ(imu.sample->angular_velocity_covariance[4], kRateVariance_rad2ps2);

  ASSERT_TRUE(take_within(f.participant, tf.reader, *tf.sample));
  ASSERT_EQ(tf.sample->transforms._length, 2U);
  const TransformStamped& map_odom = tf.sample->transforms._buffer[1];
  EXPECT_STREQ(map_odom.header.frame_id, "hq3/map");
  EXPECT_STREQ(map_odom.child_frame_id, "hq3/odom");
  EXPECT_NEAR(map_odom.transform.translation.x, 0.0, 1e-6);
  EXPECT_NEAR(map_odom.transform.translation.y, 1.0, 1e-6);
  EXPECT_NEAR(map_odom.transform.translation.z, 0.0, 1e-6);
  EXPECT_NEAR(std::abs(map_odom.transform.rotation.w), 1.0, 1e-6);

  s.estimator_health = hq_msgs_HEALTH_LOST;
  f.bridge.publish_state(s);
  ASSERT_TRUE(take_within(f.participant, odom.reader, *odom.sample));
  EXPECT_EQ(odom.sample->twist.covariance[0], -1.0);
}

// /tf_static as tf2's static broadcaster: base_link -> camera_link -> camera_optical of the
// mount, transient local, so a reader that joins after it was written still gets it.
TEST(Ros2Bridge, TfStaticReachesAReaderThatJoinsLater) {
  Fixture f;
  const Eigen::Isometry3d T_B_C =
      Eigen::Translation3d(0.1, 0.0, 0.05) *
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY());  // optical z along body x
  f.bridge.set_camera_mount(geometry::CameraMount(T_B_C));
  f.bridge.publish_state(level_state());
  link::Topic<TfMessage> topic(f.participant, "rt/tf_static");
  link::Reader<TfMessage> late(f.participant, topic, tf_static_qos());
  link::Sample<TfMessage> sample;
  ASSERT_TRUE(take_within(f.participant, late, *sample));
  ASSERT_EQ(sample->transforms._length, 2U);
  const TransformStamped& link = sample->transforms._buffer[0];
  const TransformStamped& optical = sample->transforms._buffer[1];
  EXPECT_STREQ(link.header.frame_id, "hq3/base_link");
  EXPECT_STREQ(link.child_frame_id, "hq3/camera_link");
  EXPECT_STREQ(optical.header.frame_id, "hq3/camera_link");
  EXPECT_STREQ(optical.child_frame_id, "hq3/camera_optical");
  const geometry::RosCameraFrames frames =
      geometry::ros_camera_frames(geometry::CameraMount(T_B_C));
  EXPECT_NEAR(link.transform.translation.x, frames.T_F_camera_link.translation().x(), 1e-9);
  EXPECT_NEAR(link.transform.translation.z, frames.T_F_camera_link.translation().z(), 1e-9);
  EXPECT_NEAR(link.transform.translation.x, 0.1, 1e-9);
  EXPECT_NEAR(link.transform.translation.z, -0.05, 1e-9);  // FRD z down -> FLU z up
  // Written once: the next state writes no second sample.
  f.bridge.publish_state(level_state());
  dds_sample_info_t info{};
  EXPECT_FALSE(late.take(*sample, info));
}

// The state's cloud (body FRD) goes out as a PointCloud2 of float32 x, y, z in FLU.
TEST(Ros2Bridge, ObstacleCloudIsAPointCloud2InFlu) {
  Fixture f;
  Probe<PointCloud2> cloud(f.participant, "rt/hq3/obstacles");
  link::Sample<link::VehicleState> s;
  *s = level_state();
  link::reserve(s->obstacle_points_B_m, 2);
  s->obstacle_points_B_m._buffer[0] = {1.0F, 2.0F, 3.0F};
  s->obstacle_points_B_m._buffer[1] = {-4.0F, 0.5F, -0.25F};
  s->obstacle_points_B_m._length = 2;
  f.bridge.publish_state(*s);
  ASSERT_TRUE(take_within(f.participant, cloud.reader, *cloud.sample));
  const PointCloud2& c = *cloud.sample;
  EXPECT_EQ(c.height, 1U);
  EXPECT_EQ(c.width, 2U);
  EXPECT_EQ(c.point_step, 12U);
  EXPECT_EQ(c.row_step, 24U);
  ASSERT_EQ(c.fields._length, 3U);
  EXPECT_STREQ(c.fields._buffer[2].name, "z");
  EXPECT_EQ(c.fields._buffer[2].offset, 8U);
  EXPECT_EQ(c.fields._buffer[2].datatype, 7);
  ASSERT_EQ(c.data._length, 24U);
  float xyz[6];
  std::memcpy(xyz, c.data._buffer, sizeof xyz);
  EXPECT_THAT(xyz, ::testing::ElementsAre(1.0F, -2.0F, -3.0F, -4.0F, -0.5F, 0.25F));
  EXPECT_EQ(f.bridge.counters().clouds_published, 1U);
}

TEST(Ros2Bridge, CameraGoesOutAsCompressedImageWithCameraInfo) {
  Fixture f;
  Probe<CompressedImage> image(f.participant, "rt/hq3/camera/image/compressed");
  Probe<CameraInfo> info(f.participant, "rt/hq3/camera/camera_info");
  geometry::PinholeCamera camera;
  camera.fx = 500;
  camera.fy = 510;
  camera.cx = 319.5;
  camera.cy = 239.5;
  camera.width = 640;
  camera.height = 480;
  f.bridge.set_camera(camera);
  link::Sample<link::CameraFrame> frame;
  frame->t_ns = 2'000'000'000;
  link::reserve(frame->rgb_jpeg, 4);
  const std::uint8_t jpeg[4] = {0xFF, 0xD8, 0xFF, 0xD9};
  std::memcpy(frame->rgb_jpeg._buffer, jpeg, 4);
  frame->rgb_jpeg._length = 4;
  f.bridge.publish_camera(*frame);
  ASSERT_TRUE(take_within(f.participant, image.reader, *image.sample));
  EXPECT_STREQ(image.sample->format, "jpeg");
  EXPECT_STREQ(image.sample->header.frame_id, "hq3/camera_optical");
  ASSERT_EQ(image.sample->data._length, 4U);
  EXPECT_EQ(image.sample->data._buffer[1], 0xD8);
  ASSERT_TRUE(take_within(f.participant, info.reader, *info.sample));
  EXPECT_EQ(info.sample->width, 640U);
  EXPECT_EQ(info.sample->k[0], 500.0);
  EXPECT_EQ(info.sample->k[5], 239.5);
  EXPECT_EQ(info.sample->p[2], 319.5);
  EXPECT_EQ(info.sample->d._length, 5U);
  EXPECT_EQ(info.sample->header.stamp.sec, 2);
}

// XCDR1, as rmw_cyclonedds writes and reads: the serialized sample starts with the CDR_LE
// encapsulation 00 01 (XCDR2 would be 00 07).
TEST(Ros2Bridge, WritesXcdr1) {
  Fixture f;
  link::Topic<Odometry> topic(f.participant, "rt/hq3/odom");
  const dds_entity_t reader =
      dds_create_reader(f.participant.handle(), topic.handle(), ros2_qos().get(), nullptr);
  ASSERT_GT(reader, 0);
  f.bridge.publish_state(level_state());
  ddsi_serdata* sample = nullptr;
  dds_sample_info_t info{};
  for (int i = 0; i < 500 && dds_takecdr(reader, &sample, 1, &info, DDS_ANY_STATE) <= 0; ++i) {
    dds_sleepfor(DDS_MSECS(10));
  }
  ASSERT_NE(sample, nullptr);
  std::uint8_t header[4]{};
  ddsi_serdata_to_ser(sample, 0, 4, header);
  ddsi_serdata_unref(sample);
  EXPECT_EQ(header[0], 0x00);
  EXPECT_EQ(header[1], 0x01);
}

// A TwistStamped on cmd_vel_in becomes the link's command in H from the ROS 2 station.
TEST(Ros2Bridge, CmdVelInBecomesALinkCommandInH) {
  Fixture f;
  link::Topic<TwistStamped> topic(f.participant, "rt/hq3/cmd_vel_in");
  link::Writer<TwistStamped> writer(f.participant, topic, ros2_qos());
  std::string frame = "base_link";
  TwistStamped twist{};
  twist.header.frame_id = frame.data();
  twist.twist.linear = {0.5, 0.2, 0.1};
  twist.twist.angular = {0.0, 0.0, 0.4};
  ASSERT_TRUE(writer.write(twist)) << writer.last_error();
  link::VelocityCommand command{};
  for (int i = 0; i < 500 && !f.bridge.take_command(0, command); ++i) dds_sleepfor(DDS_MSECS(10));
  EXPECT_EQ(command.vehicle_id, 3U);
  EXPECT_EQ(command.station_id, 250U);
  EXPECT_EQ(command.t_ns, 0);
  EXPECT_FLOAT_EQ(command.v_H_mps.x, 0.5F);
  EXPECT_FLOAT_EQ(command.v_H_mps.y, -0.2F);
  EXPECT_FLOAT_EQ(command.v_H_mps.z, -0.1F);
  EXPECT_FLOAT_EQ(command.yaw_rate_radps, -0.4F);
  EXPECT_EQ(f.bridge.counters().commands_received, 1U);
}

// A Twist on cmd_vel, as teleop_twist_keyboard and teleop_twist_joy publish by default, flies
// as a TwistStamped does.
TEST(Ros2Bridge, TwistOnCmdVelBecomesALinkCommandInH) {
  Fixture f;
  link::Topic<Twist> topic(f.participant, "rt/hq3/cmd_vel");
  link::Writer<Twist> writer(f.participant, topic, ros2_qos());
  const Twist twist{{0.5, 0.2, 0.1}, {0.0, 0.0, 0.4}};
  ASSERT_TRUE(writer.write(twist)) << writer.last_error();
  link::VelocityCommand command{};
  for (int i = 0; i < 500 && !f.bridge.take_command(0, command); ++i) dds_sleepfor(DDS_MSECS(10));
  EXPECT_EQ(command.station_id, 250U);
  EXPECT_FLOAT_EQ(command.v_H_mps.x, 0.5F);
  EXPECT_FLOAT_EQ(command.v_H_mps.y, -0.2F);
  EXPECT_FLOAT_EQ(command.yaw_rate_radps, -0.4F);
  EXPECT_EQ(f.bridge.counters().commands_received, 1U);
}

// GIVEN ROS time 100 s (simulated) WHEN TwistStamped commands arrive stamped 99.6 s (fresh),
// 99.4 s (older than kMaxCommandAge_ns), 100.6 s (from the future) and 0 (unstamped) THEN the
// fresh and the unstamped ones fly, the other two are dropped and counted stale.
TEST(Ros2Bridge, StaleStampedCommandsAreDropped) {
  Fixture f;
  link::Topic<TwistStamped> topic(f.participant, "rt/hq3/cmd_vel_in");
  link::Writer<TwistStamped> writer(f.participant, topic, ros2_qos());
  std::string frame = "base_link";
  const std::int64_t now_ns = 100'000'000'000;
  const std::int64_t stamps_ns[] = {now_ns - 400'000'000, now_ns - 600'000'000,
                                    now_ns + 600'000'000, 0};
  const double speeds[] = {0.1, 0.2, 0.3, 0.4};
  for (int i = 0; i < 4; ++i) {
    TwistStamped twist{};
    twist.header.frame_id = frame.data();
    twist.header.stamp = to_ros_time(stamps_ns[i]);
    twist.twist.linear = {speeds[i], 0.0, 0.0};
    ASSERT_TRUE(writer.write(twist)) << writer.last_error();
  }
  std::vector<float> flown;
  link::VelocityCommand command{};
  for (int i = 0; i < 300 && flown.size() < 2; ++i) {
    while (f.bridge.take_command(now_ns, command)) flown.push_back(command.v_H_mps.x);
    dds_sleepfor(DDS_MSECS(10));
  }
  ASSERT_EQ(flown.size(), 2U);
  EXPECT_FLOAT_EQ(flown[0], 0.1F);
  EXPECT_FLOAT_EQ(flown[1], 0.4F);
  EXPECT_EQ(f.bridge.counters().commands_stale, 2U);
  EXPECT_EQ(f.bridge.counters().commands_received, 4U);
  EXPECT_EQ(kMaxCommandAge_ns, 500'000'000);
}

// Every mode text a ROS node may send, as the ground's request would carry it; anything else
// is refused with a reason, never guessed.
TEST(ParseModeRequest, ReadsEveryModeAndRefusesTheRest) {
  RosModeRequest r;
  EXPECT_EQ(parse_mode_request("take_off", r), nullptr);
  EXPECT_EQ(r.mode, hq_msgs_MODE_TELEOP);
  EXPECT_TRUE(r.take_off);
  const std::pair<const char*, hq_msgs_Mode> plain[] = {{"land", hq_msgs_MODE_LAND},
                                                        {" hover\n", hq_msgs_MODE_HOVER},
                                                        {"teleop", hq_msgs_MODE_TELEOP},
                                                        {"explore", hq_msgs_MODE_EXPLORE},
                                                        {"marker", hq_msgs_MODE_MARKER}};
  for (const auto& [text, mode] : plain) {
    ASSERT_EQ(parse_mode_request(text, r), nullptr) << text;
    EXPECT_EQ(r.mode, mode) << text;
    EXPECT_FALSE(r.take_off) << text;
    EXPECT_EQ(r.marker_task, hq_msgs_MARKER_TASK_NONE) << text;
  }
  ASSERT_EQ(parse_mode_request("marker go_to 7", r), nullptr);
  EXPECT_EQ(r.mode, hq_msgs_MODE_MARKER);
  EXPECT_EQ(r.marker_task, hq_msgs_MARKER_TASK_GO_TO);
  EXPECT_EQ(r.target_id, 7);
  ASSERT_EQ(parse_mode_request("marker land 0", r), nullptr);
  EXPECT_EQ(r.marker_task, hq_msgs_MARKER_TASK_LAND);
  using ::testing::HasSubstr;
  const std::pair<std::string, const char*> refused[] = {
      {"fly_upside_down", "unknown mode"},
      {"", "unknown mode"},
      {"Land", "unknown mode"},
      {"take_off now", "unknown mode"},
      {"marker spin 3", "unknown marker task"},
      {"marker hold", "needs a marker id"},
      {"marker hold -1", "not an integer >= 0"},
      {"marker hold 3x", "not an integer >= 0"},
      {"marker hold 99999999999", "not an integer >= 0"},
      {std::string(kMaxModeRequestChars + 1, 'a'), "longer than any mode request"}};
  for (const auto& [text, why] : refused) {
    const char* reason = parse_mode_request(text, r);
    ASSERT_NE(reason, nullptr) << text;
    EXPECT_THAT(reason, HasSubstr(why)) << text;
  }
}

// mode_request texts are taken in order; the answers go out on mode_status.
TEST(Ros2Bridge, TakesModeRequestTextsAndPublishesTheAnswers) {
  Fixture f;
  link::Topic<RosString> request_topic(f.participant, "rt/hq3/mode_request");
  link::Writer<RosString> requests(f.participant, request_topic, ros2_qos());
  Probe<RosString> status(f.participant, "rt/hq3/mode_status");
  std::string text = "land";
  RosString request{};
  request.data = text.data();
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  const char* taken = nullptr;
  while (taken == nullptr && std::chrono::steady_clock::now() < deadline) {
    if (requests.matched_readers() > 0 && f.bridge.counters().mode_requests_received == 0) {
      requests.write(request);
    }
    taken = f.bridge.take_mode_request();
  }
  ASSERT_NE(taken, nullptr);
  EXPECT_STREQ(taken, "land");
  EXPECT_EQ(f.bridge.take_mode_request(), nullptr);
  f.bridge.publish_mode_status("mode land accepted");
  ASSERT_TRUE(take_within(f.participant, status.reader, *status.sample));
  EXPECT_STREQ(status.sample->data, "mode land accepted");
  EXPECT_EQ(f.bridge.counters().mode_answers_published, 1U);
}

// ros_discovery_info, read by a ROS tool that starts later (transient local): one node,
// haptiquad_<vehicle id> in "/", with the GIDs (16-byte GUIDs, ROS 2 Iron+) of the bridge's
// readers and writers, all on the participant that announces them.
TEST(Ros2Bridge, AnnouncesItsNodeOnRosDiscoveryInfo) {
  Fixture f;
  link::Topic<ParticipantEntitiesInfo> topic(f.participant, "ros_discovery_info");
  link::Reader<ParticipantEntitiesInfo> late(f.participant, topic, discovery_info_qos());
  link::Sample<ParticipantEntitiesInfo> info;
  ASSERT_TRUE(take_within(f.participant, late, *info));
  dds_guid_t participant{};
  ASSERT_EQ(dds_get_guid(f.participant.handle(), &participant), DDS_RETCODE_OK);
  EXPECT_EQ(std::memcmp(info->gid.data, participant.v, 16), 0);
  ASSERT_EQ(info->node_entities_info_seq._length, 1U);
  const NodeEntitiesInfo& node = info->node_entities_info_seq._buffer[0];
  EXPECT_STREQ(node.node_namespace, "/");
  EXPECT_STREQ(node.node_name, "haptiquad_3");
  EXPECT_EQ(f.bridge.node_name(), "haptiquad_3");
  ASSERT_EQ(node.reader_gid_seq._length, 3U);  // cmd_vel_in, cmd_vel, mode_request
  ASSERT_EQ(node.writer_gid_seq._length, 9U);  // odom .. mode_status
  std::vector<std::string> gids;
  for (const auto& seq : {node.reader_gid_seq, node.writer_gid_seq}) {
    for (std::uint32_t i = 0; i < seq._length; ++i) {
      const Gid& g = seq._buffer[i];
      // A GUID's first 12 bytes are its participant's prefix.
      EXPECT_EQ(std::memcmp(g.data, participant.v, 12), 0) << i;
      gids.emplace_back(reinterpret_cast<const char*>(g.data), 16);
    }
  }
  std::sort(gids.begin(), gids.end());
  EXPECT_EQ(std::unique(gids.begin(), gids.end()), gids.end()) << "two entities share a GID";
}

// The node name comes from link.ros2.node_name; a name ROS would not take is refused.
TEST(Ros2Bridge, NodeNameFromConfigAndCheckedAsARosName) {
  link::LinkConfig config = ros2_config();
  config.ros2.node_name = "quad_east";
  EXPECT_EQ(link::ros2_node_name(config), "quad_east");
  for (const char* bad : {"9quad", "quad/east", "quad-east", "/quad"}) {
    config.ros2.node_name = bad;
    try {
      link::check_config(config);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), ::testing::HasSubstr("link.ros2.node_name")) << bad;
    }
  }
}

}  // namespace
}  // namespace hq::ros2_bridge
