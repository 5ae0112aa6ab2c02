#pragma once
/// The vehicle side of the DDS link: takes operator commands, mode requests and heartbeats,
/// checks them through the Failsafe, and publishes the vehicle state (with the obstacle memory's
/// cloud at a low rate), events, heartbeats and rate-limited JPEG camera frames.
///
/// poll() never blocks: the on-board loop calls it once per control step with the step's time,
/// which is the receipt stamp of everything it takes. Every sample is taken into preallocated
/// storage and checked before use, so nothing in a message can crash the process.

#include "hq/link/link.hpp"
#include "hq/link/writer_binding.hpp"
#include "hq/link_bridge/failsafe.hpp"
#include "hq/markers/marker_detector.hpp"
#include "hq/modes/mode_controller.hpp"
#include "hq/obstacle_memory/obstacle_memory.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/ros2_bridge/ros2_bridge.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

namespace hq::link_bridge {

/// Event codes of this vehicle (Event.code).
enum class EventCode : std::uint32_t {
  kModeAccepted = 1,
  kModeRefused = 2,
  kCommandsRejected = 3,
  kModeRequestRejected = 4,
  kHeartbeatsRejected = 5,
  kHold = 6,
  kHeartbeatLost = 7,
  kCommandsResumed = 8,
  kMarkerTaskAccepted = 9,
  kMarkerTaskRefused = 10,
  kVehicle = 11,  ///< The vehicle runtime: flight controller lost, disarmed, out of offboard.
  // 20+: ownership and escalation (numbered apart from codes other work may add after 11).
  kCommanderChanged = 20,  ///< Another station commands the vehicle now.
  kHoldToLand = 21,        ///< Held without commands for hold_to_land: landing.
  /// The run ended on purpose, after landing or holding: the session's last event.
  kVehicleEnded = link::kEventCodeVehicleEnded,
  /// Samples claiming another station than their writer's certificate (refused).
  kIntrusion = link::kEventCodeIntrusion,
};

/// The marker stage's task of a link MarkerTask; false for NONE or a value outside the enum.
bool to_marker_task(hq_msgs_MarkerTask value, marker_modes::MarkerTask& task);

/// The chain's mode request of an accepted link request with mode `mode`: its marker task, if it
/// has one (MARKER_TASK_NONE: none). Refused, naming why, when the task is outside the enum or
/// the target id is negative; whether the chain can do it (its marker stage on) is the chain's
/// answer to the request.
Verdict to_mode_request(const link::ModeRequest& request, modes::Mode mode,
                        pipeline::ModeRequest& out);

struct BridgeOptions {
  double camera_rate_hz = 10.0;     ///< JPEG frames to the operator at most this often.
  int jpeg_quality = 70;            ///< cv::imencode quality, 1..100.
  double heartbeat_rate_hz = 10.0;  ///< The vehicle's own heartbeat.
  /// Rejections are summarised in one event per this period, not one per sample, so that a
  /// flood of bad samples cannot flood the reliable event topic.
  double rejection_report_period_s = 1.0;
  /// The remembered obstacle cloud rides on the vehicle state at most this often,
  /// so the console can draw a top view; 0 = never. Between clouds the state carries none.
  double obstacle_cloud_rate_hz = 1.0;
  /// Points per cloud, 1..hq_msgs_kMaxObstaclePoints (the IDL bound).
  int max_obstacle_points = static_cast<int>(hq_msgs_kMaxObstaclePoints);
};

/// What the bridge needs to send the memory's cloud: the map (points in the odometry origin O,
/// hq/geometry/frames.hpp) and where the body is in O, to express the cloud in the body frame B
/// as the IDL field obstacle_points_B_m says.
struct ObstacleCloudSource {
  const obstacle_memory::ObstacleMemory* memory = nullptr;  ///< Not owned; null = no cloud.
  Eigen::Isometry3d T_O_B = Eigen::Isometry3d::Identity();
};

/// What the vehicle state carries beyond the chain's output, each flagged absent unless given.
struct StateExtras {
  ObstacleCloudSource cloud;
  /// The marker filter's pose while it is anchored (marker modes), in the map frame W.
  bool position_valid = false;
  Eigen::Vector3d p_W_m = Eigen::Vector3d::Zero();
  double yaw_rad = 0.0;
  /// Why position_valid is false (hq::navigation::PositionInvalid; 0 while valid or without a
  /// marker stage), seconds since the last accepted marker, horizontal 1-sigma (m).
  std::uint8_t position_invalid_reason = 0;
  double position_age_s = 0.0;
  double position_sigma_m = 0.0;
  /// Markers detected in the latest frame (at most kMaxMarkersInState are sent).
  std::span<const markers::MarkerDetection> markers;
  /// Simulator truth of the velocity in H: only ever set when the vehicle is the simulator.
  bool truth_valid = false;
  Eigen::Vector3d v_truth_H_mps = Eigen::Vector3d::Zero();
  /// The vehicle cannot fly as commanded (its flight controller lost or not in offboard): the
  /// state says degraded whatever the estimate.
  bool vehicle_degraded = false;
  /// Motors spinning: off the floor (not landed) and the flight controller, when one reports,
  /// armed.
  bool motors_armed = false;
  /// The marker the marker or explore mode flies to (< 0: none), and the explore mode's phase
  /// (0: not exploring, else marker_modes::ExplorePhase + 1).
  int marker_target_id = -1;
  int explore_phase = 0;
  /// The modes the vehicle offers (link::mode_bit per hq_msgs_Mode; 0: not said) and why marker
  /// and explore are not (link::ModeOffReason).
  std::uint8_t modes_offered = 0;
  std::uint8_t marker_mode_off_reason = 0;
  std::uint8_t explore_mode_off_reason = 0;
};

class LinkBridge {
 public:
  /// Creates participant, topics, readers and writers on link.domain_id for link.vehicle_id,
  /// and with link.ros2.enabled the ROS 2 topics (ros2_bridge.hpp) on the same participant.
  /// Draws this vehicle's session id (non-zero, std::random_device) unless failsafe.session_id
  /// is already set (tests); it goes out in every state, heartbeat and event, and mode requests
  /// must carry it. link.stations, if any, are the stations allowed to command.
  /// @throws hq::InputError naming the DDS call or the fail-safe setting that failed.
  LinkBridge(const link::LinkConfig& link, const FailsafeConfig& failsafe,
             const BridgeOptions& options = {});

  /// Takes every pending sample (receipt time t_ns), appends accepted mode requests with their
  /// marker tasks (and a land request when the heartbeat is lost) to `mode_requests`, publishes
  /// the heartbeat when due, and returns the fail-safe state whose command the chain must fly.
  /// With ROS 2 on, cmd_vel_in commands are the station link.ros2.station_id of the lowest
  /// priority: taken through the same fail-safe (checks, hold, hold-to-land, heartbeat loss:
  /// its commands stand in for heartbeats), but dropped and counted while a native station's
  /// command was accepted within command_lease_ms, as DDS exclusive ownership would if they
  /// shared a topic. A request whose marker task is malformed (to_mode_request) is refused with a
  /// kMarkerTaskRefused event and not requested. With ROS 2 on, the mode_request texts
  /// (ros2_bridge::parse_mode_request) are mode requests of station link.ros2.station_id for
  /// this session, through the same fail-safe and chain; an unreadable one is refused with a
  /// kModeRequestRejected event and the reason on mode_status.
  const FailsafeState& poll(std::int64_t t_ns, std::vector<pipeline::ModeRequest>& mode_requests);

  /// Acknowledges a mode request with an event (accepted or refused with the chain's reason;
  /// a marker task is named), and on the ROS 2 mode_status when a ROS node asked.
  void acknowledge(std::int64_t t_ns, const pipeline::ModeRequest& request,
                   const modes::ModeSwitch& result);

  /// Publishes the vehicle state of one chain output. When extras.cloud has a memory and the
  /// cloud rate allows it at out.t_ns, the state carries the memory's down-sampled map in Q (at
  /// most max_obstacle_points, finite points only); otherwise an empty cloud. Position, markers
  /// and truth go out as given in extras, flagged absent otherwise. Allocates nothing.
  void publish_state(const pipeline::ChainOutput& out, const StateExtras& extras = {});

  /// Obstacle points in the latest published state (0 when it carried no cloud).
  [[nodiscard]] int last_cloud_size() const { return last_cloud_size_; }
  [[nodiscard]] std::uint64_t clouds_sent() const { return clouds_sent_; }

  /// Publishes `image_bgr` (CV_8UC3 or CV_8UC1) as JPEG if the camera rate allows it now.
  /// Returns true if a frame was sent.
  bool publish_camera(std::int64_t t_ns, const cv::Mat& image_bgr);

  /// Publishes an event (text truncated to the message's bound).
  void publish_event(std::int64_t t_ns, hq_msgs_Severity severity, EventCode code,
                     const char* text);

  /// The session's last event, before the participant goes: "vehicle ended: <reason>" (info,
  /// kVehicleEnded), then waits at most ack_timeout_ns for every matched station to acknowledge
  /// it, so the ground learns the vehicle said goodbye instead of seeing a link loss. Returns
  /// true when all acknowledged (or none is matched), false on timeout. Blocks: call it once, at
  /// the end of a run, never from the control loop.
  bool say_goodbye(std::int64_t t_ns, std::string_view reason,
                   std::int64_t ack_timeout_ns = kGoodbyeAckTimeoutNs);
  static constexpr std::int64_t kGoodbyeAckTimeoutNs = 500'000'000;

  [[nodiscard]] const Failsafe& failsafe() const { return failsafe_; }
  /// The ROS 2 topics, null unless link.ros2.enabled.
  [[nodiscard]] ros2_bridge::Ros2Bridge* ros2() { return ros2_.get(); }
  [[nodiscard]] const ros2_bridge::Ros2Bridge* ros2() const { return ros2_.get(); }
  [[nodiscard]] std::uint64_t session_id() const { return failsafe_.config().session_id; }
  [[nodiscard]] std::uint64_t camera_frames_sent() const { return camera_sent_; }
  [[nodiscard]] std::uint64_t states_sent() const { return state_sequence_; }
  [[nodiscard]] std::uint64_t events_sent() const { return event_sequence_; }

 private:
  /// The stations' mode requests through the fail-safe into mode_requests (operator origin);
  /// each refused one gets an event.
  void take_mode_requests(std::int64_t t_ns, std::vector<pipeline::ModeRequest>& mode_requests);
  /// The ROS 2 node's mode requests (mode_request text) as station link.ros2.station_id's,
  /// through the same fail-safe gate; each refused one is answered on mode_status and an event.
  void take_ros2_mode_requests(std::int64_t t_ns,
                               std::vector<pipeline::ModeRequest>& mode_requests);
  /// The answer to a mode request: an event, and on mode_status when a ROS node asked.
  void answer(std::int64_t t_ns, hq_msgs_Severity severity, EventCode code, const char* text,
              bool from_ros2);
  void report_rejections(std::int64_t t_ns);
  static FailsafeConfig with_session(FailsafeConfig config, const link::LinkConfig& link);

  link::LinkConfig link_;
  BridgeOptions options_;
  Failsafe failsafe_;
  link::Participant participant_;
  link::Topics topics_;
  link::Reader<link::VelocityCommand> command_reader_;
  link::Reader<link::ModeRequest> mode_reader_;
  link::Reader<link::Heartbeat> heartbeat_reader_;
  link::WriterBinding writers_;         ///< Which station each sample's writer is (secured link).
  std::int64_t echo_t_ns_ = 0;          ///< Newest accepted ground heartbeat's stamp.
  std::int64_t echo_receipt_t_ns_ = 0;  ///< When it arrived (our clock).
  link::Writer<link::VehicleState> state_writer_;
  link::Writer<link::CameraFrame> camera_writer_;
  link::Writer<link::Event> event_writer_;
  link::Writer<link::Heartbeat> heartbeat_writer_;
  std::unique_ptr<ros2_bridge::Ros2Bridge> ros2_;
  bool have_native_command_ = false;           ///< A native station's command was accepted.
  std::int64_t last_native_command_t_ns_ = 0;  ///< When the last one was.

  link::Sample<link::VehicleState> state_;
  link::Sample<link::CameraFrame> camera_;
  link::Sample<link::Event> event_;
  std::vector<Eigen::Vector3f> cloud_O_m_;  // telemetry_cloud() output, sized once
  std::vector<unsigned char> jpeg_;
  std::vector<int> jpeg_params_;

  std::uint64_t state_sequence_ = 0;
  std::uint64_t event_sequence_ = 0;
  std::uint64_t heartbeat_sequence_ = 0;
  std::uint64_t ros2_mode_sequence_ = 0;
  std::uint64_t camera_sent_ = 0;
  std::int64_t next_heartbeat_ns_ = 0;
  std::int64_t next_camera_ns_ = 0;
  std::int64_t next_rejection_report_ns_ = 0;
  std::int64_t next_cloud_ns_ = 0;
  int last_cloud_size_ = 0;
  std::uint64_t clouds_sent_ = 0;
  FailsafeCounters reported_;
};

}  // namespace hq::link_bridge
