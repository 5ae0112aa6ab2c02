#pragma once
/// ROS 2-compatible topics beside the link (link.ros2, --ros2): what a ROS 2 machine with
/// rmw_cyclonedds on the same DDS domain sees as ROS topics, in ROS's frames
/// (hq/geometry/ros_frames.hpp), with ROS's naming (DDS topic rt/<ns>/<name>, type
/// pkg::msg::dds_::Type_), XCDR1 and ROS's default QoS (reliable, volatile, keep last 10):
///
/// | ROS topic                            | type                      | from |
/// |--------------------------------------|---------------------------|-----------------------------|
/// | /<ns>/odom                           | nav_msgs/Odometry         | every vehicle state | |
/// /<ns>/imu                            | sensor_msgs/Imu           | every vehicle state         |
/// | /tf                                  | tf2_msgs/TFMessage        | every vehicle state | |
/// | /tf_static                           | tf2_msgs/TFMessage        | once set_camera_mount() |
/// /<ns>/obstacles                      | sensor_msgs/PointCloud2   | states carrying the cloud   |
/// | /<ns>/camera/image/compressed        | sensor_msgs/CompressedImage | every camera frame sent |
/// | /<ns>/camera/camera_info             | sensor_msgs/CameraInfo    | with each image, once
/// set_camera() | | /<ns>/cmd_vel_in (read)              | geometry_msgs/TwistStamped | ROS teleop
/// -> take_command | | /<ns>/cmd_vel (read) | geometry_msgs/Twist | teleop_twist_keyboard/joy |

/// | /<ns>/mode_request (read)            | std_msgs/String           | take_mode_request() | |
/// /<ns>/mode_status                    | std_msgs/String           | publish_mode_status()      |
/// | ros_discovery_info                   | rmw_dds_common/ParticipantEntitiesInfo | once, at start
/// |
///
/// Mode requests are text on a topic, not a std_srvs-style service: a ROS 2 service on raw DDS
/// is a pair of rq/ rr/ topics whose samples carry rmw_cyclonedds's request header, which
/// `ros2 topic pub` cannot send and which a secured vehicle would have to grant twice; a string
/// every ROS tool can publish (`ros2 topic pub --once /hq1/mode_request std_msgs/msg/String
/// "{data: take_off}"`) with the answer on mode_status serves the same purpose. The texts:
/// parse_mode_request(). The requests go through the vehicle's gate (the link bridge's
/// fail-safe, then the mode controller), never around it; each answer, accepted or refused
/// with the reason, is a mode_status sample.
///
/// ros_discovery_info (reliable, transient local, keep last 1, as rmw_cyclonedds's): one node,
/// link.ros2.node_name in namespace "/", with the GUIDs of the bridge's readers and writers, so
/// `ros2 node list` and `ros2 node info` show the vehicle. ROS 2 Iron and later (Jazzy): the
/// Gid is the 16-byte GUID; Humble's 24-byte Gid is a different layout, not spoken.
///
/// Frame ids: <ns>/odom (ENU world E), <ns>/base_link (FLU body F), <ns>/camera_optical (C,
/// already ROS's optical convention). Stamps are ROS time (RosClock below): the epoch on a real
/// vehicle, the simulated time with /clock (rosgraph_msgs/Clock on rt/clock) in simulation.
///
/// Odometry: the pose is the odometry's integrated pose (VehicleState.p_odom_m, yaw_odom_rad:
/// odom NED-like -> E, continuous, REP-105), its covariance from its sigmas (position, yaw
/// relative to odom's start heading; roll and pitch about a degree), or pose.covariance[0] = -1
/// before it is valid. The twist is the estimated velocity in the child frame F (v_H rotated by
/// roll and pitch) and the gyro rates, its covariance the estimator's (v_H_sigma_mps), or
/// twist.covariance[0] = -1 while the estimator is lost. Imu: the same orientation and rates,
/// its yaw variance that of an unknown heading (pi^2/3: no compass); no acceleration
/// (linear_acceleration covariance[0] = -1). /tf: <ns>/odom -> <ns>/base_link, and while the
/// marker filter is anchored <ns>/map -> <ns>/odom (the marker map W NED -> ENU). /tf_static
/// (transient local, keep last 1, as tf2's static broadcaster): <ns>/base_link ->
/// <ns>/camera_link -> <ns>/camera_optical of the vehicle file's camera mount.
///
/// The bridge writes on the LinkBridge's own participant, from the same calls that publish the
/// link's state and camera (no thread, no extra JPEG encoding: the image is the link's bytes).
/// Publishing allocates nothing of its own: frame ids, the cloud and the image point at buffers
/// sized at construction.

#include "hq/link/link.hpp"
#include "hq/ros2_bridge/ros2_messages.hpp"

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace hq::link {
#define HQ_ROS2_TOPIC(Type)                                                   \
  template <>                                                                 \
  struct TopicTraits<Type> {                                                  \
    static const dds_topic_descriptor_t& descriptor() { return Type##_desc; } \
    static constexpr const char* kName = "";                                  \
  }
HQ_ROS2_TOPIC(nav_msgs_msg_dds__Odometry_);
HQ_ROS2_TOPIC(sensor_msgs_msg_dds__Imu_);
HQ_ROS2_TOPIC(tf2_msgs_msg_dds__TFMessage_);
HQ_ROS2_TOPIC(sensor_msgs_msg_dds__PointCloud2_);
HQ_ROS2_TOPIC(sensor_msgs_msg_dds__CompressedImage_);
HQ_ROS2_TOPIC(sensor_msgs_msg_dds__CameraInfo_);
HQ_ROS2_TOPIC(geometry_msgs_msg_dds__TwistStamped_);
HQ_ROS2_TOPIC(rosgraph_msgs_msg_dds__Clock_);
HQ_ROS2_TOPIC(geometry_msgs_msg_dds__Twist_);
HQ_ROS2_TOPIC(std_msgs_msg_dds__String_);
HQ_ROS2_TOPIC(rmw_dds_common_msg_dds__ParticipantEntitiesInfo_);
#undef HQ_ROS2_TOPIC
}  // namespace hq::link

namespace hq::ros2_bridge {

/// A TwistStamped on cmd_vel_in older than this (its stamp against the bridge's ROS time, the
/// same RosClock) is stale and dropped: a command from a queue, a replayed bag or a node whose
/// clock is off must not fly. A stamp of 0 (many teleop nodes leave it unset) is taken as
/// unstamped, as Twist on cmd_vel is. Newer than now by more than the same limit: also dropped.
inline constexpr std::int64_t kMaxCommandAge_ns = 500'000'000;

/// ROS 2's default QoS (rmw_qos_profile_default: reliable, volatile, keep last 10) with XCDR1,
/// the representation rmw_cyclonedds reads and writes.
link::Qos ros2_qos();
/// /tf_static's, as tf2's static broadcaster: reliable, transient local, keep last 1, so a
/// node that joins later still receives the fixed frames.
link::Qos tf_static_qos();
/// The command reader's: as ros2_qos() but best-effort, so it matches reliable and best-effort
/// ROS publishers alike (a retransmitted command would be late anyway).
link::Qos ros2_command_qos();
/// /clock's: as ros2_qos() but keep last 1 (only the latest time matters; rclcpp's clock
/// subscription is best-effort keep-last 1, which a reliable writer serves).
link::Qos clock_qos();

/// ros_discovery_info's: as tf_static_qos() (rmw_cyclonedds's: reliable, transient local, keep
/// last 1), so a ROS tool started later still learns the node.
link::Qos discovery_info_qos();

/// A mode request as the text on mode_request gives it: what the ground's ModeRequest carries.
struct RosModeRequest {
  hq_msgs_Mode mode = hq_msgs_MODE_HOVER;
  bool take_off = false;
  hq_msgs_MarkerTask marker_task = hq_msgs_MARKER_TASK_NONE;
  std::int32_t target_id = 0;
};
/// Longer mode request texts are refused unread (every valid one is far shorter).
inline constexpr std::size_t kMaxModeRequestChars = 64;
/// Parses a mode request text, surrounding whitespace ignored: "take_off" (take off, then
/// teleop, as the ground's take-off), "land", "hover", "teleop", "explore", "marker", or
/// "marker <hold|go_to|land> <id>" (a marker task on AprilTag id >= 0). Returns null when
/// understood, else why not (static text, for the refusal).
const char* parse_mode_request(std::string_view text, RosModeRequest& out);

/// The DDS topic of ROS topic `name` in namespace `ns`: "rt/<ns>/<name>".
std::string dds_topic_name(const std::string& ns, const std::string& name);

struct Ros2Counters {
  std::uint64_t states_published = 0;
  std::uint64_t clouds_published = 0;
  std::uint64_t images_published = 0;
  std::uint64_t commands_received = 0;    ///< TwistStamped samples taken from cmd_vel_in.
  std::uint64_t commands_overridden = 0;  ///< Of those: dropped, a native station commands.
  std::uint64_t commands_stale = 0;       ///< TwistStamped dropped: stamp past kMaxCommandAge_ns.
  std::uint64_t clocks_published = 0;     ///< /clock samples (simulated time only).
  std::uint64_t mode_requests_received = 0;  ///< mode_request samples taken.
  std::uint64_t mode_answers_published = 0;  ///< mode_status samples written.
};

class Ros2Bridge {
 public:
  /// Creates the topics, writers and the cmd_vel_in reader on `participant` for
  /// link::ros2_namespace(config). hq::InputError naming the DDS call on failure.
  Ros2Bridge(const link::Participant& participant, const link::LinkConfig& config);

  /// Odometry, Imu and /tf of one vehicle state; the obstacle cloud when the state carries one.
  void publish_state(const link::VehicleState& state);
  /// The link's JPEG as a CompressedImage, and the CameraInfo once set_camera() was called.
  void publish_camera(const link::CameraFrame& frame);
  /// Intrinsics of the frames sent (undistorted pinhole: D zeros, R identity, P = [K|0]).
  void set_camera(const geometry::PinholeCamera& camera) { messages_.set_camera(camera); }
  /// The camera's mount (the vehicle file's): /tf_static gets base_link -> camera_link ->
  /// camera_optical (hq::geometry::ros_camera_frames), written with the first state after.
  void set_camera_mount(const geometry::CameraMount& mount) { messages_.set_camera_mount(mount); }
  /// How the chain's clock maps to ROS time (default: epoch_from_monotonic(), a real vehicle).
  /// simulated_time() also publishes /clock with every state.
  void set_clock(const RosClock& clock) { messages_.set_clock(clock); }
  [[nodiscard]] const RosClock& clock() const { return messages_.clock(); }

  /// The next ROS command, a Twist from cmd_vel (teleop_twist_keyboard's and teleop_twist_joy's
  /// default) or a TwistStamped from cmd_vel_in, as the link's command in H
  /// (command_from_twist) from station link.ros2.station_id, unstamped (t_ns 0); false when none
  /// is pending. `now_chain_ns` (the chain's clock) judges TwistStamped stamps: one older than
  /// kMaxCommandAge_ns in ROS time (clock()) is dropped and counted (commands_stale). Values are
  /// not checked here: the fail-safe rejects and counts NaN, Inf and out-of-envelope ones as for
  /// any station.
  bool take_command(std::int64_t now_chain_ns, link::VelocityCommand& command);
  /// The next text on mode_request, null when none is pending; valid until the next call.
  const char* take_mode_request();
  /// Answers a mode request on mode_status (accepted, or refused with the reason).
  void publish_mode_status(const char* text);

  /// Counts a taken command dropped because a native station commands (lowest priority).
  void count_overridden() { ++counters_.commands_overridden; }

  [[nodiscard]] const Ros2Counters& counters() const { return counters_; }
  [[nodiscard]] const std::string& ros_namespace() const { return namespace_; }
  [[nodiscard]] const std::string& node_name() const { return node_name_; }
  [[nodiscard]] const std::string& odom_frame() const { return messages_.odom_frame(); }
  [[nodiscard]] const std::string& body_frame() const { return messages_.body_frame(); }

 private:
  /// Writes ros_discovery_info once: this node's readers and writers on `participant`.
  void announce_node(const link::Participant& participant);

  std::string namespace_;
  std::string node_name_;
  std::uint32_t vehicle_id_;
  std::uint32_t station_id_;
  Ros2Messages messages_;  ///< What is published, built as the flight record builds it.

  link::Topic<Odometry> odom_topic_;
  link::Topic<Imu> imu_topic_;
  link::Topic<TfMessage> tf_topic_;
  link::Topic<PointCloud2> cloud_topic_;
  link::Topic<CompressedImage> image_topic_;
  link::Topic<CameraInfo> info_topic_;
  link::Topic<TwistStamped> command_topic_;
  link::Topic<Twist> twist_topic_;
  link::Writer<Odometry> odom_writer_;
  link::Writer<Imu> imu_writer_;
  link::Writer<TfMessage> tf_writer_;
  link::Writer<PointCloud2> cloud_writer_;
  link::Writer<CompressedImage> image_writer_;
  link::Writer<CameraInfo> info_writer_;
  link::Reader<TwistStamped> command_reader_;
  link::Reader<Twist> twist_reader_;
  link::Topic<TfMessage> tf_static_topic_;
  link::Writer<TfMessage> tf_static_writer_;
  link::Topic<RosClockMsg> clock_topic_;
  link::Writer<RosClockMsg> clock_writer_;
  link::Topic<RosString> mode_request_topic_;
  link::Topic<RosString> mode_status_topic_;
  link::Reader<RosString> mode_request_reader_;
  link::Writer<RosString> mode_status_writer_;
  link::Topic<ParticipantEntitiesInfo> discovery_topic_;
  link::Writer<ParticipantEntitiesInfo> discovery_writer_;
  std::vector<Gid> reader_gids_;  ///< What ros_discovery_info points at (written once).
  std::vector<Gid> writer_gids_;
  NodeEntitiesInfo node_info_{};
  link::Sample<RosString> mode_request_;
  link::Sample<TwistStamped> twist_;
  link::Sample<Twist> plain_twist_;
  std::uint64_t command_sequence_ = 0;
  Ros2Counters counters_;
};

}  // namespace hq::ros2_bridge
