#pragma once
/// One vehicle runtime for every frame source and flight controller, as on a real vehicle: it
/// owns nothing but the loop. Each step takes what the flight controller sent (IMU, health),
/// what the operator sent (command, mode requests), at most one new RGB-D frame, runs the
/// on-board chain on it (or ticks it between frames) and sends the setpoint to the flight
/// controller. Recordings, cameras, the SITL process and the in-process simulator all run
/// through this same code, so the fail-safes are the same for all of them:
///   - no setpoint stream until the chain has an estimate (or knows it is landed, at rest);
///   - flight controller silent beyond its timeout: an error event, the chain holds (hover);
///   - flight controller disarmed or out of offboard on its own (its failsafe, the pilot's RC, a
///   GCS):
///     said once, the chain lands or holds, and the runtime never re-arms or re-enters offboard
///     by itself: only an operator's request for a flying mode asks the FC to arm (retried a
///     few times while the FC is not yet heard or refuses);
///   - camera silent: the chain's own coast-then-safe-hover (chain.camera_timeout_s);
///   - operator link: the link bridge's hold-then-land, behind the OperatorPort.
///
/// Time is an argument: step(t_ns) with t_ns from CLOCK_MONOTONIC on a vehicle, or simulated
/// time in lock-step runs. step() allocates nothing after the first frame.

#include "hq/frame_source/frame_source.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/vehicle/flight_controller.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

namespace hq::vehicle {

/// Simulator truth, only ever given by a simulated vehicle (for the operator's "vs truth" plots).
struct TruthSample {
  Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d p_W_m = Eigen::Vector3d::Zero();  ///< Simulator world (NWU).
  bool on_ground = true;
};

/// Where truth comes from when the vehicle is simulated (the in-process simulator, the SITL
/// frame channel); absent on a real vehicle.
class TruthSource {
 public:
  virtual ~TruthSource() = default;
  [[nodiscard]] virtual std::optional<TruthSample> truth() const = 0;
};

/// What the runtime knows about the vehicle beyond the chain's output.
struct VehicleStatus {
  FcStatus fc;
  bool streaming = false;    ///< Setpoints go to the FC (since the first estimate or landed).
  bool fc_lost = false;      ///< Heard from once, silent beyond its timeout now.
  bool fc_override = false;  ///< The FC left offboard or disarmed on its own: not our setpoints.
  std::optional<TruthSample> truth;
  [[nodiscard]] bool degraded() const { return fc_lost || fc_override; }
};

/// The operator as the runtime sees it: the DDS link, a scripted timeline, or nobody.
class OperatorPort {
 public:
  virtual ~OperatorPort() = default;
  /// At t_ns: the command to fly now; mode requests that arrived are appended to `requests`.
  virtual modes::OperatorCommand poll(std::int64_t t_ns,
                                      std::vector<pipeline::ModeRequest>& requests) = 0;
  /// What the chain answered to one of those requests.
  virtual void on_mode_result(std::int64_t /*t_ns*/, const pipeline::ModeRequest& /*request*/,
                              const modes::ModeSwitch& /*result*/) {}
  /// Every chain output (frames and ticks), with the runtime's view of the vehicle.
  virtual void on_output(const pipeline::ChainOutput& /*out*/, const VehicleStatus& /*status*/) {}
  /// Every frame the chain processed.
  virtual void on_frame(const sources::RgbdFrame& /*frame*/) {}
  /// Runtime events: the FC lost, disarmed or out of offboard, the setpoint stream started.
  /// The text is valid only during the call.
  virtual void on_event(std::int64_t /*t_ns*/, FcSeverity /*severity*/, std::string_view /*text*/) {
  }
};

/// What the vehicle does when its run ends (the run length, SIGINT/SIGTERM, a fatal error):
/// land where it is, or hold (hover) and leave the rest to the flight controller's own
/// offboard-loss failsafe once the setpoint stream stops.
enum class StopAction { kLand, kHold };
const char* to_string(StopAction action);

struct RuntimeConfig {
  /// The chain is ticked at this period between frames (camera timeout, IMU coast).
  std::int64_t control_period_ns = 5'000'000;
  /// IMU samples buffered between two steps; more are dropped and counted.
  int imu_capacity = 1024;
  /// The least variance per axis sent with the velocity to the FC's estimator (m^2/s^2), and
  /// the variance sent when the estimator's covariance is unknown (zero or not finite): the
  /// estimator's own covariance leaves out what it cannot see (the camera's latency and
  /// extrinsics error), so the FC is never told the velocity is better than this.
  double velocity_variance_m2ps2 = 0.01;
};

struct RuntimeCounters {
  std::uint64_t steps = 0;
  std::uint64_t frames = 0;
  std::uint64_t frames_out_of_order = 0;  ///< Not newer than the previous frame: dropped.
  std::uint64_t ticks = 0;                ///< Chain outputs between frames.
  std::uint64_t setpoints = 0;
  std::uint64_t setpoints_withheld = 0;  ///< Before the first estimate (airborne start).
  std::uint64_t imu_samples = 0;
  std::uint64_t imu_overflow = 0;
  std::uint64_t arm_requests = 0;
  std::uint64_t velocity_reports = 0;  ///< Velocities handed to the FC (usable frames).
  std::uint64_t velocity_resets = 0;   ///< Times the reported velocity restarted (reset_counter).
};

class VehicleRuntime final : private FcSink {
 public:
  /// Nothing is owned; all must outlive the runtime. op and truth may be null.
  /// @throws hq::InputError for a config out of range.
  VehicleRuntime(pipeline::OnboardChain& chain, sources::FrameSource& source, FlightController& fc,
                 OperatorPort* op, const TruthSource* truth = nullptr,
                 const RuntimeConfig& config = {});

  /// One step at t_ns (non-decreasing). Returns false once the frame source has ended and its
  /// last frame was processed.
  bool step(std::int64_t t_ns);

  /// The run is ending: from now on the operator's commands and mode requests are not taken
  /// (the port is still polled, so the link stays served), and the chain lands or holds on the
  /// vehicle's own request (never held by the modes' dwell). Said once as an event. Keep
  /// stepping until stop_complete(); a source that has ended is still ticked.
  void begin_stop(std::int64_t t_ns, StopAction action);
  /// begin_stop() was called and the vehicle is where it should end: landed (kLand, also when it
  /// never took off), hovering (kHold), or the flight controller lost (nothing to fly through).
  [[nodiscard]] bool stop_complete() const;
  [[nodiscard]] bool stopping() const { return stopping_; }

  /// Stamp of a frame read ahead and waiting for the clock to reach it (replays).
  [[nodiscard]] std::optional<std::int64_t> pending_frame_t_ns() const;
  [[nodiscard]] bool ended() const { return ended_ && !have_pending_; }
  [[nodiscard]] const VehicleStatus& status() const { return status_; }
  [[nodiscard]] const RuntimeCounters& counters() const { return counters_; }
  /// The latest chain output (frame or tick); nullopt before the first.
  [[nodiscard]] const std::optional<pipeline::ChainOutput>& last_output() const { return last_; }
  [[nodiscard]] const sources::RgbdFrame& last_frame() const { return frame_; }

 private:
  void on_imu(const FcImuSample& sample) override;
  void on_fc_event(FcSeverity severity, std::string_view text) override;

  static constexpr int kMaxArmAttempts = 5;
  static constexpr std::int64_t kArmRetryNs = 1'000'000'000;

  void supervise_fc(std::int64_t t_ns);
  void request_arm_when_ready(std::int64_t t_ns);
  /// The chain's latest belief: on the ground, motors idle.
  [[nodiscard]] bool landed() const { return last_ && last_->mode.landed; }
  void take_operator(std::int64_t t_ns);
  /// Hands a frame's usable velocity to the FC, from the first estimate on (landed too: EKF2
  /// starts fusing external vision before take-off).
  void report_velocity(const pipeline::ChainOutput& out);
  void feed_imu_until(std::int64_t t_ns);
  void deliver(const pipeline::ChainOutput& out);
  /// Says the learnt hover thrust once it has converged (a warning when far from the config).
  void announce_hover_thrust(const pipeline::ChainOutput& out);
  /// Marker or explore mode holding because the marker pose became invalid, and resuming.
  void announce_marker_position(const pipeline::ChainOutput& out);
  void event(std::int64_t t_ns, FcSeverity severity, std::string_view text);

  pipeline::OnboardChain& chain_;
  sources::FrameSource& source_;
  FlightController& fc_;
  OperatorPort* op_;
  const TruthSource* truth_;
  RuntimeConfig config_;

  std::vector<FcImuSample> imu_;
  int imu_count_ = 0;
  int imu_next_ = 0;
  std::vector<pipeline::ModeRequest> requests_;
  sources::RgbdFrame frame_;
  bool have_pending_ = false;
  bool ended_ = false;
  bool have_frame_ = false;
  std::int64_t t_last_frame_ns_ = 0;
  std::int64_t t_now_ns_ = 0;
  std::int64_t next_tick_ns_ = 0;
  bool ever_connected_ = false;
  bool arm_wanted_ = false;  ///< The operator asked to fly and the FC is not flying us yet.
  int arm_attempts_ = 0;
  std::int64_t next_arm_attempt_ns_ = 0;
  bool was_flying_offboard_ = false;
  bool said_hover_thrust_ = false;  ///< The learnt hover thrust was announced.
  bool stopping_ = false;           ///< begin_stop() was called.
  StopAction stop_action_ = StopAction::kLand;
  /// A frame's estimate was unusable since the last velocity reported: the estimator re-seeds
  /// its filter, so the next one is a restart (reset_counter), not a continuation.
  bool velocity_interrupted_ = false;
  bool velocity_reported_ = false;
  std::uint8_t velocity_reset_counter_ = 0;
  VehicleStatus status_;
  RuntimeCounters counters_;
  std::optional<pipeline::ChainOutput> last_;
};

/// `--fc none`: no flight controller (replays, bench runs). Setpoints are counted and kept, not
/// flown. Its IMU is the recording's (replay), or at the IMU rate a level or accelerometer-tilted
/// one for a camera without a gyro: zero rate, specific force from `tilt_source`'s
/// accelerometer rotated into B by R_B_sensor, else (0, 0, -g).
class NoFlightController final : public FlightController {
 public:
  /// Recorded IMU in stamp order (may be empty).
  explicit NoFlightController(std::vector<FcImuSample> recorded = {});
  /// A live source whose accelerometer gives the tilt (not owned; null: level).
  void set_tilt_source(const sources::FrameSource* tilt_source, const Eigen::Matrix3d& R_B_sensor,
                       double rate_hz = 200.0);

  void poll(std::int64_t t_ns, FcSink& sink) override;
  void send_setpoint(std::int64_t t_ns, const control::AttitudeSetpoint& setpoint) override;
  [[nodiscard]] FcStatus status(std::int64_t t_ns) const override;
  [[nodiscard]] FcCounters counters() const override { return counters_; }
  [[nodiscard]] std::string describe() const override;
  [[nodiscard]] const control::AttitudeSetpoint& last_setpoint() const { return last_setpoint_; }

 private:
  std::vector<FcImuSample> recorded_;
  std::size_t next_recorded_ = 0;
  const sources::FrameSource* tilt_source_ = nullptr;
  bool synthesise_ = false;
  Eigen::Matrix3d R_B_sensor_ = Eigen::Matrix3d::Identity();
  std::int64_t imu_period_ns_ = 5'000'000;
  std::int64_t next_imu_ns_ = -1;
  FcCounters counters_;
  control::AttitudeSetpoint last_setpoint_;
};

}  // namespace hq::vehicle
