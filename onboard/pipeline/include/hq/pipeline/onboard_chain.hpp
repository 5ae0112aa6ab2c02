#pragma once
/// The on-board process chain of the core paper (§3.1-3.2, Fig. 4) on one RGB-D frame:
/// dense odometry -> velocity estimator (eqs. 1-5) -> obstacle field (v_obs) -> mode controller
/// (v_des = v*_des + v_obs) -> velocity PID -> attitude-thrust setpoint.
///
/// Configured once; then stamps and data in, setpoint out. The chain reads no clock: stage
/// durations come from a Clock the caller injects (a steady clock in the apps, a fake in tests,
/// none to skip timing). After the first frame, on_frame() allocates nothing.

#include "hq/control/hover_thrust_estimator.hpp"
#include "hq/control/velocity_controller.hpp"
#include "hq/estimator/velocity_estimator.hpp"
#include "hq/geometry/pinhole_camera.hpp"
#include "hq/marker_modes/marker_providers.hpp"
#include "hq/modes/mode_controller.hpp"
#include "hq/obstacle_memory/obstacle_memory.hpp"
#include "hq/obstacles/clearance_filter.hpp"
#include "hq/obstacles/obstacle_field.hpp"
#include "hq/odometry/dense_odometry.hpp"
#include "hq/pipeline/odom_pose.hpp"
#include "hq/seen_space/seen_space_limiter.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

namespace hq::pipeline {

/// The chain's own settings (section `chain:`).
struct ChainConfig {
  double camera_timeout_s = 0.3;  ///< No frame for longer than this: safe hover on IMU only.
  /// Below this climb since take-off (and in land) the floor is expected in view and within the
  /// sensor's minimum range: the obstacle field's near-range hazard and floor push are off.
  double takeoff_height_m = 0.5;
  /// Gives the odometry the gyro's rotation between frames (bias from the complementary
  /// filter's levelling; the odometry estimates the rest) as its initial guess and a prior on
  /// the rotation (odometry.use_rotation_prior).
  bool gyro_rotation_prior = true;
  /// Per-axis rate error of that rotation other than a bias: white noise, the camera-IMU time
  /// offset and the gyro low-pass filter's lag (under fast yaw these dominate: measured through
  /// the chain at 90-120 deg/s, 0.002 made the velocity 2x worse than 0.01). Its covariance is
  /// (this x frame interval)^2 rad^2. The bias the complementary filter leaves (it cannot see
  /// yaw) is the odometry's to allow for and estimate (odometry.gyro_bias_sigma_radps,
  /// estimate_gyro_bias).
  double gyro_prior_sigma_radps = 0.01;
  /// A frame whose depth was taken at most this long before or after its colour has its depth
  /// turned to the colour's exposure by the gyro (odometry.align_depth_to_colour); a larger gap
  /// is a wrong stamp, not a camera's, and is left alone. With gyro_rotation_prior.
  double depth_colour_max_offset_s = 0.05;
  /// Height of the body origin above the floor when standing on it (landing gear): the
  /// height estimate starts here at every take-off.
  double landed_height_m = 0.08;
  /// Safe hover (no usable velocity) for longer than this lands: the IMU holds the
  /// attitude but not the position, so hovering blind forever ends in a drift into a wall.
  /// The land is the modes' blind descent; other mode requests are refused until the estimate
  /// is back.
  double safe_hover_land_s = 5.0;
  /// While the velocity is the inertial coast's, not the odometry's, the operator's horizontal
  /// command is not flown: the vehicle brakes to a hold on the IMU, so that the level safe hover
  /// after the coast starts near standstill. Followed, a command accelerates the vehicle blind
  /// and the safe hover (which cannot brake) carries it on: in the unseen-space campaign with
  /// the depth term, a vehicle that lost its odometry beside a textureless wall reached 1.6 m/s
  /// on the coast and drifted into the wall. Climb and descent are still flown (the take-off
  /// climbs on the coast until the floor is beyond the sensor's minimum range).
  bool hold_on_inertial_coast = true;
  /// The integrated odom pose's uncertainty growth (odom_pose.hpp): keys odom_yaw_drift_radps,
  /// odom_velocity_error_fraction, odom_velocity_error_correlation_s, odom_blind_drift_mps.
  OdomPoseConfig odom;
};

/// Reads the `chain:` section {camera_timeout_s, takeoff_height_m, gyro_rotation_prior,
/// gyro_prior_sigma_radps, depth_colour_max_offset_s, landed_height_m, safe_hover_land_s,
/// hold_on_inertial_coast, odom_yaw_drift_radps, odom_velocity_error_fraction,
/// odom_velocity_error_correlation_s, odom_blind_drift_mps} strictly.
void read_config(config::StrictMap& section, ChainConfig& out);

/// Everything config/onboard.yaml configures, one struct per component.
struct OnboardConfig {
  odometry::OdometryConfig odometry;
  estimator::VelocityEstimatorConfig estimator;
  obstacles::ObstacleConfig obstacles;
  obstacle_memory::MemoryConfig memory;
  seen_space::SeenSpaceConfig seen_space;  ///< No motion into unseen space.
  control::VelocityControllerConfig control;
  /// The thrust the vehicle really gives for the thrust commanded, learnt in flight.
  control::HoverThrustConfig hover_thrust;
  modes::ModesConfig modes;
  ChainConfig chain;
  /// The marker stage and the marker/explore providers; off unless markers.enabled.
  marker_modes::MarkerModesConfig markers;
};

/// Loads an on-board config file strictly: sections odometry, estimator, obstacles, memory,
/// seen_space, control, modes and chain, each handed to its component's read_config (an absent
/// section keeps that component's defaults; an unknown section or key is an error). Throws
/// hq::InputError naming file, key, value and expectation.
OnboardConfig load_onboard_config(const std::string& path);

/// Monotonic time source for stage timing, injected so the chain itself reads no clock.
class Clock {
 public:
  virtual ~Clock() = default;
  [[nodiscard]] virtual std::int64_t now_ns() const = 0;
};

/// Wall durations of one on_frame() call, per stage (ns; all zero without a Clock).
struct StageDurations {
  std::int64_t odometry_ns = 0;
  std::int64_t estimator_ns = 0;
  std::int64_t memory_ns = 0;  ///< Obstacle memory (near zero when disabled).
  std::int64_t obstacles_ns = 0;
  std::int64_t control_ns = 0;  ///< Mode controller and velocity PID.
  std::int64_t total_ns = 0;    ///< Frame arrival to setpoint.
};

/// Stage names in StageDurations order, for tables.
inline constexpr int kStageCount = 6;
inline constexpr const char* kStageNames[kStageCount] = {"odometry",  "estimator", "memory",
                                                         "obstacles", "control",   "total"};
/// The duration of stage i (0..kStageCount-1) in kStageNames order.
std::int64_t stage_ns(const StageDurations& durations, int i);

/// Where ChainOutput::height_m comes from.
enum class HeightSource { kNone, kDepth, kEstimate };
const char* to_string(HeightSource source);

/// One step of the chain: the estimate, the obstacles and the setpoint, with what went wrong.
struct ChainOutput {
  std::int64_t t_ns = 0;
  bool frame = false;  ///< True when produced by on_frame(), false by on_tick().
  odometry::TrackingStatus tracking = odometry::TrackingStatus::kLost;
  const char* tracking_reason = "";  ///< Static text.
  double valid_ratio = 0.0;          ///< Odometry usable-pixel ratio.
  estimator::VelocityEstimate estimate;
  obstacles::ObstacleResult obstacles;
  /// Obstacle memory outcome: memory.cleared is the pose-jump event, memory.clear_count counts
  /// them; memory.reason says why it was skipped (disabled, not tracking).
  obstacle_memory::MemoryUpdate memory;
  modes::ModeOutput mode;  ///< mode.control.setpoint is the attitude-thrust setpoint.
  /// True when the setpoint is the safe hover (level, thrust m g, no yaw rate) because there is
  /// no usable velocity: estimate unavailable, camera timed out or non-finite input.
  bool safe_hover = false;
  /// The velocity is not from odometry this step: an inertial coast (estimate.status kInertial),
  /// or none at all (safe hover). The estimator says so; the ground shows it.
  bool degraded = false;
  const char* safe_hover_reason = "";  ///< Static text when safe_hover.
  bool camera_timed_out = false;
  /// Landed, taking off (left the floor, not yet chain.takeoff_height_m climbed, or an explicit
  /// take-off still climbing), airborne, landing.
  modes::FlightState flight_state = modes::FlightState::kLanded;
  /// Body height above the floor: from depth when the floor is in view (kDepth), else the
  /// landed height plus the climb integrated from the estimate (kEstimate); 0 with kNone.
  double height_m = 0.0;
  HeightSource height_source = HeightSource::kNone;
  /// The body's horizontal offset from where it took off, in H (m): the usable estimates'
  /// velocity integrated in the frame of the take-off heading, turned by the gyro's yaw. It
  /// drifts as any dead reckoning (the estimate's error times the flight time); it bounds the
  /// flight (modes.max_distance_from_takeoff_m), it does not navigate.
  Eigen::Vector2d offset_from_takeoff_H_m = Eigen::Vector2d::Zero();
  /// The body's pose in the world-fixed odom frame (odom_pose.hpp): the same dead reckoning
  /// from the chain's start, never reset (odom -> base_link), with its growing uncertainty.
  OdomPoseEstimate odom;
  /// The vehicle's clearance (hq/obstacles/clearance_filter.hpp: bounding sphere to the
  /// nearest obstacle point in view or in the memory, median of the last frames), the figure
  /// sent as VehicleState.clearance_m (m); -1 when none; held on steps without a frame.
  double clearance_m = -1.0;
  /// The safe hover lasted chain.safe_hover_land_s, so the chain asked to land.
  bool safe_hover_landing = false;
  /// The seen-space limit on the operator's command (teleop), for the operator to
  /// feel and see: the command as flown (before the mode ramp and v_obs), whether it was cut,
  /// and whether by a direction with no data (creep speed).
  seen_space::SeenSpaceUpdate seen_space;
  Eigen::Vector3d v_cmd_flown_H_mps = Eigen::Vector3d::Zero();
  bool command_limited = false;
  bool command_unseen = false;
  /// The operator's command was limited by the flight envelope (modes.max_height_m, the height
  /// unknown, or modes.max_distance_from_takeoff_m); v_cmd_flown_H_mps shows what is flown.
  bool command_envelope_limited = false;
  /// Allowed speed per direction in H, bin 0 along the heading then clockwise, for
  /// seen_space_bins bins (m/s; the creep speed where nothing is known).
  std::array<float, seen_space::kMaxBins> seen_space_limits_mps{};
  int seen_space_bins = 0;
  /// The gain between the thrust commanded and the thrust the rotors give, learnt in flight;
  /// mode.control.setpoint.thrust_n is already divided by it.
  control::HoverThrustEstimate hover_thrust;
  /// The thrust that hovers the vehicle as learnt (N, in the units sent to the FC): m g / gain.
  double hover_thrust_n = 0.0;
  StageDurations durations;
};

/// The marker stage's task for a marker-mode request: what to do about which marker.
struct MarkerTarget {
  marker_modes::MarkerTask task = marker_modes::MarkerTask::kHold;
  int marker_id = 0;
};

/// A mode request as an operator makes it: the mode and, for the marker mode, its task.
struct ModeRequest {
  modes::Mode mode = modes::Mode::kHover;
  std::optional<MarkerTarget> marker;
  /// Take off first (ModeController::request_takeoff), then fly `mode`.
  bool take_off = false;
  /// Operators are held to the modes' dwell and rate limit; what arrives on the operator's path
  /// but is the vehicle's own safety (the link failsafe's land) is kVehicle, never held.
  modes::RequestOrigin origin = modes::RequestOrigin::kOperator;
  /// Asked by a ROS 2 node (link.ros2's mode_request): the answer also goes back there.
  bool from_ros2 = false;
};

class OnboardChain {
 public:
  /// @param camera   intrinsics of the undistorted frames given to on_frame().
  /// @param vehicle  mass, limits and the camera mount T_B_C (the paper's R_QC, Q_p_C).
  /// @param clock    optional, not owned, must outlive the chain; null disables stage timing.
  /// @throws hq::InputError if the components reject the camera or config.
  OnboardChain(const OnboardConfig& config, const VehicleConfig& vehicle,
               const geometry::PinholeCamera& camera, const Clock* clock = nullptr);

  /// One IMU sample in the body frame B (FRD): gyro (rad/s) and specific force (m/s^2).
  /// Non-finite or out-of-order samples are ignored by the estimator.
  void on_imu(std::int64_t t_ns, const Eigen::Vector3d& gyro_radps,
              const Eigen::Vector3d& accel_mps2);

  /// Runs the whole chain on one frame. gray CV_8UC1, depth_m CV_32FC1 (metres, 0 = none), both
  /// camera-sized. Without a usable estimate the setpoint is the controller's safe hover.
  ChainOutput on_frame(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m);
  /// The same for a camera that takes its depth map at depth_t_ns, apart from the colour
  /// (Kinect v1): the depth is turned to the colour's exposure with the gyro.
  ChainOutput on_frame(std::int64_t t_ns, std::int64_t depth_t_ns, const cv::Mat& gray,
                       const cv::Mat& depth_m);

  /// Between frames (e.g. from the IMU loop): once no frame has arrived for longer than
  /// chain.camera_timeout_s (or none ever did), steps the mode controller on the inertial coast
  /// while it lasts, then on the safe hover; otherwise nullopt (the last frame's setpoint
  /// stands).
  std::optional<ChainOutput> on_tick(std::int64_t t_ns);

  /// The operator's latest command (used in teleop mode). The mode controller gets it limited
  /// to the seen space, again on every frame with that frame's view.
  void set_operator_command(const modes::OperatorCommand& command);
  /// The gain between commanded and actual thrust as learnt so far.
  [[nodiscard]] const control::HoverThrustEstimate& hover_thrust() const {
    return hover_thrust_.estimate();
  }
  /// Requests a flight mode; see ModeController::request_mode. Operators' requests are held to
  /// the modes' dwell and rate limit; the vehicle's own (its failsafes) are not.
  modes::ModeSwitch request_mode(modes::Mode mode, modes::RequestOrigin origin);
  /// A mode request with its marker task: the task goes to the marker stage first, and the
  /// whole request is refused (with the reason) when the stage is off or the target invalid.
  modes::ModeSwitch request_mode(const ModeRequest& request);

  [[nodiscard]] modes::Mode mode() const { return modes_.mode(); }
  [[nodiscard]] const OnboardConfig& config() const { return config_; }
  [[nodiscard]] const estimator::VelocityEstimator& estimator() const { return estimator_; }
  /// The obstacle memory (telemetry_cloud(), save()); empty when config.memory.enabled is off.
  [[nodiscard]] const obstacle_memory::ObstacleMemory& memory() const { return memory_; }
  /// The marker stage (navigation, marker and explore providers); null unless markers.enabled.
  [[nodiscard]] marker_modes::MarkerStage* markers() { return markers_.get(); }
  [[nodiscard]] const marker_modes::MarkerStage* markers() const { return markers_.get(); }

 private:
  [[nodiscard]] std::int64_t now_ns() const { return clock_ ? clock_->now_ns() : 0; }
  /// Current R_H_B from the complementary filter (identity before its first sample).
  [[nodiscard]] Eigen::Matrix3d R_H_B_from_tilt() const;
  /// on_frame's stages, in order. The odometry with the gyro's rotation since the last frame.
  odometry::OdometryResult track_odometry(std::int64_t t_ns, std::int64_t depth_t_ns,
                                          const cv::Mat& gray, const cv::Mat& depth_m);
  /// The velocity estimate (eqs. 1-5) and the marker stage into out.estimate.
  void estimate_velocity(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m,
                         const odometry::OdometryResult& odometry, ChainOutput& out);
  /// The obstacle memory into out.memory.
  void update_memory(std::int64_t t_ns, const cv::Mat& depth_m,
                     const odometry::OdometryResult& odometry, const Eigen::Matrix3d& R_H_B,
                     ChainOutput& out);
  /// Take-off phase, obstacle field (v_obs), height and the seen space with the
  /// operator's command limited to it.
  void sense_obstacles(std::int64_t t_ns, const cv::Mat& depth_m,
                       const odometry::OdometryResult& odometry, const Eigen::Matrix3d& R_H_B,
                       ChainOutput& out);
  /// The estimate's v_H when it is usable (odometry or inertial coast), else none.
  static std::optional<Eigen::Vector3d> usable_v_H_mps(const estimator::VelocityEstimate& estimate);
  /// Updates the height above the floor from the floor in view (NaN: none) or the estimate,
  /// hands it to the mode controller and fills out.height_m/height_source.
  void update_height(std::int64_t t_ns, double floor_height_m, ChainOutput& out);
  /// Dead-reckons the offset from the take-off point with a usable estimate (reset on the
  /// floor), hands it to the mode controller and fills out.offset_from_takeoff_H_m; steps the
  /// odom pose (never reset) into out.odom.
  void update_offset_from_takeoff(std::int64_t t_ns, ChainOutput& out);
  /// Fills out.flight_state after the mode step.
  void finish_output(ChainOutput& out) const;
  /// Before the controller runs: a gain learnt since the last output moves the controller's
  /// integral so the thrust sent does not jump.
  void follow_hover_thrust();
  /// Divides the setpoint's thrust by the learnt gain and tells the estimator what was sent.
  void correct_thrust(ChainOutput& out);
  /// Hands the operator's command, limited to the seen space, to the modes; fills out's
  /// command fields and per-bin limits when out is given.
  void apply_operator_limit(ChainOutput* out);
  /// Counts the safe hover and lands once it lasted safe_hover_land_s.
  void escalate_safe_hover(ChainOutput& out);

  OnboardConfig config_;
  const Clock* clock_;
  odometry::DenseOdometry odometry_;
  estimator::VelocityEstimator estimator_;
  obstacle_memory::ObstacleMemory memory_;
  obstacles::ObstacleField obstacles_;
  obstacles::ClearanceFilter clearance_filter_;
  seen_space::SeenSpaceLimiter seen_space_;
  modes::ModeController modes_;
  control::HoverThrustEstimator hover_thrust_;
  /// The latest output was airborne (not on the floor, not taking off or landing): the
  /// accelerometer measures the rotors' thrust.
  bool thrust_measurable_ = false;
  double thrust_gain_applied_ = 1.0;  ///< The gain the controller's integral was moved for.
  std::unique_ptr<marker_modes::MarkerStage> markers_;
  bool have_frame_ = false;
  std::int64_t t_last_frame_ns_ = 0;
  double climb_since_takeoff_m_ = 0.0;  ///< Integrated -v_z of usable estimates since take-off.
  bool takeoff_complete_ = false;       ///< Climbed takeoff_height_m since leaving the ground.
  double height_m_ = 0.0;               ///< Body above the floor (see ChainOutput::height_m).
  bool height_known_ = false;
  std::int64_t t_height_ns_ = 0;
  // The take-off point's dead reckoning: the offset in the frame T of the take-off heading, the
  // yaw of H in T (the gyro's, integrated), and their clocks.
  Eigen::Vector2d offset_T_m_ = Eigen::Vector2d::Zero();
  double yaw_since_takeoff_rad_ = 0.0;
  std::int64_t t_yaw_ns_ = -1;
  std::int64_t t_offset_ns_ = -1;
  OdomPose odom_pose_;  ///< The odom frame's dead reckoning (out.odom).
  bool have_tick_ = false;
  std::int64_t t_first_tick_ns_ = 0;
  Eigen::Matrix3d R_B_C_;  ///< To turn the body's rotation into the camera's.
  Eigen::Matrix3d R_prev_cur_B_ = Eigen::Matrix3d::Identity();  ///< gyro since last frame
  std::int64_t t_last_imu_ns_ = -1;
  bool gyro_since_frame_ = false;
  Eigen::Vector3d omega_B_radps_ = Eigen::Vector3d::Zero();  ///< latest rate, bias removed
  modes::OperatorCommand operator_command_;  ///< As the operator sent it, before the limit.
  bool have_operator_command_ = false;
  /// The last usable velocity estimate (none when unusable): the limiter's reaction distance.
  std::optional<Eigen::Vector3d> v_est_for_limit_H_mps_;
  bool velocity_from_odometry_ = false;  // the last estimate's (hold_on_inertial_coast)
  bool in_safe_hover_ = false;
  std::int64_t t_safe_hover_start_ns_ = 0;
  bool lost_estimate_landing_ = false;  ///< Landing because the safe hover lasted too long.
};

}  // namespace hq::pipeline
