#pragma once
/// The flight controller hq-sim --sitl plays over MAVLink, shaped like PX4 in OFFBOARD with
/// attitude-thrust setpoints (docs.px4.io "Offboard Mode"): arming, the offboard mode and its
/// failsafes, a LAND mode, and the messages PX4 streams. Pure: simulated time, truth and
/// messages in, an attitude command and messages out; the process wiring is in sitl_runner.
///
/// Its velocity estimate reads what PX4 reads: ODOMETRY's velocity (body FRD or local NED),
/// fused with its own IMU (VisionVelocityFilter); VISION_SPEED_ESTIMATE is ignored and counted,
/// as PX4 does not fuse it. LAND and the failsafe descent fly on that estimate's vertical
/// velocity, or on a barometer-like vertical rate (truth plus a slowly wandering error) while
/// vision is stale. Its clock is the simulated time since start; it answers TIMESYNC with it.
///
/// Frames: the simulator's world W is NWU, its body B is FRD (core paper §3); MAVLink's local
/// frame is NED, so v_NED = (v_W.x, -v_W.y, -v_W.z).

#include "hq/mavlink/messages.hpp"
#include "hq/sim/imu.hpp"
#include "hq/sim/quadrotor.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sitl/vision_velocity_filter.hpp"

#include <array>
#include <cstdint>
#include <random>
#include <string_view>

namespace hq::sitl {

/// Where the autopilot's messages go (the runner encodes and sends them). Must not allocate.
class MessageSink {
 public:
  virtual ~MessageSink() = default;
  virtual void send(const mavlink::Message& message) = 0;
};

struct SitlAutopilotConfig {
  /// PX4 COM_OF_LOSS_T: offboard with no setpoint for this long -> LAND.
  std::int64_t offboard_loss_ns = 500'000'000;
  /// Offboard is granted only if a setpoint arrived within this (PX4 wants a stream first).
  std::int64_t setpoint_stream_ns = 500'000'000;
  /// Companion heartbeat silent this long while in offboard -> LAND.
  std::int64_t companion_loss_ns = 2'000'000'000;
  double land_speed_mps = 0.5;         ///< Descent speed in LAND.
  double land_speed_gain_per_s = 2.0;  ///< P gain of the vertical-speed loop.
  /// On the ground this long in LAND -> disarm (PX4's land detector).
  std::int64_t landed_disarm_ns = 500'000'000;
  std::int64_t attitude_period_ns = 20'000'000;   ///< ATTITUDE at 50 Hz.
  std::int64_t status_period_ns = 1'000'000'000;  ///< HEARTBEAT and SYS_STATUS at 1 Hz.
  VisionVelocityFilterConfig vision;
  int min_vision_quality_pct = 0;  ///< EKF2_EV_QMIN: ODOMETRY of lower quality is not fused.
  /// The barometer-like vertical rate's error: a first-order Gauss-Markov process.
  double baro_rate_sigma_mps = 0.1;
  double baro_rate_correlation_s = 1.0;
  std::uint32_t seed = 1;
};

enum class SitlMode { kPosctl, kOffboard, kLand };
/// "POSCTL", "OFFBOARD", "LAND".
std::string_view sitl_mode_name(SitlMode mode);

/// What the runner reports at the end.
struct SitlAutopilotStats {
  std::uint64_t setpoints = 0;             ///< SET_ATTITUDE_TARGET accepted as input.
  std::uint64_t setpoints_rejected = 0;    ///< Non-finite or for another system.
  std::uint64_t commands = 0;              ///< COMMAND_LONG received (each acked).
  std::uint64_t vision_speed_ignored = 0;  ///< VISION_SPEED_ESTIMATE: PX4 does not read it.
  std::uint64_t odometry_received = 0;     ///< ODOMETRY messages, whatever became of them.
  std::uint64_t odometry_fused = 0;        ///< Velocity fused into the estimate.
  std::uint64_t odometry_resets = 0;       ///< reset_counter changed: re-initialised on it.
  std::uint64_t rejected_frame = 0;        ///< child_frame_id not BODY_FRD or LOCAL_NED.
  std::uint64_t rejected_estimator = 0;    ///< estimator_type not a vision one (PX4's rule).
  std::uint64_t rejected_nan = 0;          ///< Velocity not finite.
  std::uint64_t rejected_quality = 0;      ///< Below min_vision_quality_pct.
  std::uint64_t rejected_gate = 0;         ///< Innovation beyond the gate.
  std::uint64_t rejected_stamp = 0;        ///< Stamp outside the filter's history.
  /// The velocity received (NED, at its stamp) against the truth then: m^2/s^2 summed.
  std::uint64_t raw_samples = 0;
  double raw_sq_error_sum = 0.0;
  /// The fused velocity against the truth at every IMU step while vision is fresh.
  std::uint64_t fused_samples = 0;
  double fused_sq_error_sum = 0.0;
  std::int64_t descent_on_vision_ns = 0;  ///< LAND flown on the fused vertical velocity.
  std::int64_t descent_on_baro_ns = 0;    ///< LAND flown on the barometer-like rate.
  std::uint64_t timesync_answered = 0;
  std::int64_t armed_ns = 0;
  std::int64_t offboard_ns = 0;
  std::uint64_t gcs_heartbeats = 0;   ///< HEARTBEAT from a GCS (MAV_TYPE_GCS).
  std::uint64_t params_sent = 0;      ///< PARAM_VALUE sent.
  std::uint64_t params_set = 0;       ///< PARAM_SET accepted.
  std::uint64_t params_rejected = 0;  ///< PARAM_SET refused (range, type) or unknown name/index.
};

/// The parameters hq-sim --sitl exposes to a GCS, under PX4's names, onto SitlAutopilotConfig
/// (all REAL32, so no INT32 byte-wise encoding question arises): COM_DISARM_LAND (s),
/// COM_OBC_LOSS_T (s), COM_OF_LOSS_T (s), MPC_LAND_SPEED (m/s), MPC_Z_VEL_P_ACC (1/s).
inline constexpr int kSitlParamCount = 5;

class SitlAutopilot {
 public:
  /// max_thrust_n = 4 rotors x thrust_coefficient x max_rotor_speed^2; hover from mass.
  SitlAutopilot(const sim::QuadrotorParams& vehicle, const SitlAutopilotConfig& config = {});

  /// A message from the companion received at simulated time t_ns.
  void on_message(std::int64_t t_ns, std::uint8_t system_id, std::uint8_t component_id,
                  const mavlink::Message& message, const sim::TruthState& truth, MessageSink& out);
  /// Failsafes, LAND, periodic messages at t_ns; returns the command to hold until the next
  /// call. Call at a fixed tick (e.g. 2 ms).
  sim::AttitudeCommand update(std::int64_t t_ns, const sim::TruthState& truth, MessageSink& out);
  /// One simulator IMU sample: HIGHRES_IMU out (time_usec = simulated time since start), and
  /// the velocity estimate propagated with it, turned into NED with the attitude of `truth`
  /// (this FC's attitude estimate is the truth's).
  void on_imu(const sim::ImuSample& sample, const sim::TruthState& truth, MessageSink& out);

  [[nodiscard]] bool armed() const { return armed_; }
  [[nodiscard]] SitlMode mode() const { return mode_; }
  [[nodiscard]] double max_thrust_n() const { return max_thrust_n_; }
  [[nodiscard]] double battery_v() const { return battery_v_; }
  [[nodiscard]] const SitlAutopilotStats& stats() const { return stats_; }
  /// PX4 custom_mode of the current mode (main << 16 | sub << 24).
  [[nodiscard]] std::uint32_t custom_mode() const;

 private:
  void statustext(std::uint8_t severity, std::string_view text, MessageSink& out) const;
  void ack(const mavlink::CommandLong& command, std::uint8_t result, std::uint8_t system_id,
           std::uint8_t component_id, MessageSink& out) const;
  void handle_command(std::int64_t t_ns, std::uint8_t system_id, std::uint8_t component_id,
                      const mavlink::CommandLong& command, const sim::TruthState& truth,
                      MessageSink& out);
  void handle_setpoint(std::int64_t t_ns, const mavlink::SetAttitudeTarget& target);
  /// The parameter protocol: PARAM_REQUEST_LIST, PARAM_REQUEST_READ, PARAM_SET (echoed).
  void handle_param(const mavlink::Message& message, MessageSink& out);
  void send_param(int index, MessageSink& out);
  void set_mode(SitlMode mode, std::string_view why, MessageSink& out);
  void set_armed(bool armed, std::string_view why, MessageSink& out);
  void send_heartbeat(MessageSink& out) const;
  void handle_odometry(const mavlink::Odometry& odometry);
  /// The vertical velocity (up) this FC flies LAND on: the fused one while vision is fresh,
  /// else the barometer-like rate.
  double estimated_v_up_mps(std::int64_t t_ns, const sim::TruthState& truth, std::int64_t dt_ns);
  /// The true NED velocity at t_ns from the recent IMU steps (false if not that recent).
  bool truth_at(std::int64_t t_ns, Eigen::Vector3d& v_NED_mps) const;
  /// Level, no yaw rate, thrust tracking the vertical speed v_up_mps from v_up_estimate_mps.
  sim::AttitudeCommand level_command(const sim::TruthState& truth, double v_up_mps,
                                     double v_up_estimate_mps) const;

  SitlAutopilotConfig config_;
  double mass_kg_;
  double max_thrust_n_;
  bool armed_ = false;
  SitlMode mode_ = SitlMode::kPosctl;
  sim::AttitudeCommand setpoint_;
  std::int64_t last_setpoint_ns_ = -1;  ///< -1: never.
  std::int64_t last_companion_ns_ = -1;
  std::int64_t last_gcs_ns_ = -1;
  std::int64_t on_ground_since_ns_ = -1;
  std::int64_t last_update_ns_ = -1;
  std::int64_t next_attitude_ns_ = 0;
  std::int64_t next_status_ns_ = 0;
  double battery_v_ = 16.8;
  SitlAutopilotStats stats_;
  VisionVelocityFilter vision_;
  Eigen::Matrix3d R_NED_B_ = Eigen::Matrix3d::Identity();  ///< The last IMU step's attitude.
  bool said_vision_speed_ignored_ = false;
  std::mt19937 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  double baro_rate_error_mps_ = 0.0;
  /// The truth's NED velocity at the recent IMU steps, to score a measurement at its stamp.
  static constexpr std::size_t kTruthHistory = 512;
  std::array<std::int64_t, kTruthHistory> truth_t_ns_{};
  std::array<Eigen::Vector3d, kTruthHistory> truth_v_NED_mps_{};
  std::size_t truth_next_ = 0;
  std::size_t truth_count_ = 0;
};

}  // namespace hq::sitl
