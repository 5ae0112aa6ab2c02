#include "ros2_record.hpp"

#include "hq/base/error.hpp"

#include <algorithm>
#include <unistd.h>

namespace hq::onboard_log {
namespace {

using ros2_bridge::message_definition;

// The largest message: a JPEG at the link's bound (or the obstacle cloud, smaller) with its
// header, frame id and format.
constexpr std::size_t kCdrCapacity =
    std::max<std::size_t>(hq_msgs_kMaxJpegBytes, std::size_t{12} * hq_msgs_kMaxObstaclePoints) +
    4096;

// One QoS profile as rosbag2 (Humble's metadata) writes offered_qos_profiles: rmw's enum
// values (history 1 keep last; reliability 1 reliable; durability 1 transient local,
// 2 volatile; liveliness 1 automatic) and durations as sec/nsec, infinite being rmw's
// RMW_DURATION_INFINITE (INT64_MAX ns). These are the QoS the bridge's writers offer.
std::string offered_qos(int depth, bool transient_local) {
  const char* infinite = "\n    sec: 9223372036\n    nsec: 854775807";
  return std::string("- history: 1\n  depth: ") + std::to_string(depth) +
         "\n  reliability: 1\n  durability: " + (transient_local ? "1" : "2") +
         "\n  deadline:" + infinite + "\n  lifespan:" + infinite +
         "\n  liveliness: 1\n  liveliness_lease_duration:" + infinite +
         "\n  avoid_ros_namespace_conventions: false";
}

mcap::Bytes as_bytes(const char* text) {
  return {reinterpret_cast<const std::uint8_t*>(text), std::char_traits<char>::length(text)};
}

const Ros2RecordOptions& checked_new(const Ros2RecordOptions& options) {
  if (access(options.path.c_str(), F_OK) == 0) {
    throw InputError(options.path +
                     ": exists; refusing to overwrite a flight record, expected a new file");
  }
  return options;
}

}  // namespace

Ros2Record::Ros2Record(const Ros2RecordOptions& options)
    : options_(checked_new(options)),
      messages_(options.ros_namespace),
      cdr_(kCdrCapacity),
      clock_offset_ns_(ros2_bridge::RosClock::epoch_from_monotonic().offset_ns()) {
  const std::string& ns = options_.ros_namespace;
  topics_[kClock] = "/clock";
  topics_[kTfStatic] = "/tf_static";
  topics_[kTf] = "/tf";
  topics_[kOdom] = ros2_bridge::ros_topic_name(ns, "odom");
  topics_[kImu] = ros2_bridge::ros_topic_name(ns, "imu");
  topics_[kCloud] = ros2_bridge::ros_topic_name(ns, "obstacles");
  topics_[kImage] = ros2_bridge::ros_topic_name(ns, "camera/image/compressed");
  topics_[kCameraInfo] = ros2_bridge::ros_topic_name(ns, "camera/camera_info");
  channel_ids_.fill(-1);
  if (options_.camera_mount) messages_.set_camera_mount(*options_.camera_mount);
  mcap::WriterOptions writer = options_.writer;
  writer.profile = "ros2";
  writer_.open(options_.path, writer);
  report_.path = options_.path;
}

void Ros2Record::set_camera(const geometry::PinholeCamera& camera) {
  if (camera_claimed_.exchange(true)) return;
  camera_ = camera;
  camera_set_.store(true, std::memory_order_release);
}

void Ros2Record::set_clock(const ros2_bridge::RosClock& clock) {
  clock_offset_ns_.store(clock.offset_ns(), std::memory_order_relaxed);
  clock_simulated_.store(clock.is_simulated(), std::memory_order_release);
}

void Ros2Record::apply_settings() {
  if (!camera_applied_ && camera_set_.load(std::memory_order_acquire)) {
    messages_.set_camera(camera_);
    camera_applied_ = true;
  }
  const bool simulated = clock_simulated_.load(std::memory_order_acquire);
  messages_.set_clock({clock_offset_ns_.load(std::memory_order_relaxed), simulated});
}

std::uint16_t Ros2Record::channel_id(Channel channel,
                                     const ros2_bridge::MessageDefinition& definition) {
  if (channel_ids_[channel] >= 0) return static_cast<std::uint16_t>(channel_ids_[channel]);
  // The QoS of the bridge's writer for this topic (ros2_bridge.hpp): /tf_static transient
  // local keep last 1, /clock keep last 1, the others ROS's default (keep last 10); all
  // reliable and volatile otherwise.
  const bool is_static = channel == kTfStatic;
  const int depth = is_static || channel == kClock ? 1 : 10;
  const std::uint16_t schema =
      writer_.add_schema(definition.name, "ros2msg", as_bytes(definition.text));
  const std::uint16_t id = writer_.add_channel(
      schema, topics_[channel], "cdr", {{"offered_qos_profiles", offered_qos(depth, is_static)}});
  channel_ids_[channel] = id;
  return id;
}

template <typename Message>
void Ros2Record::write(Channel channel, const Message& message, std::int64_t log_ns,
                       std::int64_t publish_ns) {
  if (failed_ || closed_) return;
  if (!ros2_bridge::serialize(message, cdr_)) {
    ++report_.too_large;
    return;
  }
  // Receipt stamps of one thread only go back if the system clock is stepped back.
  if (log_ns < last_log_ns_) {
    ++report_.log_times_raised;
    log_ns = last_log_ns_;
  }
  last_log_ns_ = log_ns;
  try {
    const std::uint16_t id = channel_id(channel, message_definition<Message>());
    writer_.write(id, static_cast<std::uint32_t>(counts_[channel]), log_ns, publish_ns,
                  cdr_.data());
    ++counts_[channel];
  } catch (const std::exception& e) {
    fail(e.what());
  }
}

void Ros2Record::on_state(const link::VehicleState& state, std::int64_t log_ns,
                          std::int64_t publish_ns) {
  if (failed_ || closed_) return;
  apply_settings();
  const ros2_bridge::StateMessages m = messages_.build_state(state);
  if (m.clock != nullptr) write(kClock, *m.clock, log_ns, publish_ns);
  if (m.tf_static != nullptr) {
    write(kTfStatic, *m.tf_static, log_ns, publish_ns);
    messages_.confirm_tf_static();
  }
  write(kOdom, *m.odom, log_ns, publish_ns);
  write(kImu, *m.imu, log_ns, publish_ns);
  write(kTf, *m.tf, log_ns, publish_ns);
  if (m.cloud != nullptr) write(kCloud, *m.cloud, log_ns, publish_ns);
}

void Ros2Record::on_camera(const link::CameraFrame& frame, std::int64_t log_ns,
                           std::int64_t publish_ns) {
  if (failed_ || closed_) return;
  apply_settings();
  const ros2_bridge::CameraMessages m = messages_.build_camera(frame);
  if (frame.rgb_jpeg._length > 0) write(kImage, *m.image, log_ns, publish_ns);
  if (m.info != nullptr) write(kCameraInfo, *m.info, log_ns, publish_ns);
}

void Ros2Record::tick(std::int64_t steady_ns) {
  if (failed_ || closed_ || steady_ns - last_flush_ns_ < options_.writer.chunk_time_limit_ns) {
    return;
  }
  last_flush_ns_ = steady_ns;
  try {
    writer_.flush();
  } catch (const std::exception& e) {
    fail(e.what());
  }
}

void Ros2Record::fail(const std::string& what) {
  if (failed_) return;
  failed_ = true;
  report_.error = options_.path + ": ROS 2 record stopped: " + what;
}

const Ros2RecordReport& Ros2Record::close() {
  if (closed_) return report_;
  closed_ = true;
  if (!failed_) {
    try {
      writer_.close();
    } catch (const std::exception& e) {
      fail(e.what());
    }
  }
  // What reached the file (a failed chunk's messages are not in it).
  const mcap::Statistics& s = writer_.statistics();
  report_.messages = s.message_count;
  report_.bytes = writer_.bytes_written();
  for (std::size_t c = 0; c < kChannelCount; ++c) {
    if (channel_ids_[c] < 0) continue;
    const auto written = s.channel_message_counts.find(static_cast<std::uint16_t>(channel_ids_[c]));
    report_.per_topic.emplace_back(topics_[c],
                                   written == s.channel_message_counts.end() ? 0 : written->second);
  }
  return report_;
}

}  // namespace hq::onboard_log
