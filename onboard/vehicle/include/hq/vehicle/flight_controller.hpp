#pragma once
/// The flight controller as the vehicle runtime sees it: IMU and attitude in (stamped on the
/// runtime's clock), attitude-thrust setpoints out, arming and the offboard mode, and its health.
/// Implementations: the MAVLink link to PX4/ArduPilot or to hq-sim --sitl (onboard/vehicle), the
/// in-process simulator (onboard/closed_loop, for lock-step test campaigns) and `none` for replays
/// and bench runs, which logs setpoints only.
///
/// Frames (core paper §3): body B is FRD (the paper's Q, NED body); the FC's local frame is NED.

#include "hq/control/velocity_controller.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <string_view>

namespace hq::vehicle {

/// One IMU sample in B, on the runtime clock.
struct FcImuSample {
  std::int64_t t_ns = 0;
  Eigen::Vector3d omega_B_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d f_B_mps2 = Eigen::Vector3d::Zero();  ///< Specific force.
};

/// The FC's own attitude estimate of B in its local NED frame, on the runtime clock.
struct FcAttitude {
  std::int64_t t_ns = 0;
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  double yaw_rad = 0.0;
};

enum class FcSeverity { kInfo, kWarning, kError };

/// Where a reported velocity comes from: the estimator's odometry-corrected filter, or its
/// IMU-only coast over lost frames (degraded, bounded in time; the FC has that IMU itself).
enum class VelocitySource { kOdometry, kInertialCoast };

/// The chain's velocity for the FC's own estimator, one per camera frame while it is usable.
struct VelocityReport {
  std::int64_t t_ns = 0;                                         ///< Runtime clock.
  Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();             ///< In H (yaw-only B).
  Eigen::Matrix3d covariance_H_m2ps2 = Eigen::Matrix3d::Zero();  ///< Of v_H_mps, in H.
  double roll_rad = 0.0;   ///< B in H, as the chain's attitude filter has it (R_H_B = Ry Rx).
  double pitch_rad = 0.0;  ///< B in H, as the chain's attitude filter has it.
  VelocitySource source = VelocitySource::kOdometry;
  /// Bumped when the velocity restarts without continuity (the estimator's filter re-seeded
  /// after the estimate was unavailable): the FC re-initialises instead of fusing the jump.
  std::uint8_t reset_counter = 0;
};

/// Receives what the FC sent, during FlightController::poll().
class FcSink {
 public:
  virtual ~FcSink() = default;
  /// IMU samples in stamp order.
  virtual void on_imu(const FcImuSample& sample) = 0;
  virtual void on_attitude(const FcAttitude& /*attitude*/) {}
  /// Text the FC wants the operator to see (STATUSTEXT, command refusals). The view is valid
  /// only during the call.
  virtual void on_fc_event(FcSeverity /*severity*/, std::string_view /*text*/) {}
};

struct FcStatus {
  bool connected = false;  ///< Heard from within the heartbeat timeout.
  bool armed = false;
  bool offboard = false;  ///< In the mode that flies our setpoints (PX4 OFFBOARD, GUIDED_NOGPS).
  std::int64_t heartbeat_age_ns = -1;  ///< -1: never heard.
  double battery_v = -1.0;             ///< -1: unknown.
  int battery_pct = -1;                ///< -1: unknown.
};

struct FcCounters {
  std::uint64_t messages_sent = 0;
  std::uint64_t messages_received = 0;  ///< Valid frames of known messages.
  std::uint64_t frames_dropped = 0;     ///< Bad CRC, truncated, unknown id, bad length.
  std::uint64_t send_failures = 0;
  std::uint64_t setpoints_sent = 0;
  std::uint64_t imu_samples = 0;
  std::uint64_t velocity_reports_sent = 0;  ///< ODOMETRY or VISION_SPEED_ESTIMATE.
  /// Companion-to-FC clock: from TIMESYNC round trips when the FC answers them, else the
  /// least-delayed-packet mapping of its stamps.
  bool clock_from_timesync = false;
  std::uint64_t timesync_samples = 0;   ///< Answers taken into the offset.
  std::uint64_t timesync_rejected = 0;  ///< Answers too slow (RTT) or far off the offset.
  std::int64_t timesync_offset_ns = 0;  ///< Runtime clock minus FC clock.
  double timesync_jitter_ns = 0.0;      ///< RMS of the samples about the filtered offset.
  std::int64_t timesync_rtt_ns = 0;     ///< Round trip of the last accepted answer.
};

class FlightController {
 public:
  virtual ~FlightController() = default;
  /// Takes everything the FC has sent up to t_ns (runtime clock) and hands it to `sink`. Never
  /// blocks; allocates nothing.
  virtual void poll(std::int64_t t_ns, FcSink& sink) = 0;
  /// An attitude-thrust setpoint produced at t_ns. Allocates nothing.
  virtual void send_setpoint(std::int64_t t_ns, const control::AttitudeSetpoint& setpoint) = 0;
  /// The chain's velocity, for the FC's own estimator. Allocates nothing.
  virtual void send_velocity(const VelocityReport& /*report*/) {}
  /// Asks the FC to arm and enter the offboard mode. Only ever called on an operator's request.
  virtual void request_arm_offboard(std::int64_t /*t_ns*/) {}
  /// Asks the FC to disarm (after touchdown).
  virtual void request_disarm(std::int64_t /*t_ns*/) {}
  [[nodiscard]] virtual FcStatus status(std::int64_t t_ns) const = 0;
  [[nodiscard]] virtual FcCounters counters() const { return {}; }
  [[nodiscard]] virtual std::string describe() const = 0;
};

}  // namespace hq::vehicle
