#pragma once
/// hq-onboard --record DIR: one MCAP file per flight on the vehicle, DIR/onboard.mcap.
///
/// The shared link log (hq/flight_log/link_log.hpp) records the link samples the vehicle
/// publishes and receives (states, camera frames, events, heartbeats, velocity commands, mode
/// requests) as the CDR Cyclone carried, on a DDS participant and thread of its own. What only
/// the vehicle knows is pushed from the per-step chain into bounded lock-free queues (no
/// allocation, lock or file I/O on the frame path; a full queue drops and counts) and written
/// on that thread as JSON channels:
///   /onboard/imu        hq_onboard.Imu        every IMU sample the flight controller gave
///   /onboard/odometry   hq_onboard.Odometry   per frame: tracking, valid ratio, v_C (eqs. 1, 2)
///   /onboard/estimator  hq_onboard.Estimator  per step: status, v_B (eq. 4), v_H (eq. 5),
///                                             omega_B, roll and pitch
///   /onboard/control    hq_onboard.Control    per step: mode, flight state, v_des and v_obs in
///                                             H, the thrust/attitude setpoint and whether it
///                                             went to the flight controller
///   /onboard/timing     hq_onboard.Timing     per frame: stage durations (ns)
/// The vehicle config and camera calibration are attachments; the run summary (frames, drops,
/// duration, session id) is the "flight_summary" metadata.
///
/// Beside it, DIR/ros2.mcap (link.ros2.record, on by default; with the link only): the flight as
/// a ROS 2 bag of the MCAP "ros2" profile, the messages the ROS 2 bridge publishes built by its
/// own code from the same link samples, for `ros2 bag info` and `ros2 bag play`
/// (src/ros2_record.hpp; docs/flight-records.md).

#include "hq/flight_log/link_log.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/ros2_bridge/ros2_messages.hpp"
#include "hq/vehicle/flight_controller.hpp"
#include "hq/vehicle/vehicle_runtime.hpp"

#include <cstdint>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace hq::onboard_log {

struct OnboardRecorderOptions {
  std::string dir;          ///< Created if missing; the file is dir/onboard.mcap (must not exist).
  link::LinkConfig link;    ///< The vehicle's link (domain, keys when secured).
  bool record_link = true;  ///< False without --link: only the vehicle's own channels.
  std::vector<flight_log::AttachmentFile> attachments;  ///< vehicle config, camera calibration
  std::size_t step_queue_capacity = 1024;               ///< Chain outputs (about 5 s at 200 Hz).
  std::size_t imu_queue_capacity = 4096;                ///< IMU samples (about 4 s at 1 kHz).
  /// The vehicle file's camera mount: /tf_static (base_link -> camera_link -> camera_optical).
  std::optional<geometry::CameraMount> camera_mount;
  mcap::WriterOptions writer;
};

/// The file name --record DIR writes.
inline constexpr const char* kOnboardFileName = "onboard.mcap";
/// The ROS 2 bag --record DIR writes beside it (link.ros2.record).
inline constexpr const char* kRos2FileName = "ros2.mcap";

/// What reached DIR/ros2.mcap; path empty when it was not recorded.
struct Ros2RecordReport {
  std::string path;
  std::uint64_t messages = 0;
  std::uint64_t bytes = 0;
  std::uint64_t too_large = 0;         ///< Messages larger than the serializing buffer.
  std::uint64_t log_times_raised = 0;  ///< Receipt stamps lifted to the one before (clock step).
  std::vector<std::pair<std::string, std::uint64_t>> per_topic;  ///< ROS topic, messages
  std::string error;                                             ///< First failure, or empty.
};

class OnboardRecorder {
 public:
  /// Creates dir (if needed) and dir/onboard.mcap, the log's DDS participant and thread.
  /// @throws hq::InputError naming the path when it cannot be created or written, or exists.
  explicit OnboardRecorder(const OnboardRecorderOptions& options);
  ~OnboardRecorder();
  OnboardRecorder(const OnboardRecorder&) = delete;
  OnboardRecorder& operator=(const OnboardRecorder&) = delete;

  /// From the frame path: copies what the channels need into a queue slot. Never allocates,
  /// locks or blocks; a full queue drops the step and counts it.
  void push_step(const pipeline::ChainOutput& out, const vehicle::VehicleStatus& status) noexcept;
  /// From the runtime's FC poll: one IMU sample (B frame). Same guarantees.
  void push_imu(const vehicle::FcImuSample& sample) noexcept;

  /// The camera the images come from (the frame source's, undistorted): /camera/calibration
  /// beside every frame. Once, before the flight (the first call wins).
  void set_camera(const geometry::PinholeCamera& camera);
  /// How the chain's clock maps to ROS time in ros2.mcap: the bridge's (Ros2Bridge::clock()),
  /// so the bag's stamps are those it publishes. Before the flight; default: the epoch from the
  /// monotonic clock (a real vehicle); RosClock::simulated_time() adds /clock.
  void set_ros_clock(const ros2_bridge::RosClock& clock);

  /// True once a write failed (disk full); error() names the file and reason. Any thread.
  [[nodiscard]] bool failed() const noexcept;
  [[nodiscard]] const std::string& error() const noexcept;
  [[nodiscard]] const std::string& path() const noexcept;
  [[nodiscard]] const std::vector<std::string>& attachments_skipped() const;
  /// Steps and IMU samples pushed (accepted or dropped), for the exit summary.
  [[nodiscard]] std::uint64_t steps_pushed() const noexcept;
  [[nodiscard]] std::uint64_t imu_pushed() const noexcept;
  /// Wall seconds since construction (steady clock), the recorded run's duration.
  [[nodiscard]] double seconds_since_start() const noexcept;

  /// Stops, writes `summary` as "flight_summary" metadata and closes. Idempotent.
  const flight_log::RecorderReport& close(const mcap::KeyValues& summary = {});
  /// DIR/ros2.mcap's, complete after close().
  [[nodiscard]] const Ros2RecordReport& ros2_report() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The runtime's operator port with the recorder behind it: every chain output is pushed,
/// everything is forwarded to `inner` (may be null). The first write failure is told once as
/// an error event through `inner` (the link port sends it to the ground); the flight goes on.
class RecordingPort final : public vehicle::OperatorPort {
 public:
  RecordingPort(vehicle::OperatorPort* inner, OnboardRecorder& recorder)
      : inner_(inner), recorder_(recorder) {}
  modes::OperatorCommand poll(std::int64_t t_ns,
                              std::vector<pipeline::ModeRequest>& requests) override;
  void on_mode_result(std::int64_t t_ns, const pipeline::ModeRequest& request,
                      const modes::ModeSwitch& result) override;
  void on_output(const pipeline::ChainOutput& out, const vehicle::VehicleStatus& status) override;
  void on_frame(const sources::RgbdFrame& frame) override;
  void on_event(std::int64_t t_ns, vehicle::FcSeverity severity, std::string_view text) override;
  /// True once the recording failure was told.
  [[nodiscard]] bool failure_told() const { return failure_told_; }

 private:
  vehicle::OperatorPort* inner_;
  OnboardRecorder& recorder_;
  bool failure_told_ = false;
};

/// A flight controller with the recorder tapping its IMU: everything else is forwarded.
class RecordingFlightController final : public vehicle::FlightController {
 public:
  RecordingFlightController(vehicle::FlightController& inner, OnboardRecorder& recorder)
      : inner_(inner), recorder_(recorder) {}
  void poll(std::int64_t t_ns, vehicle::FcSink& sink) override;
  void send_setpoint(std::int64_t t_ns, const control::AttitudeSetpoint& setpoint) override {
    inner_.send_setpoint(t_ns, setpoint);
  }
  void send_velocity(const vehicle::VelocityReport& report) override {
    inner_.send_velocity(report);
  }
  void request_arm_offboard(std::int64_t t_ns) override { inner_.request_arm_offboard(t_ns); }
  void request_disarm(std::int64_t t_ns) override { inner_.request_disarm(t_ns); }
  [[nodiscard]] vehicle::FcStatus status(std::int64_t t_ns) const override {
    return inner_.status(t_ns);
  }
  [[nodiscard]] vehicle::FcCounters counters() const override { return inner_.counters(); }
  [[nodiscard]] std::string describe() const override { return inner_.describe(); }

 private:
  vehicle::FlightController& inner_;
  OnboardRecorder& recorder_;
};

/// The exit summary's lines: file, size, per-channel counts ("  record /onboard/imu  N
/// messages"), drops, failure.
void print_report(std::FILE* out, const flight_log::RecorderReport& report);
/// ros2.mcap's lines ("  ros2 record /tf  N messages"), nothing when it was not recorded.
void print_report(std::FILE* out, const Ros2RecordReport& report);

}  // namespace hq::onboard_log
