#include "hq/flight_log/link_log.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/flight_log/time_order.hpp"
#include "hq/geometry/ros_frames.hpp"
#include "hq/link/link.hpp"

#include "foxglove_frames.hpp"
#include "foxglove_schemas.hpp"
#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <span>
#include <sys/resource.h>
#include <thread>
#include <unistd.h>

namespace hq::flight_log {
namespace {

mcap::Bytes as_bytes(const std::string& text) {
  return {reinterpret_cast<const std::uint8_t*>(text.data()), text.size()};
}

mcap::Bytes as_bytes(const char* text) {
  return {reinterpret_cast<const std::uint8_t*>(text), std::strlen(text)};
}

std::int64_t steady_ns() { return monotonic_now_ns(); }

// JPEG (FF D8) or PNG (89 'P' 'N' 'G'), as foxglove.CompressedImage's format names them.
const char* image_format(std::span<const std::uint8_t> data) {
  if (data.size() >= 4 && data[0] == 0x89 && data[1] == 'P' && data[2] == 'N' && data[3] == 'G') {
    return "png";
  }
  return "jpeg";
}

std::string media_type_of(const std::string& path) {
  const auto ends = [&](const char* suffix) {
    const std::size_t n = std::strlen(suffix);
    return path.size() >= n && path.compare(path.size() - n, n, suffix) == 0;
  };
  if (ends(".yaml") || ends(".yml")) return "application/yaml";
  if (ends(".json")) return "application/json";
  return "application/octet-stream";
}

// The link's reader QoS with a deeper history: the link's readers keep the latest sample only
// (the controller wants nothing older), but the log wants every sample and its thread runs
// niced, so it may be late on a loaded machine. History depth is the reader's own business (not
// part of QoS matching), so the writers see a reader like any other.
link::Qos recording(link::Qos qos, int depth) {
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, depth);
  return qos;
}

// A flight record is never overwritten (as the CSV recorder refuses a folder holding one).
const LinkLogOptions& checked_new(const LinkLogOptions& options) {
  if (access(options.path.c_str(), F_OK) == 0) {
    throw InputError(options.path +
                     ": exists; refusing to overwrite a flight record, expected a "
                     "new file");
  }
  return options;
}

// The link topics the log takes, in channel-id order.
enum TopicIndex : std::size_t {
  kVehicleState,
  kCameraFrame,
  kEvent,
  kHeartbeat,
  kVelocityCommand,
  kModeRequest,
  kLinkTopicCount
};

}  // namespace

void ChannelWriter::write_json(std::uint16_t channel, std::int64_t log_ns,
                               std::int64_t publish_ns) {
  write(channel, log_ns, publish_ns, as_bytes(json_.text()));
}

struct LinkLog::Impl final : ChannelWriter {
  Impl(LinkLog& owning_log, const LinkLogOptions& requested, LocalSource* local_source)
      : owner(owning_log),
        options(checked_new(requested)),
        local(local_source),
        // The process's own identity when the link is secured; plain DDS otherwise.
        participant(options.link, options.role),
        topics(participant),
        state_reader(participant, topics.vehicle_state, recording(link::vehicle_state_qos(), 64)),
        camera_reader(participant, topics.camera, recording(link::camera_qos(), 16)),
        event_reader(participant, topics.event, recording(link::event_qos(), 64)),
        heartbeat_reader(participant, topics.heartbeat,
                         recording(link::heartbeat_qos(options.link), 32)),
        command_reader(participant, topics.command,
                       recording(link::command_qos(options.link, link::End::kReader), 128)),
        mode_reader(participant, topics.mode_request, recording(link::mode_request_qos(), 32)),
        conditions{link::ReadCondition(state_reader),   link::ReadCondition(camera_reader),
                   link::ReadCondition(event_reader),   link::ReadCondition(heartbeat_reader),
                   link::ReadCondition(command_reader), link::ReadCondition(mode_reader)},
        stop_condition(participant),
        waitset(participant) {
    readers = {state_reader.handle(),     camera_reader.handle(),  event_reader.handle(),
               heartbeat_reader.handle(), command_reader.handle(), mode_reader.handle()};
    for (std::size_t i = 0; i < conditions.size() && options.record_link; ++i) {
      waitset.attach(conditions[i].handle(), static_cast<dds_attach_t>(i));
    }
    waitset.attach(stop_condition.handle(), static_cast<dds_attach_t>(kLinkTopicCount));
    link::reserve(state_sample->obstacle_points_B_m, hq_msgs_kMaxObstaclePoints);
    link::reserve(state_sample->markers, hq_msgs_kMaxMarkersInState);
    link::reserve(camera_sample->rgb_jpeg, hq_msgs_kMaxJpegBytes);
    link::reserve(camera_sample->depth_preview, hq_msgs_kMaxDepthPreviewBytes);
    cloud_flu.reserve(std::size_t{3} * hq_msgs_kMaxObstaclePoints);
    cdr.reserve(64 * 1024);
    json().text().reserve(512 * 1024);

    writer.open(options.path, options.writer);
    report.path = options.path;
    const std::string& idl = link_idl_text();
    static constexpr std::array<std::pair<const char*, const char*>, kLinkTopicCount> kLink = {{
        {"/hq/vehicle_state", "hq_msgs::VehicleState"},
        {"/hq/camera_frame", "hq_msgs::CameraFrame"},
        {"/hq/event", "hq_msgs::Event"},
        {"/hq/heartbeat", "hq_msgs::Heartbeat"},
        {"/hq/velocity_command", "hq_msgs::VelocityCommand"},
        {"/hq/mode_request", "hq_msgs::ModeRequest"},
    }};
    static constexpr std::array<const char*, kLinkTopicCount> kDdsTopic = {
        "hq_vehicle_state", "hq_camera_frame",     "hq_event",
        "hq_heartbeat",     "hq_velocity_command", "hq_mode_request"};
    for (std::size_t i = 0; i < kLinkTopicCount; ++i) {
      const std::uint16_t schema = writer.add_schema(kLink[i].second, "omgidl", as_bytes(idl));
      link_channel[i] = add_channel(
          schema, kLink[i].first, "cdr",
          {{"dds_topic", kDdsTopic[i]}, {"domain_id", std::to_string(options.link.domain_id)}});
    }
    const std::uint16_t image_schema = writer.add_schema("foxglove.CompressedImage", "jsonschema",
                                                         as_bytes(kCompressedImageSchema));
    image_channel = add_channel(image_schema, "/camera/image/compressed", "json", {});
    depth_channel = add_channel(image_schema, "/camera/depth_preview/compressed", "json", {});
    cloud_channel = add_channel(
        writer.add_schema("foxglove.PointCloud", "jsonschema", as_bytes(kPointCloudSchema)),
        "/obstacles", "json", {{"frame", "base_link (FLU: x forward, y left, z up)"}});
    const std::uint16_t transform_schema =
        writer.add_schema("foxglove.FrameTransform", "jsonschema", as_bytes(kFrameTransformSchema));
    tf_channel = add_channel(transform_schema, "/tf", "json",
                             {{"frames", "odom (ENU) -> base_link (FLU), per state"}});
    tf_static_channel =
        add_channel(transform_schema, "/tf_static", "json",
                    {{"frames", "base_link -> camera_link -> camera_optical (the camera mount)"}});
    calibration_channel = add_channel(writer.add_schema("foxglove.CameraCalibration", "jsonschema",
                                                        as_bytes(kCameraCalibrationSchema)),
                                      "/camera/calibration", "json", {{"frame", "camera_optical"}});
    if (options.camera_mount) {
      const geometry::RosCameraFrames frames = geometry::ros_camera_frames(*options.camera_mount);
      T_base_camera_link = rigid(frames.T_F_camera_link);
      T_camera_link_optical = rigid(frames.T_camera_link_optical);
      write_static_transforms(dds_time());
    }
    if (local != nullptr) local->add_channels(*this);

    for (const AttachmentFile& a : options.attachments) {
      std::ifstream in(a.path, std::ios::binary);
      if (!in) {
        report.attachments_skipped.push_back(a.path + ": cannot be read");
        continue;
      }
      const std::string content((std::istreambuf_iterator<char>(in)),
                                std::istreambuf_iterator<char>());
      const std::string type = a.media_type.empty() ? media_type_of(a.path) : a.media_type;
      writer.add_attachment(a.path, type, as_bytes(content), dds_time());
      ++report.attachments;
    }
    writer.flush();
    last_flush_ns = steady_ns();
  }

  std::uint16_t add_channel(std::uint16_t schema, const char* topic, const char* encoding,
                            const mcap::KeyValues& metadata) {
    const std::uint16_t id = writer.add_channel(schema, topic, encoding, metadata);
    if (report.per_channel.size() <= id) report.per_channel.resize(id + 1u);
    report.per_channel[id].topic = topic;
    return id;
  }

  std::uint16_t add_json_channel(const char* topic, const char* schema_name,
                                 const char* json_schema,
                                 const mcap::KeyValues& metadata) override {
    return add_channel(writer.add_schema(schema_name, "jsonschema", as_bytes(json_schema)), topic,
                       "json", metadata);
  }

  // Every message goes through the time-order buffer, so the file's log times never go back.
  void write(std::uint16_t channel, std::int64_t log_ns, std::int64_t publish_ns,
             mcap::Bytes data) override {
    if (owner.failed()) {
      ++report.samples_not_written;
      return;
    }
    order.add(channel, log_ns, publish_ns, data,
              [this](const TimeOrderBuffer::Message& m) { commit(m); });
  }

  void release(std::int64_t horizon_ns) {
    order.release(horizon_ns, [this](const TimeOrderBuffer::Message& m) { commit(m); });
  }

  void commit(const TimeOrderBuffer::Message& m) {
    if (owner.failed()) {
      ++report.samples_not_written;
      return;
    }
    ChannelReport& c = report.per_channel[m.channel];
    try {
      writer.write(m.channel, static_cast<std::uint32_t>(c.messages), m.log_ns, m.publish_ns,
                   m.data);
    } catch (const std::exception& e) {
      // Handed over all the same: its chunk may have reached the file before a later part
      // failed, so count_written() asks the writer what the file holds.
      fail(e.what());
    }
    if (c.messages == 0) c.first_log_time_ns = m.log_ns;
    c.last_log_time_ns = m.log_ns;
    ++c.messages;
  }

  // The report's counts are what reached the file: after a failed write, the messages handed
  // over in the chunk that never got there are not written, whatever the sequence counters say.
  void count_written() {
    const mcap::Statistics& s = writer.statistics();
    report.messages = s.message_count;
    report.channels = s.channel_count;
    report.bytes = writer.bytes_written();
    for (std::size_t id = 0; id < report.per_channel.size(); ++id) {
      const auto written = s.channel_message_counts.find(static_cast<std::uint16_t>(id));
      const std::uint64_t n = written == s.channel_message_counts.end() ? 0 : written->second;
      ChannelReport& c = report.per_channel[id];
      report.samples_not_written += c.messages - std::min(c.messages, n);
      c.messages = n;
    }
  }

  void fail(const std::string& what) {
    if (owner.failed()) return;
    owner.error_ = options.path + ": recording stopped: " + what;
    report.error = owner.error_;
    owner.failed_.store(true, std::memory_order_release);
  }

  // Takes every sample a reader holds as serialized CDR (encapsulation header included, as
  // MCAP's "cdr" encoding expects) and writes it; derives the Foxglove channels from states
  // and frames.
  void drain(std::size_t topic) {
    constexpr std::uint32_t kBatch = 16;
    std::array<ddsi_serdata*, kBatch> samples{};
    std::array<dds_sample_info_t, kBatch> infos{};
    for (;;) {
      const dds_return_t n =
          dds_takecdr(readers[topic], samples.data(), kBatch, infos.data(), DDS_ANY_STATE);
      if (n <= 0) return;
      const std::int64_t log_ns = dds_time();
      for (std::size_t i = 0; i < static_cast<std::size_t>(n); ++i) {
        ddsi_serdata* sample = samples[i];
        if (infos[i].valid_data) {
          const std::uint32_t size = ddsi_serdata_size(sample);
          cdr.resize(size);
          ddsi_serdata_to_ser(sample, 0, size, cdr.data());
          write(link_channel[topic], log_ns, infos[i].source_timestamp, cdr);
          derive(topic, sample, log_ns, infos[i].source_timestamp);
        }
        ddsi_serdata_unref(sample);
      }
      if (static_cast<std::uint32_t>(n) < kBatch) return;
    }
  }

  // The Foxglove channels of a state or frame, and what the local source derives from it
  // (which goes on when this file failed: it may write a file of its own).
  void derive(std::size_t topic, ddsi_serdata* sample, std::int64_t log_ns,
              std::int64_t publish_ns) {
    if (owner.failed() && local == nullptr) return;
    if (topic == kVehicleState &&
        ddsi_serdata_to_sample(sample, &*state_sample, nullptr, nullptr)) {
      if (!owner.failed()) {
        write_cloud(log_ns, publish_ns);
        write_odom_transform(log_ns, publish_ns);
      }
      if (local != nullptr) local->on_link_state(*state_sample, log_ns, publish_ns);
    } else if (topic == kCameraFrame &&
               ddsi_serdata_to_sample(sample, &*camera_sample, nullptr, nullptr)) {
      if (!owner.failed()) write_images(log_ns, publish_ns);
      if (local != nullptr) local->on_link_camera(*camera_sample, log_ns, publish_ns);
    }
  }

  void write_cloud(std::int64_t log_ns, std::int64_t publish_ns) {
    // FRD -> FLU (x, -y, -z), so the 3D panel shows the obstacles the right way up.
    const auto& points = state_sample->obstacle_points_B_m;
    cloud_flu.resize(std::size_t{3} * points._length);
    for (std::uint32_t i = 0; i < points._length; ++i) {
      cloud_flu[3 * i] = points._buffer[i].x;
      cloud_flu[3 * i + 1] = -points._buffer[i].y;
      cloud_flu[3 * i + 2] = -points._buffer[i].z;
    }
    Json& j = json();
    j.clear();
    j.raw("{\"timestamp\":");
    j.stamp(log_ns);
    j.raw(
        ",\"frame_id\":\"base_link\",\"pose\":{\"position\":{\"x\":0,\"y\":0,\"z\":0},"
        "\"orientation\":{\"x\":0,\"y\":0,\"z\":0,\"w\":1}},\"point_stride\":12,\"fields\":["
        "{\"name\":\"x\",\"offset\":0,\"type\":7},{\"name\":\"y\",\"offset\":4,\"type\":7},"
        "{\"name\":\"z\",\"offset\":8,\"type\":7}],\"data\":");
    // Three packed little-endian floats a point: Foxglove's FLOAT32 (7) fields as they are.
    j.base64({reinterpret_cast<const std::uint8_t*>(cloud_flu.data()),
              cloud_flu.size() * sizeof(float)});
    j.raw("}");
    write_json(cloud_channel, log_ns, publish_ns);
  }

  void write_image(std::uint16_t channel, const char* frame_id, std::int64_t log_ns,
                   std::int64_t publish_ns, std::span<const std::uint8_t> data) {
    Json& j = json();
    j.clear();
    j.raw("{\"timestamp\":");
    j.stamp(log_ns);
    j.raw(",\"frame_id\":\"");
    j.raw(frame_id);
    j.raw("\",\"format\":\"");
    j.raw(image_format(data));
    j.raw("\",\"data\":");
    j.base64(data);
    j.raw("}");
    write_json(channel, log_ns, publish_ns);
  }

  // odom -> base_link of the state just taken; the static ones again every second, so a
  // viewer that seeks into the file finds them within a second of any instant.
  void write_odom_transform(std::int64_t log_ns, std::int64_t publish_ns) {
    frame_transform_json(json(), log_ns, kOdomFrame, kBaseFrame, odom_T_base_link(*state_sample));
    write_json(tf_channel, log_ns, publish_ns);
    if (options.camera_mount && log_ns - last_static_ns >= 1'000'000'000) {
      write_static_transforms(log_ns);
    }
  }

  void write_static_transforms(std::int64_t log_ns) {
    last_static_ns = log_ns;
    frame_transform_json(json(), log_ns, kBaseFrame, kCameraLinkFrame, T_base_camera_link);
    write_json(tf_static_channel, log_ns, log_ns);
    frame_transform_json(json(), log_ns, kCameraLinkFrame, kCameraOpticalFrame,
                         T_camera_link_optical);
    write_json(tf_static_channel, log_ns, log_ns);
  }

  void write_images(std::int64_t log_ns, std::int64_t publish_ns) {
    const auto& f = *camera_sample;
    if (camera_set.load(std::memory_order_acquire)) {
      camera_calibration_json(json(), log_ns, kCameraOpticalFrame, camera, f.width_px, f.height_px);
      write_json(calibration_channel, log_ns, publish_ns);
    }
    if (f.rgb_jpeg._length > 0) {
      write_image(image_channel, kCameraOpticalFrame, log_ns, publish_ns,
                  {f.rgb_jpeg._buffer, f.rgb_jpeg._length});
    }
    if (f.depth_preview._length > 0) {
      write_image(depth_channel, kCameraOpticalFrame, log_ns, publish_ns,
                  {f.depth_preview._buffer, f.depth_preview._length});
    }
  }

  void drain_all() {
    for (std::size_t i = 0; i < kLinkTopicCount && options.record_link; ++i) drain(i);
    if (local != nullptr) local->drain(*this);
  }

  void run() {
    // Below the flight's threads: on a loaded machine the scheduler serves the control loops
    // first; the log catches up from DDS histories and its queues. (Linux nice is per thread;
    // raising it needs no privilege. Failure only costs that preference.)
    static_cast<void>(setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 10));
    std::array<dds_attach_t, kLinkTopicCount + 1> triggered{};
    while (!stopping.load(std::memory_order_acquire)) {
      // 100 ms: the local queues have no DDS condition, so they are drained at least this often.
      waitset.wait(triggered, DDS_MSECS(100));
      drain_all();
      // Held for the window: what the queues and readers hand over later is older than now.
      release(dds_time() - options.reorder_window_ns);
      // At least one chunk a second reaches the file, even when few messages arrive, so a
      // SIGKILL loses at most about a second.
      const std::int64_t now_ns = steady_ns();
      if (now_ns - last_flush_ns >= options.writer.chunk_time_limit_ns && !owner.failed()) {
        last_flush_ns = now_ns;
        try {
          writer.flush();
        } catch (const std::exception& e) {
          fail(e.what());
        }
      }
    }
    drain_all();
    release(std::numeric_limits<std::int64_t>::max());
  }

  LinkLog& owner;
  LinkLogOptions options;
  LocalSource* local;
  mcap::McapWriter writer;
  link::Participant participant;
  link::Topics topics;
  link::Reader<link::VehicleState> state_reader;
  link::Reader<link::CameraFrame> camera_reader;
  link::Reader<link::Event> event_reader;
  link::Reader<link::Heartbeat> heartbeat_reader;
  link::Reader<link::VelocityCommand> command_reader;
  link::Reader<link::ModeRequest> mode_reader;
  std::array<link::ReadCondition, kLinkTopicCount> conditions;
  link::GuardCondition stop_condition;
  link::WaitSet waitset;
  std::array<dds_entity_t, kLinkTopicCount> readers{};
  std::array<std::uint16_t, kLinkTopicCount> link_channel{};
  std::uint16_t image_channel = 0;
  std::uint16_t depth_channel = 0;
  std::uint16_t cloud_channel = 0;
  std::uint16_t tf_channel = 0;
  std::uint16_t tf_static_channel = 0;
  std::uint16_t calibration_channel = 0;
  RigidTransform T_base_camera_link;
  RigidTransform T_camera_link_optical;
  std::int64_t last_static_ns = 0;
  std::vector<float> cloud_flu;    ///< the state's cloud in FLU, sized once
  geometry::PinholeCamera camera;  ///< written once before camera_set
  std::atomic<bool> camera_set{false};
  std::atomic<bool> camera_claimed{false};
  link::Sample<link::VehicleState> state_sample;
  link::Sample<link::CameraFrame> camera_sample;
  std::vector<std::uint8_t> cdr;
  std::atomic<bool> stopping{false};
  std::atomic<bool> closed{false};
  std::int64_t last_flush_ns = 0;
  // About a second of a flight at 10 Hz camera (two images and the frame's CDR each).
  TimeOrderBuffer order{8192, std::size_t{8} << 20};
  RecorderReport report;
  std::thread thread;
};

LinkLog::LinkLog(const LinkLogOptions& options, LocalSource* local)
    : impl_(std::make_unique<Impl>(*this, options, local)) {
  impl_->thread = std::thread([this] { impl_->run(); });
}

LinkLog::~LinkLog() {
  try {
    close();
  } catch (...) {
    // close() reports through its return value; nothing may escape a destructor.
  }
}

const std::vector<std::string>& LinkLog::attachments_skipped() const {
  return impl_->report.attachments_skipped;  // written only by the constructor
}

void LinkLog::set_camera(const geometry::PinholeCamera& camera) {
  Impl& d = *impl_;
  if (d.camera_claimed.exchange(true)) return;
  d.camera = camera;
  d.camera_set.store(true, std::memory_order_release);
}

const RecorderReport& LinkLog::close(const mcap::KeyValues& summary) {
  Impl& d = *impl_;
  if (d.closed.exchange(true)) return d.report;
  d.stopping.store(true, std::memory_order_release);
  try {
    d.stop_condition.set(true);
  } catch (const std::exception&) {
    // The thread wakes within its 100 ms wait timeout anyway.
  }
  if (d.thread.joinable()) d.thread.join();
  if (d.local != nullptr) d.report.local_samples_dropped = d.local->dropped();
  if (!failed()) {
    try {
      d.writer.flush();  // the last chunk reaches the file before its messages are counted
      if (!summary.empty()) d.writer.add_metadata("flight_summary", summary);
      mcap::KeyValues counts;
      for (const ChannelReport& c : d.report.per_channel) {
        counts[c.topic + ".messages"] = std::to_string(c.messages);
        counts[c.topic + ".first_log_time_ns"] = std::to_string(c.first_log_time_ns);
        counts[c.topic + ".last_log_time_ns"] = std::to_string(c.last_log_time_ns);
      }
      if (d.local != nullptr) {
        counts[d.local->dropped_key()] = std::to_string(d.report.local_samples_dropped);
        d.local->describe_clock(counts);
      }
      counts["log_time"] = "epoch (CLOCK_REALTIME) ns, written in log-time order";
      counts["reorder_window_ns"] = std::to_string(d.options.reorder_window_ns);
      counts["late_messages_restamped"] = std::to_string(d.order.late());
      counts["late_max_ns"] = std::to_string(d.order.late_max_ns());
      d.writer.add_metadata("recorder", counts);
      d.writer.close();
    } catch (const std::exception& e) {
      d.fail(e.what());
    }
  }
  d.count_written();
  return d.report;
}

}  // namespace hq::flight_log
