// The CDR writer behind the flight record's ROS 2 bag: known layouts byte for byte (the
// encapsulation header, alignment counted after it, strings with their NUL), overflow, and
// every message the bridge publishes serialized exactly as Cyclone DDS puts it on the wire.
#include "hq/ros2_bridge/ros2_cdr.hpp"

#include "hq/link/test_support.hpp"
#include "hq/ros2_bridge/ros2_bridge.hpp"

#include <dds/ddsi/ddsi_serdata.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

namespace hq::ros2_bridge {
namespace {

using ::testing::ElementsAreArray;
using ::testing::HasSubstr;

std::vector<std::uint8_t> bytes_of(const CdrWriter& out) {
  return {out.data().begin(), out.data().end()};
}

TEST(CdrWriter, ClockIsTheHeaderThenSecondsAndNanoseconds) {
  CdrWriter out(64);
  ASSERT_TRUE(serialize(RosClockMsg{{1, 2}}, out));
  EXPECT_THAT(bytes_of(out), ElementsAreArray<std::uint8_t>({0x00, 0x01, 0x00, 0x00,  // CDR_LE
                                                             1, 0, 0, 0, 2, 0, 0, 0}));
}

TEST(CdrWriter, AlignsAfterTheHeaderAndCountsTheNulInStrings) {
  char parent[] = "a";
  char child[] = "bc";
  TransformStamped t{};
  t.header.stamp = {-1, 7};
  t.header.frame_id = parent;
  t.child_frame_id = child;
  t.transform.translation = {1.0, 0.0, 0.0};
  t.transform.rotation = {0.0, 0.0, 0.0, 1.0};
  TfMessage m{};
  m.transforms._buffer = &t;
  m.transforms._length = 1;
  m.transforms._maximum = 1;
  CdrWriter out(256);
  ASSERT_TRUE(serialize(m, out));
  const std::vector<std::uint8_t> b = bytes_of(out);
  // Body offsets (after the 4 header bytes): count 0, sec 4, nanosec 8, "a" 12 (length 2),
  // pad to 20, "bc" 20 (length 3) ends at 27, pad to 32 for the first float64, 7 doubles.
  ASSERT_EQ(b.size(), 4u + 32u + 7u * 8u);
  const std::vector<std::uint8_t> head(b.begin(), b.begin() + 4 + 32);
  EXPECT_THAT(head, ElementsAreArray<std::uint8_t>({
                        0x00, 0x01, 0x00, 0x00,                  // encapsulation
                        1,    0,    0,    0,                     // one transform
                        0xff, 0xff, 0xff, 0xff, 7,   0,   0, 0,  // stamp -1 s + 7 ns
                        2,    0,    0,    0,    'a', 0,          // "a" with its NUL
                        0,    0,                                 // pad to 4
                        3,    0,    0,    0,    'b', 'c', 0,     // "bc"
                        0,    0,    0,    0,    0                // pad to 8 (body offset 32)
                    }));
  double x = 0.0;
  std::memcpy(&x, b.data() + 4 + 32, 8);
  EXPECT_EQ(x, 1.0);
  double w = 0.0;
  std::memcpy(&w, b.data() + 4 + 32 + 6 * 8, 8);
  EXPECT_EQ(w, 1.0);
}

TEST(CdrWriter, AMessageLargerThanTheBufferIsRefusedNotTruncated) {
  Ros2Messages messages("hq1");
  link::Sample<link::VehicleState> state;
  CdrWriter small(64);
  EXPECT_FALSE(serialize(*messages.build_state(*state).odom, small));
  EXPECT_TRUE(small.overflowed());
  CdrWriter enough(1024);
  EXPECT_TRUE(serialize(*messages.build_state(*state).odom, enough));
  EXPECT_FALSE(enough.overflowed());
  // Reused: begin() starts over.
  EXPECT_TRUE(serialize(RosClockMsg{{3, 4}}, enough));
  EXPECT_EQ(enough.data().size(), 12u);
}

TEST(MessageDefinitions, NameEachTypeAndCarryTheirDependenciesOnce) {
  const MessageDefinition& odom = message_definition<Odometry>();
  EXPECT_STREQ(odom.name, "nav_msgs/msg/Odometry");
  const std::string text = odom.text;
  for (const char* dependency :
       {"MSG: std_msgs/Header\n", "MSG: builtin_interfaces/Time\n",
        "MSG: geometry_msgs/PoseWithCovariance\n", "MSG: geometry_msgs/Pose\n",
        "MSG: geometry_msgs/Point\n", "MSG: geometry_msgs/Quaternion\n",
        "MSG: geometry_msgs/TwistWithCovariance\n", "MSG: geometry_msgs/Twist\n",
        "MSG: geometry_msgs/Vector3\n"}) {
    EXPECT_EQ(text.find(dependency), text.rfind(dependency)) << dependency;
    EXPECT_THAT(text, HasSubstr(dependency));
  }
  EXPECT_THAT(text, HasSubstr("\n" + std::string(80, '=') + "\nMSG: "));
  EXPECT_STREQ(message_definition<TfMessage>().name, "tf2_msgs/msg/TFMessage");
  EXPECT_STREQ(message_definition<Imu>().name, "sensor_msgs/msg/Imu");
  EXPECT_STREQ(message_definition<PointCloud2>().name, "sensor_msgs/msg/PointCloud2");
  EXPECT_STREQ(message_definition<CompressedImage>().name, "sensor_msgs/msg/CompressedImage");
  EXPECT_STREQ(message_definition<CameraInfo>().name, "sensor_msgs/msg/CameraInfo");
  EXPECT_STREQ(message_definition<RosClockMsg>().name, "rosgraph_msgs/msg/Clock");
}

// Cyclone's bytes for `message`: written on a private domain with the bridge's QoS (XCDR1) and
// taken serialized, as the link log takes the link's samples.
template <typename T>
std::vector<std::uint8_t> cyclone_bytes(const link::Participant& participant, const T& message,
                                        const std::string& name) {
  const link::Topic<T> topic(participant, name);
  link::Reader<T> reader(participant, topic, ros2_qos());
  link::Writer<T> writer(participant, topic, ros2_qos());
  EXPECT_TRUE(writer.write(message));
  ddsi_serdata* sample = nullptr;
  dds_sample_info_t info{};
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (dds_takecdr(reader.handle(), &sample, 1, &info, DDS_ANY_STATE) <= 0) {
    if (std::chrono::steady_clock::now() > deadline) return {};
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  std::vector<std::uint8_t> bytes(ddsi_serdata_size(sample));
  ddsi_serdata_to_ser(sample, 0, bytes.size(), bytes.data());
  ddsi_serdata_unref(sample);
  return bytes;
}

// Ours against Cyclone's: the same representation identifier (CDR_LE), the same body; Cyclone
// may pad the end to 4 bytes (and say so in the options), which a reader ignores.
template <typename T>
void expect_same_as_cyclone(const link::Participant& participant, const T& message,
                            const std::string& name) {
  CdrWriter ours(1 << 20);
  ASSERT_TRUE(serialize(message, ours)) << name;
  const std::vector<std::uint8_t> mine = bytes_of(ours);
  const std::vector<std::uint8_t> theirs = cyclone_bytes(participant, message, name);
  ASSERT_GE(theirs.size(), mine.size()) << name;
  ASSERT_LT(theirs.size() - mine.size(), 4u) << name;
  EXPECT_EQ(theirs[0], 0x00) << name;
  EXPECT_EQ(theirs[1], 0x01) << name;
  const std::vector<std::uint8_t> their_body(theirs.begin() + 4,
                                             theirs.begin() + static_cast<long>(mine.size()));
  const std::vector<std::uint8_t> my_body(mine.begin() + 4, mine.end());
  EXPECT_EQ(my_body, their_body) << name;
  for (std::size_t i = mine.size(); i < theirs.size(); ++i) EXPECT_EQ(theirs[i], 0) << name;
}

TEST(CdrWriter, EveryBridgeMessageIsByteForByteWhatCycloneSerializes) {
  const link::Participant participant(link::test::private_domain_id());
  Ros2Messages messages("fleet/quad_2");
  messages.set_clock(RosClock(1'700'000'000'000'000'000, false));
  geometry::PinholeCamera camera;
  camera.width = 320;
  camera.height = 240;
  camera.fx = 300.5;
  camera.fy = 301.25;
  camera.cx = 160.0;
  camera.cy = 119.5;
  messages.set_camera(camera);
  Eigen::Isometry3d T_B_C = Eigen::Isometry3d::Identity();
  T_B_C.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix();
  T_B_C.translation() = Eigen::Vector3d(0.1, 0.02, -0.03);
  messages.set_camera_mount(geometry::CameraMount(T_B_C));

  link::Sample<link::VehicleState> state;
  state->t_ns = 12'345'678'901;
  state->roll_rad = 0.05f;
  state->pitch_rad = -0.02f;
  state->yaw_odom_rad = 1.2f;
  state->p_odom_m = {1.5f, -2.0f, -1.0f};
  state->v_H_mps = {0.3f, -0.1f, 0.05f};
  state->omega_B_radps = {0.01f, 0.02f, -0.3f};
  state->odom_valid = true;
  state->odom_position_sigma_m = 0.2f;
  state->position_valid = true;  // map -> odom as a second transform
  state->p_W_m = {4.0f, 1.0f, -1.1f};
  state->yaw_W_rad = 0.4f;
  link::reserve(state->obstacle_points_B_m, 5);
  state->obstacle_points_B_m._length = 5;
  for (std::uint32_t i = 0; i < 5; ++i) {
    state->obstacle_points_B_m._buffer[i] = {1.0f + static_cast<float>(i), 0.5f, -0.25f};
  }
  const StateMessages m = messages.build_state(*state);
  ASSERT_NE(m.tf_static, nullptr);
  ASSERT_NE(m.cloud, nullptr);
  ASSERT_EQ(m.tf->transforms._length, 2u);
  expect_same_as_cyclone(participant, *m.odom, "rt/fleet/quad_2/odom");
  expect_same_as_cyclone(participant, *m.imu, "rt/fleet/quad_2/imu");
  expect_same_as_cyclone(participant, *m.tf, "rt/tf");
  expect_same_as_cyclone(participant, *m.tf_static, "rt/tf_static");
  expect_same_as_cyclone(participant, *m.cloud, "rt/fleet/quad_2/obstacles");
  expect_same_as_cyclone(participant, RosClockMsg{{17, 3}}, "rt/clock");

  link::Sample<link::CameraFrame> frame;
  frame->t_ns = 12'400'000'000;
  const std::array<std::uint8_t, 7> jpeg = {0xff, 0xd8, 0xff, 0xe0, 1, 2, 3};  // odd length
  link::reserve(frame->rgb_jpeg, jpeg.size());
  frame->rgb_jpeg._length = static_cast<std::uint32_t>(jpeg.size());
  std::copy(jpeg.begin(), jpeg.end(), frame->rgb_jpeg._buffer);
  const CameraMessages c = messages.build_camera(*frame);
  ASSERT_NE(c.info, nullptr);
  expect_same_as_cyclone(participant, *c.image, "rt/fleet/quad_2/camera/image/compressed");
  expect_same_as_cyclone(participant, *c.info, "rt/fleet/quad_2/camera/camera_info");
}

}  // namespace
}  // namespace hq::ros2_bridge
