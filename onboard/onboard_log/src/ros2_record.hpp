#pragma once
/// The flight as a ROS 2 bag: DIR/ros2.mcap beside DIR/onboard.mcap, an MCAP file of the "ros2"
/// profile as rosbag2's MCAP storage plugin writes one, so `ros2 bag info` and `ros2 bag play`
/// take it. It holds the messages the ROS 2 bridge publishes (--ros2), built by the same code
/// (hq::ros2_bridge::Ros2Messages) from the same link samples (every vehicle state and camera
/// frame the link log takes), whether or not the bridge runs:
///   /clock                                rosgraph_msgs/msg/Clock (simulated time only)
///   /tf_static                            tf2_msgs/msg/TFMessage (once, transient local)
///   /tf                                   tf2_msgs/msg/TFMessage
///   /<ns>/odom                            nav_msgs/msg/Odometry
///   /<ns>/imu                             sensor_msgs/msg/Imu
///   /<ns>/obstacles                       sensor_msgs/msg/PointCloud2
///   /<ns>/camera/image/compressed         sensor_msgs/msg/CompressedImage
///   /<ns>/camera/camera_info              sensor_msgs/msg/CameraInfo
/// Topic names are the ROS names (what `ros2 topic list` shows and `ros2 bag record` stores: no
/// DDS "rt" prefix); each channel is message encoding "cdr" with a "ros2msg" schema and the
/// QoS the bridge offers as "offered_qos_profiles". A channel appears with its first message.
/// Header stamps are ROS time (the bridge's RosClock); log times are the epoch at receipt, as in
/// onboard.mcap, never going back; publish times the link sample's source timestamp.
///
/// Everything runs on the link log's thread; serializing goes into one buffer sized once for
/// the largest message. A message too large for it is dropped and counted; a failed write
/// (disk full) stops this file only, error() says why.

#include "hq/geometry/camera_mount.hpp"
#include "hq/geometry/pinhole_camera.hpp"
#include "hq/link/messages.hpp"
#include "hq/mcap/mcap.hpp"
#include "hq/onboard_log/onboard_recorder.hpp"
#include "hq/ros2_bridge/ros2_cdr.hpp"
#include "hq/ros2_bridge/ros2_messages.hpp"

#include <array>
#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace hq::onboard_log {

struct Ros2RecordOptions {
  std::string path;           ///< The .mcap file to create (must not exist).
  std::string ros_namespace;  ///< link::ros2_namespace() of the vehicle's link.
  std::optional<geometry::CameraMount> camera_mount;  ///< /tf_static; none: no /tf_static.
  mcap::WriterOptions writer;                         ///< Its profile is set to "ros2".
};

class Ros2Record {
 public:
  /// Creates the file (hq::InputError naming it when it exists or cannot be created).
  explicit Ros2Record(const Ros2RecordOptions& options);

  /// Before the flight, any thread (first call wins): intrinsics for /camera/camera_info.
  void set_camera(const geometry::PinholeCamera& camera);
  /// Before the flight, any thread: the bridge's clock (default: the epoch from the monotonic
  /// clock, a real vehicle's; simulated time adds /clock).
  void set_clock(const ros2_bridge::RosClock& clock);

  /// The link log's thread: the messages of one state, or one frame.
  void on_state(const link::VehicleState& state, std::int64_t log_ns, std::int64_t publish_ns);
  void on_camera(const link::CameraFrame& frame, std::int64_t log_ns, std::int64_t publish_ns);
  /// The link log's thread, at least every 100 ms: the open chunk reaches the file once it is
  /// older than the writer's chunk_time_limit_ns, so a SIGKILL loses about as much as in
  /// onboard.mcap.
  void tick(std::int64_t steady_ns);
  /// After the log's thread stopped: the summary section; idempotent.
  const Ros2RecordReport& close();

 private:
  enum Channel : std::size_t {
    kClock,
    kTfStatic,
    kTf,
    kOdom,
    kImu,
    kCloud,
    kImage,
    kCameraInfo,
    kChannelCount
  };
  template <typename Message>
  void write(Channel channel, const Message& message, std::int64_t log_ns, std::int64_t publish_ns);
  std::uint16_t channel_id(Channel channel, const ros2_bridge::MessageDefinition& definition);
  void apply_settings();
  void fail(const std::string& what);

  Ros2RecordOptions options_;
  mcap::McapWriter writer_;
  ros2_bridge::Ros2Messages messages_;
  ros2_bridge::CdrWriter cdr_;
  std::array<std::string, kChannelCount> topics_;
  std::array<int, kChannelCount> channel_ids_{};  ///< -1 until the channel's first message
  std::array<std::uint64_t, kChannelCount> counts_{};
  std::int64_t last_log_ns_ = 0;
  std::int64_t last_flush_ns_ = 0;
  bool failed_ = false;
  bool closed_ = false;
  Ros2RecordReport report_;

  // Handed over from the thread that sets them up to the log's thread.
  geometry::PinholeCamera camera_;
  std::atomic<bool> camera_claimed_{false};
  std::atomic<bool> camera_set_{false};
  bool camera_applied_ = false;
  std::atomic<std::int64_t> clock_offset_ns_;
  std::atomic<bool> clock_simulated_{false};
};

}  // namespace hq::onboard_log
