#include "hq/ros2_bridge/ros2_messages.hpp"

#include "hq/geometry/ros_frames.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>

namespace hq::ros2_bridge {

using geometry::enu_from_ned;
using geometry::flu_from_frd;
using geometry::q_E_F;
using geometry::v_F_from_v_H;

namespace {

constexpr std::uint8_t kFloat32 = 7;      // sensor_msgs/PointField FLOAT32
constexpr std::uint32_t kPointStep = 12;  // x, y, z float32

geometry_msgs_msg_dds__Vector3_ to_vector3(const Eigen::Vector3d& v) {
  return {v.x(), v.y(), v.z()};
}

geometry_msgs_msg_dds__Quaternion_ to_quaternion(const Eigen::Quaterniond& q) {
  return {q.x(), q.y(), q.z(), q.w()};
}

Eigen::Vector3d from_msg(const hq_msgs_Vector3f& v) {
  return {static_cast<double>(v.x), static_cast<double>(v.y), static_cast<double>(v.z)};
}

char* c_str(std::string& s) { return s.data(); }

template <typename Sequence, typename Element>
void point_at(Sequence& sequence, Element* buffer, std::uint32_t length) {
  sequence._buffer = buffer;
  sequence._length = length;
  sequence._maximum = length;
  sequence._release = false;  // ours: Cyclone never frees it
}

}  // namespace

RosClock RosClock::epoch_from_monotonic() {
  // Read back to back; the pair's spread (well under a microsecond) is the offset's error.
  const auto system = std::chrono::system_clock::now().time_since_epoch();
  const auto monotonic = std::chrono::steady_clock::now().time_since_epoch();
  return {std::chrono::duration_cast<std::chrono::nanoseconds>(system - monotonic).count(), false};
}

builtin_interfaces_msg_dds__Time_ to_ros_time(std::int64_t ros_t_ns) {
  // ROS Time: seconds and a nanosecond part in [0, 1e9), also for negative stamps.
  std::int64_t sec = ros_t_ns / 1'000'000'000;
  std::int64_t nsec = ros_t_ns % 1'000'000'000;
  if (nsec < 0) {
    nsec += 1'000'000'000;
    --sec;
  }
  return {static_cast<std::int32_t>(sec), static_cast<std::uint32_t>(nsec)};
}

std::int64_t from_ros_time(const builtin_interfaces_msg_dds__Time_& time) {
  return static_cast<std::int64_t>(time.sec) * 1'000'000'000 +
         static_cast<std::int64_t>(time.nanosec);
}

void state_covariances(const link::VehicleState& s, double pose[36], double twist[36],
                       double imu_orientation[9], double imu_rates[9]) {
  std::fill(pose, pose + 36, 0.0);
  std::fill(twist, twist + 36, 0.0);
  std::fill(imu_orientation, imu_orientation + 9, 0.0);
  std::fill(imu_rates, imu_rates + 9, 0.0);
  // Pose in odom: the integrated pose's sigmas (the same for z: integrated alike); none yet,
  // -1 as ROS says "no estimate".
  if (s.odom_valid) {
    const double position = static_cast<double>(s.odom_position_sigma_m);
    const double yaw = static_cast<double>(s.odom_yaw_sigma_rad);
    pose[0] = pose[7] = pose[14] = position * position;
    pose[21] = pose[28] = kRollPitchVariance_rad2;
    pose[35] = yaw * yaw;
  } else {
    pose[0] = -1.0;
  }
  // Twist in base_link: the estimator's velocity sigma per axis (FRD -> FLU keeps variances).
  if (static_cast<int>(s.estimator_health) == static_cast<int>(hq_msgs_HEALTH_LOST)) {
    twist[0] = -1.0;
  } else {
    const hq_msgs_Vector3f& v = s.v_H_sigma_mps;
    twist[0] = static_cast<double>(v.x) * static_cast<double>(v.x);
    twist[7] = static_cast<double>(v.y) * static_cast<double>(v.y);
    twist[14] = static_cast<double>(v.z) * static_cast<double>(v.z);
    twist[21] = twist[28] = twist[35] = kRateVariance_rad2ps2;
  }
  // The Imu's orientation is against a world frame: its yaw is unknown (no compass).
  imu_orientation[0] = imu_orientation[4] = kRollPitchVariance_rad2;
  imu_orientation[8] = kUnknownYawVariance_rad2;
  imu_rates[0] = imu_rates[4] = imu_rates[8] = kRateVariance_rad2ps2;
}

std::string ros_topic_name(const std::string& ns, const std::string& name) {
  return "/" + ns + "/" + name;
}

Ros2Messages::Ros2Messages(const std::string& ros_namespace)
    : odom_frame_(ros_namespace + "/odom"),
      body_frame_(ros_namespace + "/base_link"),
      camera_frame_(ros_namespace + "/camera_optical"),
      jpeg_format_("jpeg"),
      distortion_model_("plumb_bob"),
      map_frame_(ros_namespace + "/map"),
      camera_link_frame_(ros_namespace + "/camera_link"),
      field_x_("x"),
      field_y_("y"),
      field_z_("z") {
  odom_.header.frame_id = c_str(odom_frame_);
  odom_.child_frame_id = c_str(body_frame_);
  imu_.header.frame_id = c_str(body_frame_);
  tf_pair_[0].header.frame_id = c_str(odom_frame_);
  tf_pair_[0].child_frame_id = c_str(body_frame_);
  tf_pair_[1].header.frame_id = c_str(map_frame_);
  tf_pair_[1].child_frame_id = c_str(odom_frame_);
  point_at(tf_.transforms, tf_pair_, 2);
  tf_.transforms._length = 1;
  static_transforms_[0].header.frame_id = c_str(body_frame_);
  static_transforms_[0].child_frame_id = c_str(camera_link_frame_);
  static_transforms_[1].header.frame_id = c_str(camera_link_frame_);
  static_transforms_[1].child_frame_id = c_str(camera_frame_);
  point_at(tf_static_.transforms, static_transforms_, 2);

  cloud_.header.frame_id = c_str(body_frame_);
  fields_[0] = {c_str(field_x_), 0, kFloat32, 1};
  fields_[1] = {c_str(field_y_), 4, kFloat32, 1};
  fields_[2] = {c_str(field_z_), 8, kFloat32, 1};
  point_at(cloud_.fields, fields_, 3);
  cloud_.height = 1;
  cloud_.is_bigendian = false;
  cloud_.point_step = kPointStep;
  cloud_.is_dense = true;  // the link bridge sends finite points only
  cloud_data_.resize(static_cast<std::size_t>(hq_msgs_kMaxObstaclePoints) * kPointStep);

  image_.header.frame_id = c_str(camera_frame_);
  image_.format = c_str(jpeg_format_);
  info_.header.frame_id = c_str(camera_frame_);
  info_.distortion_model = c_str(distortion_model_);
  point_at(info_.d, distortion_, 5);
}

void Ros2Messages::set_camera(const geometry::PinholeCamera& camera) {
  info_.width = static_cast<std::uint32_t>(camera.width);
  info_.height = static_cast<std::uint32_t>(camera.height);
  const double k[9] = {camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1};
  const double r[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const double p[12] = {camera.fx, 0, camera.cx, 0, 0, camera.fy, camera.cy, 0, 0, 0, 1, 0};
  std::memcpy(info_.k, k, sizeof k);
  std::memcpy(info_.r, r, sizeof r);
  std::memcpy(info_.p, p, sizeof p);
  have_camera_ = true;
}

void Ros2Messages::set_camera_mount(const geometry::CameraMount& mount) {
  const geometry::RosCameraFrames frames = geometry::ros_camera_frames(mount);
  const auto fill = [](TransformStamped& t, const Eigen::Isometry3d& T) {
    t.transform.translation = to_vector3(T.translation());
    t.transform.rotation = to_quaternion(Eigen::Quaterniond(T.linear()).normalized());
  };
  fill(static_transforms_[0], frames.T_F_camera_link);
  fill(static_transforms_[1], frames.T_camera_link_optical);
  tf_static_pending_ = true;
}

StateMessages Ros2Messages::build_state(const link::VehicleState& s) {
  StateMessages out;
  const auto stamp = to_ros_time(clock_.ros_ns(s.t_ns));
  if (clock_.is_simulated()) {
    clock_msg_.clock = stamp;
    out.clock = &clock_msg_;
  }
  if (tf_static_pending_) {
    static_transforms_[0].header.stamp = stamp;
    static_transforms_[1].header.stamp = stamp;
    out.tf_static = &tf_static_;
  }
  const double roll_rad = static_cast<double>(s.roll_rad);
  const double pitch_rad = static_cast<double>(s.pitch_rad);
  // odom -> base_link: the odometry's integrated pose (odom NED-like -> ENU), continuous.
  const Eigen::Quaterniond q_E_F_odom =
      q_E_F(roll_rad, pitch_rad, static_cast<double>(s.yaw_odom_rad));
  const Eigen::Vector3d p_E_m = enu_from_ned(from_msg(s.p_odom_m));
  const Eigen::Vector3d v_F_mps = v_F_from_v_H(from_msg(s.v_H_mps), roll_rad, pitch_rad);
  const Eigen::Vector3d omega_F_radps = flu_from_frd(from_msg(s.omega_B_radps));

  odom_.header.stamp = stamp;
  odom_.pose.pose.position = {p_E_m.x(), p_E_m.y(), p_E_m.z()};
  odom_.pose.pose.orientation = to_quaternion(q_E_F_odom);
  odom_.twist.twist.linear = to_vector3(v_F_mps);
  odom_.twist.twist.angular = to_vector3(omega_F_radps);
  state_covariances(s, odom_.pose.covariance, odom_.twist.covariance, imu_.orientation_covariance,
                    imu_.angular_velocity_covariance);
  out.odom = &odom_;

  imu_.header.stamp = stamp;
  imu_.orientation = odom_.pose.pose.orientation;
  imu_.angular_velocity = odom_.twist.twist.angular;
  imu_.linear_acceleration = {0.0, 0.0, 0.0};
  imu_.linear_acceleration_covariance[0] = -1.0;  // the state carries no acceleration
  out.imu = &imu_;

  tf_pair_[0].header.stamp = stamp;
  tf_pair_[0].transform.translation = {p_E_m.x(), p_E_m.y(), p_E_m.z()};
  tf_pair_[0].transform.rotation = odom_.pose.pose.orientation;
  tf_.transforms._length = 1;
  if (s.position_valid) {
    // map -> odom = T_map_base T_odom_base^-1: the marker filter's absolute pose against the
    // odometry's, which drifts (REP-105).
    const Eigen::Isometry3d T_map_F = Eigen::Translation3d(enu_from_ned(from_msg(s.p_W_m))) *
                                      q_E_F(roll_rad, pitch_rad, static_cast<double>(s.yaw_W_rad));
    const Eigen::Isometry3d T_odom_F = Eigen::Translation3d(p_E_m) * q_E_F_odom;
    const Eigen::Isometry3d T_map_odom = T_map_F * T_odom_F.inverse();
    tf_pair_[1].header.stamp = stamp;
    tf_pair_[1].transform.translation = to_vector3(T_map_odom.translation());
    tf_pair_[1].transform.rotation =
        to_quaternion(Eigen::Quaterniond(T_map_odom.linear()).normalized());
    tf_.transforms._length = 2;
  }
  out.tf = &tf_;

  const std::uint32_t n = s.obstacle_points_B_m._length;
  if (n == 0 || n > hq_msgs_kMaxObstaclePoints) return out;
  for (std::uint32_t i = 0; i < n; ++i) {
    const Eigen::Vector3f p_F_m =
        flu_from_frd(from_msg(s.obstacle_points_B_m._buffer[i])).cast<float>();
    std::memcpy(&cloud_data_[static_cast<std::size_t>(i) * kPointStep], p_F_m.data(), kPointStep);
  }
  cloud_.header.stamp = stamp;
  cloud_.width = n;
  cloud_.row_step = n * kPointStep;
  point_at(cloud_.data, cloud_data_.data(), n * kPointStep);
  out.cloud = &cloud_;
  return out;
}

CameraMessages Ros2Messages::build_camera(const link::CameraFrame& frame) {
  const auto stamp = to_ros_time(clock_.ros_ns(frame.t_ns));
  image_.header.stamp = stamp;
  point_at(image_.data, frame.rgb_jpeg._buffer, frame.rgb_jpeg._length);
  CameraMessages out;
  out.image = &image_;
  if (have_camera_) {
    info_.header.stamp = stamp;
    out.info = &info_;
  }
  return out;
}

}  // namespace hq::ros2_bridge
