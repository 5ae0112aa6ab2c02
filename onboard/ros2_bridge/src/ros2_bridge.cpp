#include "hq/ros2_bridge/ros2_bridge.hpp"

#include "hq/base/format_into.hpp"
#include "hq/geometry/ros_frames.hpp"

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <cstring>

namespace hq::ros2_bridge {

using geometry::command_from_twist;
using geometry::HorizontalCommand;

namespace {

constexpr int kRosDepth = 10;  // rmw_qos_profile_default's history depth

std::string_view trimmed(std::string_view text) {
  const auto space = [](char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; };
  while (!text.empty() && space(text.front())) text.remove_prefix(1);
  while (!text.empty() && space(text.back())) text.remove_suffix(1);
  return text;
}

// "<hold|go_to|land> <id>" after "marker ".
const char* parse_marker_task(std::string_view rest, RosModeRequest& out) {
  const std::size_t gap = rest.find(' ');
  if (gap == std::string_view::npos) {
    return "a marker task needs a marker id (\"marker <hold|go_to|land> <id>\")";
  }
  const std::string_view task = rest.substr(0, gap);
  const std::string_view id = trimmed(rest.substr(gap + 1));
  if (task == "hold") {
    out.marker_task = hq_msgs_MARKER_TASK_HOLD;
  } else if (task == "go_to") {
    out.marker_task = hq_msgs_MARKER_TASK_GO_TO;
  } else if (task == "land") {
    out.marker_task = hq_msgs_MARKER_TASK_LAND;
  } else {
    return "unknown marker task (expected hold, go_to or land)";
  }
  std::int32_t value = -1;
  const auto [end, error] = std::from_chars(id.data(), id.data() + id.size(), value);
  if (error != std::errc() || end != id.data() + id.size() || value < 0) {
    return "the marker id is not an integer >= 0";
  }
  out.target_id = value;
  return nullptr;
}

dds_guid_t guid_of(dds_entity_t entity) {
  dds_guid_t guid{};
  link::check(dds_get_guid(entity, &guid), "dds_get_guid", "ros_discovery_info");
  return guid;
}

Gid gid_of(dds_entity_t entity) {
  const dds_guid_t guid = guid_of(entity);
  Gid gid{};
  static_assert(sizeof gid.data == sizeof guid.v, "a Gid is a 16-byte GUID (ROS 2 Iron+)");
  std::memcpy(gid.data, guid.v, sizeof gid.data);
  return gid;
}

template <typename Sequence, typename Element>
void point_at(Sequence& sequence, std::vector<Element>& elements) {
  sequence._buffer = elements.data();
  sequence._length = static_cast<std::uint32_t>(elements.size());
  sequence._maximum = sequence._length;
  sequence._release = false;  // ours: Cyclone never frees it
}

}  // namespace

const char* parse_mode_request(std::string_view text, RosModeRequest& out) {
  out = {};
  if (text.size() > kMaxModeRequestChars) return "longer than any mode request";
  text = trimmed(text);
  const std::pair<std::string_view, hq_msgs_Mode> plain[] = {
      {"land", hq_msgs_MODE_LAND},     {"hover", hq_msgs_MODE_HOVER},
      {"teleop", hq_msgs_MODE_TELEOP}, {"explore", hq_msgs_MODE_EXPLORE},
      {"marker", hq_msgs_MODE_MARKER}, {"take_off", hq_msgs_MODE_TELEOP}};
  for (const auto& [name, mode] : plain) {
    if (text == name) {
      out.mode = mode;
      out.take_off = name == "take_off";  // as the ground's take-off: climb, then teleop
      return nullptr;
    }
  }
  constexpr std::string_view kMarker = "marker ";
  if (text.substr(0, kMarker.size()) == kMarker) {
    out.mode = hq_msgs_MODE_MARKER;
    return parse_marker_task(trimmed(text.substr(kMarker.size())), out);
  }
  return "unknown mode (expected take_off, land, hover, teleop, explore, marker [TASK ID])";
}

link::Qos discovery_info_qos() { return tf_static_qos(); }

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
      node_name_(link::ros2_node_name(config)),
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
      clock_writer_(participant, clock_topic_, clock_qos()),
      mode_request_topic_(participant, dds_topic_name(namespace_, "mode_request")),
      mode_status_topic_(participant, dds_topic_name(namespace_, "mode_status")),
      // Reliable: a request is sent once (ros2 topic pub --once) and must not be lost.
      mode_request_reader_(participant, mode_request_topic_, ros2_qos()),
      mode_status_writer_(participant, mode_status_topic_, ros2_qos()),
      discovery_topic_(participant, "ros_discovery_info"),
      discovery_writer_(participant, discovery_topic_, discovery_info_qos()) {
  announce_node(participant);
}

void Ros2Bridge::announce_node(const link::Participant& participant) {
  // The node's own endpoints; ros_discovery_info's writer is the context's, not the node's (as
  // rmw_cyclonedds lists it).
  for (const dds_entity_t reader :
       {command_reader_.handle(), twist_reader_.handle(), mode_request_reader_.handle()}) {
    reader_gids_.push_back(gid_of(reader));
  }
  for (const dds_entity_t writer :
       {odom_writer_.handle(), imu_writer_.handle(), tf_writer_.handle(), cloud_writer_.handle(),
        image_writer_.handle(), info_writer_.handle(), tf_static_writer_.handle(),
        clock_writer_.handle(), mode_status_writer_.handle()}) {
    writer_gids_.push_back(gid_of(writer));
  }
  hq::format_into(node_info_.node_namespace, "/");
  hq::format_into(node_info_.node_name, "{}", node_name_);
  point_at(node_info_.reader_gid_seq, reader_gids_);
  point_at(node_info_.writer_gid_seq, writer_gids_);
  ParticipantEntitiesInfo info{};
  info.gid = gid_of(participant.handle());
  info.node_entities_info_seq._buffer = &node_info_;
  info.node_entities_info_seq._length = 1;
  info.node_entities_info_seq._maximum = 1;
  info.node_entities_info_seq._release = false;
  // Transient local: the writer keeps it for every ROS tool that starts later.
  if (!discovery_writer_.write(info)) {
    throw InputError(std::string("ros_discovery_info: dds_write: ") +
                     discovery_writer_.last_error());
  }
}

const char* Ros2Bridge::take_mode_request() {
  dds_sample_info_t info{};
  if (!mode_request_reader_.take(*mode_request_, info)) return nullptr;
  ++counters_.mode_requests_received;
  return mode_request_->data != nullptr ? mode_request_->data : "";
}

void Ros2Bridge::publish_mode_status(const char* text) {
  RosString answer{};
  answer.data =
      const_cast<char*>(text);  // NOLINT(cppcoreguidelines-pro-type-const-cast): read only
  if (mode_status_writer_.write(answer)) ++counters_.mode_answers_published;
}

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
