#pragma once
/// One MCAP file per flight (https://mcap.dev/spec), written beside hq-ground's CSV recording:
/// the shared link log (hq/flight_log/link_log.hpp: every link sample as CDR, the camera and the
/// obstacle cloud for Foxglove, on a thread and DDS participant of its own, crash-safe chunks)
/// plus what only the ground knows (haptic forces, link latency), handed over from the command
/// tick through a bounded lock-free queue that drops and counts when full, never blocks. The
/// command path gains no file I/O and no lock (only Cyclone's delivery of the station's own
/// samples to a reader in the same process, about 8 us a command as measured by
/// hq-bench-flight-recorder).
///
/// Channels (message encoding / schema encoding):
///   /hq/vehicle_state /hq/camera_frame /hq/event /hq/heartbeat /hq/velocity_command
///   /hq/mode_request                      cdr / omgidl (schema "hq_msgs::<Type>")
///   /camera/image/compressed              json / jsonschema foxglove.CompressedImage
///   /camera/depth_preview/compressed      json / jsonschema foxglove.CompressedImage
///   /obstacles                            json / jsonschema foxglove.PointCloud (base_link, FLU)
///   /tf /tf_static                        json / jsonschema foxglove.FrameTransform (odom ->
///                                         base_link; base_link -> camera_link -> camera_optical)
///   /ground/haptics /ground/link          json / jsonschema hq_ground.Haptics, hq_ground.Link
/// log_time is the ground's receipt (dds_time(), the CSV recording's receipt_ns clock), the
/// file in log-time order;
/// publish_time the sample's DDS source timestamp (the writer's dds_time()).
///
/// A failed write (disk full) stops recording, failed() turns true and error() says why; the
/// flight goes on.

#include "hq/flight_log/link_log.hpp"
#include "hq/link/config.hpp"
#include "hq/mcap/mcap.hpp"

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace hq::mcap_recorder {

using flight_log::AttachmentFile;
using flight_log::ChannelReport;
using flight_log::link_idl_text;

struct FlightRecorderOptions {
  std::string path;                          ///< The .mcap file to create (must not exist).
  link::LinkConfig link;                     ///< domain_id: the domain the station flies on.
  std::vector<AttachmentFile> attachments;   ///< Unreadable ones are skipped and reported.
  std::size_t ground_queue_capacity = 4096;  ///< GroundSample slots (about 4 s at 1 kHz).
  mcap::WriterOptions writer;                ///< chunk_time_limit_ns bounds what a SIGKILL loses.
  /// The vehicle file's camera mount: /tf_static (base_link -> camera_link -> camera_optical).
  std::optional<geometry::CameraMount> camera_mount;
};

/// What the ground side knew at one command tick (pushed by the flight loop).
struct GroundSample {
  std::int64_t t_ns = 0;  ///< dds_time() when the command was sent
  bool command_valid = false;
  float v_cmd_H_mps[3] = {0, 0, 0};
  float yaw_rate_cmd_radps = 0;
  float p_D_m[3] = {0, 0, 0};  ///< haptic device position
  float F_D_n[3] = {0, 0, 0};  ///< force rendered on the hand
  float latency_ms = -1;       ///< latest vehicle state one-way latency (stamps)
  float round_trip_ms = -1;    ///< latest heartbeat round trip
  float state_age_ms = -1;     ///< latest state's age through the clock offset
};

/// The link log's report, with the ground queue's drops under their own name.
struct RecorderReport : flight_log::RecorderReport {
  std::uint64_t ground_samples_dropped = 0;  ///< queue full
};

class FlightRecorder {
 public:
  /// Creates the file, the DDS participant and readers, writes schemas, channels and
  /// attachments, and starts the recording thread.
  /// @throws hq::InputError if the file exists (never overwritten) or cannot be created, or a
  /// DDS call fails.
  explicit FlightRecorder(const FlightRecorderOptions& options);
  /// Stops and closes (errors swallowed: call close() to see them).
  ~FlightRecorder();
  FlightRecorder(const FlightRecorder&) = delete;
  FlightRecorder& operator=(const FlightRecorder&) = delete;

  /// From the flight loop (one producer thread): lock-free, allocation-free, never blocks;
  /// false (and counted) when the queue is full or the recorder is closed.
  bool push(const GroundSample& sample) noexcept;

  /// True once a write failed; error() then names the file and reason. Any thread.
  [[nodiscard]] bool failed() const noexcept;
  /// Attachment files that could not be read ("path: reason"), known from construction.
  [[nodiscard]] const std::vector<std::string>& attachments_skipped() const;
  /// Valid once failed() is true (written once, before failed_ is set).
  [[nodiscard]] const std::string& error() const noexcept;

  /// Stops the thread after taking what DDS still holds, writes `summary` as the
  /// "flight_summary" metadata, the recorder's own counts as "recorder" metadata, and the
  /// summary section. Idempotent; returns the report (error non-empty if anything failed).
  const RecorderReport& close(const mcap::KeyValues& summary = {});

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hq::mcap_recorder
