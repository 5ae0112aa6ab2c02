#include "hq/ros2_bridge/ros2_bridge.hpp"

#include "hq/geometry/ros_frames.hpp"

namespace hq::ros2_bridge {

using geometry::command_from_twist;
using geometry::HorizontalCommand;

namespace {

constexpr int kRosDepth = 10;  // rmw_qos_profile_default's history depth

}  // namespace

link::Qos clock_qos() {
  // As a simulator's /clock publisher: the latest time is all that matters.
  link::Qos qos = ros2_qos();
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 1);
  return qos;
}

link::Qos tf_static_qos() {
  link::Qos qos = ros2_qos();
  dds_qset_durability(qos.get(), DDS_DURABILITY_TRANSIENT_LOCAL);
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 1);
  return qos;
}

link::Qos ros2_qos() {
  link::Qos qos;
  // A write never waits for a slow ROS reader (Cyclone throttles a reliable writer whose
  // unacknowledged data passes its high-water mark): the bridge writes on the vehicle's
  // control step, and a late sample is dropped instead.
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, 0);
  dds_qset_durability(qos.get(), DDS_DURABILITY_VOLATILE);
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, kRosDepth);
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos.get(), 1, &xcdr1);
  return qos;
}

link::Qos ros2_command_qos() {
  link::Qos qos = ros2_qos();
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
  return qos;
}

std::string dds_topic_name(const std::string& ns, const std::string& name) {
  return "rt" + ros_topic_name(ns, name);
}

Ros2Bridge::Ros2Bridge(const link::Participant& participant, const link::LinkConfig& config)
    : namespace_(link::ros2_namespace(config)),
      vehicle_id_(config.vehicle_id),
      station_id_(config.ros2.station_id),
      messages_(namespace_),
      odom_topic_(participant, dds_topic_name(namespace_, "odom")),
      imu_topic_(participant, dds_topic_name(namespace_, "imu")),
      tf_topic_(participant, "rt/tf"),
      cloud_topic_(participant, dds_topic_name(namespace_, "obstacles")),
      image_topic_(participant, dds_topic_name(namespace_, "camera/image/compressed")),
      info_topic_(participant, dds_topic_name(namespace_, "camera/camera_info")),
      command_topic_(participant, dds_topic_name(namespace_, "cmd_vel_in")),
      twist_topic_(participant, dds_topic_name(namespace_, "cmd_vel")),
      odom_writer_(participant, odom_topic_, ros2_qos()),
      imu_writer_(participant, imu_topic_, ros2_qos()),
      tf_writer_(participant, tf_topic_, ros2_qos()),
      cloud_writer_(participant, cloud_topic_, ros2_qos()),
      image_writer_(participant, image_topic_, ros2_qos()),
      info_writer_(participant, info_topic_, ros2_qos()),
      command_reader_(participant, command_topic_, ros2_command_qos()),
      twist_reader_(participant, twist_topic_, ros2_command_qos()),
      tf_static_topic_(participant, "rt/tf_static"),
      tf_static_writer_(participant, tf_static_topic_, tf_static_qos()),
      clock_topic_(participant, "rt/clock"),
      clock_writer_(participant, clock_topic_, clock_qos()) {}

void Ros2Bridge::publish_state(const link::VehicleState& s) {
  const StateMessages m = messages_.build_state(s);
  if (m.clock != nullptr) {
    clock_writer_.write(*m.clock);
    ++counters_.clocks_published;
  }
  // Once: the writer keeps it (transient local) for every reader that joins later.
  if (m.tf_static != nullptr && tf_static_writer_.write(*m.tf_static)) {
    messages_.confirm_tf_static();
  }
  odom_writer_.write(*m.odom);
  imu_writer_.write(*m.imu);
  tf_writer_.write(*m.tf);
  ++counters_.states_published;
  if (m.cloud == nullptr) return;
  cloud_writer_.write(*m.cloud);
  ++counters_.clouds_published;
}

void Ros2Bridge::publish_camera(const link::CameraFrame& frame) {
  const CameraMessages m = messages_.build_camera(frame);
  image_writer_.write(*m.image);
  ++counters_.images_published;
  if (m.info != nullptr) info_writer_.write(*m.info);
}

bool Ros2Bridge::take_command(std::int64_t now_chain_ns, link::VelocityCommand& command) {
  dds_sample_info_t info{};
  const geometry_msgs_msg_dds__Twist_* t = nullptr;
  while (t == nullptr && command_reader_.take(*twist_, info)) {
    ++counters_.commands_received;
    const std::int64_t stamp_ns = from_ros_time(twist_->header.stamp);
    const std::int64_t age_ns = messages_.clock().ros_ns(now_chain_ns) - stamp_ns;
    if (stamp_ns != 0 && (age_ns > kMaxCommandAge_ns || age_ns < -kMaxCommandAge_ns)) {
      ++counters_.commands_stale;
      continue;
    }
    t = &twist_->twist;
  }
  if (t == nullptr && twist_reader_.take(*plain_twist_, info)) {
    ++counters_.commands_received;
    t = &*plain_twist_;
  }
  if (t == nullptr) return false;
  const HorizontalCommand c =
      command_from_twist({t->linear.x, t->linear.y, t->linear.z}, t->angular.z);
  command = {};
  command.vehicle_id = vehicle_id_;
  command.station_id = station_id_;
  command.sequence_number = ++command_sequence_;
  command.t_ns = 0;
  command.v_H_mps = {static_cast<float>(c.v_H_mps.x()), static_cast<float>(c.v_H_mps.y()),
                     static_cast<float>(c.v_H_mps.z())};
  command.yaw_rate_radps = static_cast<float>(c.yaw_rate_radps);
  return true;
}

}  // namespace hq::ros2_bridge
