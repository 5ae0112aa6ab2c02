#pragma once
/// The ROS 2 messages of one vehicle state and one camera frame, built without DDS: the one
/// place that fills them, used by the bridge that publishes them (ros2_bridge.hpp) and by the
/// flight record that stores them as a ROS 2 bag (onboard/onboard_log), so both hold the same
/// messages. Frames, stamps, covariances: see ros2_bridge.hpp. Building allocates nothing:
/// frame ids, the cloud and the fixed fields point at buffers sized at construction, the image
/// at the frame's own JPEG bytes.

#include "hq/geometry/camera_mount.hpp"
#include "hq/geometry/pinhole_camera.hpp"
#include "hq/link/messages.hpp"

#include "ros2_msgs.h"

#include <cstdint>
#include <string>
#include <vector>

namespace hq::ros2_bridge {

using Odometry = nav_msgs_msg_dds__Odometry_;
using Imu = sensor_msgs_msg_dds__Imu_;
using TfMessage = tf2_msgs_msg_dds__TFMessage_;
using TransformStamped = geometry_msgs_msg_dds__TransformStamped_;
using PointCloud2 = sensor_msgs_msg_dds__PointCloud2_;
using PointField = sensor_msgs_msg_dds__PointField_;
using CompressedImage = sensor_msgs_msg_dds__CompressedImage_;
using CameraInfo = sensor_msgs_msg_dds__CameraInfo_;
using TwistStamped = geometry_msgs_msg_dds__TwistStamped_;
using RosClockMsg = rosgraph_msgs_msg_dds__Clock_;
using Twist = geometry_msgs_msg_dds__Twist_;
using RosString = std_msgs_msg_dds__String_;
using Gid = rmw_dds_common_msg_dds__Gid_;
using NodeEntitiesInfo = rmw_dds_common_msg_dds__NodeEntitiesInfo_;
using ParticipantEntitiesInfo = rmw_dds_common_msg_dds__ParticipantEntitiesInfo_;

/// The one mapping from the chain's clock (VehicleState.t_ns, CameraFrame.t_ns) to ROS time,
/// used for every stamp the bridge writes and every stamp it reads:
/// - a real vehicle: its chain runs on the monotonic clock; ROS time is the epoch (the system
///   clock, as rclcpp's RCL_ROS_TIME without use_sim_time): t + (system - monotonic), the offset
///   taken once, so stamps never jump when NTP steps the system clock later;
/// - the simulator: ROS time is the simulated time itself, and the bridge publishes it on /clock
///   (rosgraph_msgs/Clock) so that nodes run with use_sim_time:=true follow it.
class RosClock {
 public:
  /// The epoch from the host's monotonic clock (std::chrono::steady_clock, CLOCK_MONOTONIC).
  static RosClock epoch_from_monotonic();
  /// Simulated time: ROS time = the chain's time, /clock published.
  static RosClock simulated_time() { return RosClock(0, true); }
  RosClock(std::int64_t offset_ns, bool simulated) : offset_ns_(offset_ns), simulated_(simulated) {}

  [[nodiscard]] std::int64_t ros_ns(std::int64_t chain_t_ns) const {
    return chain_t_ns + offset_ns_;
  }
  [[nodiscard]] std::int64_t chain_ns(std::int64_t ros_t_ns) const { return ros_t_ns - offset_ns_; }
  [[nodiscard]] bool is_simulated() const { return simulated_; }
  [[nodiscard]] std::int64_t offset_ns() const { return offset_ns_; }

 private:
  std::int64_t offset_ns_;
  bool simulated_;
};

/// builtin_interfaces/Time of a ROS time in ns: seconds and nanoseconds in [0, 1e9).
builtin_interfaces_msg_dds__Time_ to_ros_time(std::int64_t ros_t_ns);
/// The ns of a builtin_interfaces/Time.
std::int64_t from_ros_time(const builtin_interfaces_msg_dds__Time_& time);

/// The covariances the bridge writes, in one place (ROS: 6x6 row-major x y z roll pitch yaw).
/// Roll and pitch: the complementary filter's levelling, about a degree (1-sigma).
inline constexpr double kRollPitchVariance_rad2 = 0.0175 * 0.0175;
/// A yaw nothing measures (no compass): uniform over the circle, variance pi^2 / 3.
inline constexpr double kUnknownYawVariance_rad2 = 3.14159265358979 * 3.14159265358979 / 3.0;
/// The gyro's rates after the bias: noise and filter lag, chain.gyro_prior_sigma_radps's 0.01.
inline constexpr double kRateVariance_rad2ps2 = 0.01 * 0.01;
/// Odometry.pose and twist covariances and Imu covariances of one state (out: 36, 36, 9, 9).
void state_covariances(const link::VehicleState& s, double pose[36], double twist[36],
                       double imu_orientation[9], double imu_rates[9]);

/// The ROS topic of `name` in namespace `ns`: "/<ns>/<name>" (what `ros2 topic list` and a
/// ROS 2 bag show; DDS carries it as "rt" + this).
std::string ros_topic_name(const std::string& ns, const std::string& name);

/// What one vehicle state gives, each pointing into the builder (valid until its next build).
struct StateMessages {
  const RosClockMsg* clock = nullptr;    ///< Simulated time only (/clock).
  const TfMessage* tf_static = nullptr;  ///< The camera mount, until confirm_tf_static().
  const Odometry* odom = nullptr;
  const Imu* imu = nullptr;
  const TfMessage* tf = nullptr;
  const PointCloud2* cloud = nullptr;  ///< When the state carries obstacle points.
};

/// What one camera frame gives; the image's data points at the frame's JPEG bytes.
struct CameraMessages {
  const CompressedImage* image = nullptr;
  const CameraInfo* info = nullptr;  ///< Once set_camera() was called.
};

class Ros2Messages {
 public:
  /// Frame ids <ns>/odom, <ns>/base_link, <ns>/camera_link, <ns>/camera_optical, <ns>/map.
  explicit Ros2Messages(const std::string& ros_namespace);
  Ros2Messages(const Ros2Messages&) = delete;
  Ros2Messages& operator=(const Ros2Messages&) = delete;

  /// Intrinsics of the frames sent (undistorted pinhole: D zeros, R identity, P = [K|0]).
  void set_camera(const geometry::PinholeCamera& camera);
  /// The camera's mount: /tf_static's base_link -> camera_link -> camera_optical
  /// (hq::geometry::ros_camera_frames), offered with the next state until confirmed.
  void set_camera_mount(const geometry::CameraMount& mount);
  void set_clock(const RosClock& clock) { clock_ = clock; }
  [[nodiscard]] const RosClock& clock() const { return clock_; }

  /// Odometry, Imu, /tf (and /clock, /tf_static, the cloud when due) of one state.
  StateMessages build_state(const link::VehicleState& state);
  /// The /tf_static build_state() offered was written: not offered again.
  void confirm_tf_static() { tf_static_pending_ = false; }
  /// The frame's CompressedImage, and CameraInfo once set_camera() was called.
  CameraMessages build_camera(const link::CameraFrame& frame);

  [[nodiscard]] const std::string& odom_frame() const { return odom_frame_; }
  [[nodiscard]] const std::string& body_frame() const { return body_frame_; }

 private:
  // Frame ids and fixed strings the messages point at.
  std::string odom_frame_, body_frame_, camera_frame_, jpeg_format_, distortion_model_;
  std::string map_frame_, camera_link_frame_;
  std::string field_x_, field_y_, field_z_;
  RosClock clock_ = RosClock::epoch_from_monotonic();

  RosClockMsg clock_msg_{};
  Odometry odom_{};
  Imu imu_{};
  TransformStamped tf_pair_[2]{};  ///< odom -> base_link, and map -> odom while anchored
  TfMessage tf_{};
  TransformStamped static_transforms_[2]{};  ///< base_link -> camera_link -> camera_optical
  TfMessage tf_static_{};
  bool tf_static_pending_ = false;
  PointCloud2 cloud_{};
  PointField fields_[3]{};
  std::vector<std::uint8_t> cloud_data_;  ///< 12 bytes per point, sized for the IDL bound.
  CompressedImage image_{};
  CameraInfo info_{};
  bool have_camera_ = false;
  double distortion_[5]{};
};

}  // namespace hq::ros2_bridge
