#pragma once
/// One MCAP file per flight (https://mcap.dev/spec), as both processes write it: hq-ground's
/// flight.mcap (ground/mcap_recorder) and hq-onboard's onboard.mcap (onboard/onboard_log).
///
/// LinkLog is a DDS subscriber of its own (a second participant on the link's domain, secured
/// as the process's role), so the flight's own paths gain no file I/O and no lock: every link
/// sample is taken as the serialized CDR Cyclone received (dds_takecdr) and written unchanged,
/// with the IDL as an "omgidl" schema, on the log's own thread (niced). The same thread derives
/// what Foxglove's panels draw (the camera as foxglove.CompressedImage, the obstacle cloud as
/// foxglove.PointCloud, both JSON) and writes what only the process knows: a LocalSource adds
/// its channels and drains its bounded lock-free queues (SpscQueue) there.
///
/// Channels (message encoding / schema encoding):
///   /hq/vehicle_state /hq/camera_frame /hq/event /hq/heartbeat /hq/velocity_command
///   /hq/mode_request                      cdr / omgidl (schema "hq_msgs::<Type>")
///   /camera/image/compressed              json / jsonschema foxglove.CompressedImage
///   /camera/depth_preview/compressed      json / jsonschema foxglove.CompressedImage
///   /obstacles                            json / jsonschema foxglove.PointCloud (base_link, FLU)
///   /tf                                   json / jsonschema foxglove.FrameTransform, per state:
///                                         odom (ENU) -> base_link (FLU)
///   /tf_static                            json / jsonschema foxglove.FrameTransform, at the
///                                         start and every second: base_link -> camera_link ->
///                                         camera_optical (the camera mount; when given)
///   /camera/calibration                   json / jsonschema foxglove.CameraCalibration, per
///                                         frame, camera_optical (when set_camera() was called)
///   the LocalSource's                     json / jsonschema
/// One time base per file: every log_time is epoch nanoseconds (the CLOCK_REALTIME of dds_time()).
/// Link samples are stamped at receipt, publish_time is the sample's DDS source timestamp (the
/// writer's dds_time()); a LocalSource maps its own clock to the epoch (describe_clock() says
/// how). Messages are written in log-time order (TimeOrderBuffer, reorder_window_ns), so the
/// file's log times never go back.
///
/// Crash safety: chunks are closed at least once a second and written with write(2), so a
/// SIGKILLed process loses about the last second and hq::mcap::McapReader (or any reader that
/// scans without the summary) still reads the rest. A failed write (disk full) stops recording,
/// failed() turns true and error() says why; the flight goes on.

#include "hq/flight_log/json.hpp"
#include "hq/geometry/camera_mount.hpp"
#include "hq/geometry/pinhole_camera.hpp"
#include "hq/link/config.hpp"
#include "hq/mcap/mcap.hpp"
#include "hq/security/keys.hpp"

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace hq::flight_log {

/// A file stored as an MCAP attachment (vehicle config, camera calibration, haptics config).
struct AttachmentFile {
  std::string path;
  std::string media_type = "application/yaml";  ///< Empty: from the file name.
};

/// Per channel, what was written (for the exit summary and the tests' independent readers).
struct ChannelReport {
  std::string topic;
  std::uint64_t messages = 0;
  std::int64_t first_log_time_ns = 0;
  std::int64_t last_log_time_ns = 0;
};

/// Counts are of what reached the file: a message handed over in a chunk whose write failed
/// (disk full) is not written.
struct RecorderReport {
  std::string path;
  std::uint64_t messages = 0;
  std::uint32_t channels = 0;
  std::uint64_t bytes = 0;
  std::uint32_t attachments = 0;
  std::uint64_t local_samples_dropped = 0;       ///< the LocalSource's queues were full
  std::uint64_t samples_not_written = 0;         ///< taken after a write failure or lost in it
  std::vector<ChannelReport> per_channel;        ///< by channel id
  std::vector<std::string> attachments_skipped;  ///< "path: reason"
  std::string error;                             ///< first failure, or empty
};

/// What a LocalSource writes through, on the log's thread (and in its constructor).
class ChannelWriter {
 public:
  virtual ~ChannelWriter() = default;
  /// A json channel with a jsonschema schema; returns its channel id.
  virtual std::uint16_t add_json_channel(const char* topic, const char* schema_name,
                                         const char* json_schema,
                                         const mcap::KeyValues& metadata) = 0;
  /// One message; after a write failure it is counted as not written, never thrown.
  virtual void write(std::uint16_t channel, std::int64_t log_ns, std::int64_t publish_ns,
                     mcap::Bytes data) = 0;
  /// write() of json() as it stands.
  void write_json(std::uint16_t channel, std::int64_t log_ns, std::int64_t publish_ns);
  /// A reused buffer for the message being built.
  Json& json() { return json_; }

 private:
  Json json_;
};

/// What only the process knows, handed over from its hot path through bounded queues.
class LocalSource {
 public:
  virtual ~LocalSource() = default;
  /// In LinkLog's constructor, after the link channels: add this source's channels.
  virtual void add_channels(ChannelWriter& out) = 0;
  /// On the log's thread (at least every 100 ms, and once at close): write what was queued.
  virtual void drain(ChannelWriter& out) = 0;
  /// Samples the queues refused (full). Any thread.
  [[nodiscard]] virtual std::uint64_t dropped() const = 0;
  /// Metadata key for dropped() in the "recorder" record, e.g. "ground_samples_dropped".
  [[nodiscard]] virtual const char* dropped_key() const = 0;
  /// At close, after the last drain: how the source's clock was mapped to the epoch, added to
  /// the "recorder" metadata. Nothing by default (a source stamping in the epoch already).
  virtual void describe_clock(mcap::KeyValues& /*recorder_metadata*/) const {}
  /// On the log's thread, for each vehicle state and camera frame the log takes (decoded, valid
  /// for the call only), with its log and publish times: what a source derives from the link's
  /// samples (the vehicle's ROS 2 bag). Nothing by default.
  virtual void on_link_state(const link::VehicleState& /*state*/, std::int64_t /*log_ns*/,
                             std::int64_t /*publish_ns*/) {}
  virtual void on_link_camera(const link::CameraFrame& /*frame*/, std::int64_t /*log_ns*/,
                              std::int64_t /*publish_ns*/) {}
};

struct LinkLogOptions {
  std::string path;       ///< The .mcap file to create (must not exist).
  link::LinkConfig link;  ///< domain_id, and the keys when the link is secured.
  security::Role role = security::Role::kStation;  ///< The identity the log's participant uses.
  std::vector<AttachmentFile> attachments;         ///< Unreadable ones are skipped and reported.
  mcap::WriterOptions writer;  ///< chunk_time_limit_ns bounds what a SIGKILL loses.
  /// Messages are held this long before they are written in log-time order: longer than the
  /// log thread's drain period (100 ms) plus what a local source's stamps lag behind the clock.
  /// A SIGKILL loses this much more.
  std::int64_t reorder_window_ns = 250'000'000;
  /// The vehicle file's camera mount: /tf_static's base_link -> camera_link -> camera_optical.
  /// Empty: no static transforms (the image frames then have no path to odom).
  std::optional<geometry::CameraMount> camera_mount;
  /// False: the link channels are declared but nothing is taken from DDS (a process without a
  /// link must not record whoever else flies on the domain).
  bool record_link = true;
};

class LinkLog {
 public:
  /// Creates the file, the DDS participant and readers, writes schemas, channels (the link's,
  /// then `local`'s) and attachments, and starts the log's thread. `local` (may be null) is not
  /// owned and must outlive the log.
  /// @throws hq::InputError if the file exists (never overwritten) or cannot be created, or a
  /// DDS call fails.
  LinkLog(const LinkLogOptions& options, LocalSource* local);
  /// Stops and closes (errors swallowed: call close() to see them).
  ~LinkLog();
  LinkLog(const LinkLog&) = delete;
  LinkLog& operator=(const LinkLog&) = delete;

  /// True once a write failed; error() then names the file and reason. Any thread.
  [[nodiscard]] bool failed() const noexcept { return failed_.load(std::memory_order_acquire); }
  /// Valid once failed() is true (written once, before failed_ is set).
  [[nodiscard]] const std::string& error() const noexcept { return error_; }
  /// Attachment files that could not be read ("path: reason"), known from construction.
  [[nodiscard]] const std::vector<std::string>& attachments_skipped() const;

  /// The camera's calibration (the images' intrinsics, scaled to each frame's size), written
  /// as /camera/calibration beside every frame from now on. Once, before frames flow (the
  /// first call wins); any thread.
  void set_camera(const geometry::PinholeCamera& camera);

  /// Stops the thread after taking what DDS and the local queues still hold, writes `summary`
  /// as the "flight_summary" metadata, the log's own counts as "recorder" metadata, and the
  /// summary section. Idempotent; returns the report (error non-empty if anything failed).
  const RecorderReport& close(const mcap::KeyValues& summary = {});

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::atomic<bool> failed_{false};
  std::string error_;
};

/// The link IDL (shared/link/idl/haptiquad.idl) as compiled in, the omgidl schema's text.
const std::string& link_idl_text();

}  // namespace hq::flight_log
