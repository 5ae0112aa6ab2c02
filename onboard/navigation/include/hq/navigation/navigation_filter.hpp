#pragma once
/// Error-state Kalman filter for marker-referenced flight: the
/// marker-EKF's INS mechanisation with error-state correction (position, velocity, attitude)
/// extended by gyro and accelerometer biases, predicted with the IMU and corrected by marker
/// poses (through the marker map) and by the RGB-D velocity in H of the core chain (eq. 5).
///
/// Legend: W world (NED, gravity along +z), B body (the core paper's Q, NED), C camera,
/// H horizontal (W rotated by the body's yaw only, core paper §3). Attitude error is local:
/// R_WB = R̂_WB Exp(dtheta). Error state (15): dp_W, dv_W, dtheta_B, dbg_B, dba_B.
/// Pure: stamps and data in, estimate out; fixed-size matrices, nothing allocated per call.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <string>

namespace hq::config {
class StrictMap;
}
namespace hq::estimator {
struct VelocityEstimate;
}

namespace hq::navigation {

inline constexpr int kErrorStateSize = 15;
using ErrorCovariance = Eigen::Matrix<double, kErrorStateSize, kErrorStateSize>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// Offsets of the error-state blocks.
inline constexpr int kIndexPosition = 0;
inline constexpr int kIndexVelocity = 3;
inline constexpr int kIndexAttitude = 6;
inline constexpr int kIndexGyroBias = 9;
inline constexpr int kIndexAccelBias = 12;

struct NavigationConfig {
  // MEMS figures (defaults: MPU-6000 class, as the simulator's IMU).
  double gyro_noise_density_radps_rthz = 1.7e-4;  ///< rad/s/sqrt(Hz)
  double gyro_bias_walk_radps2_rthz = 2.0e-5;     ///< rad/s^2/sqrt(Hz)
  double accel_noise_density_mps2_rthz = 2.0e-3;  ///< m/s^2/sqrt(Hz)
  double accel_bias_walk_mps3_rthz = 3.0e-3;      ///< m/s^3/sqrt(Hz)
  double gravity_mps2 = 9.81;                     ///< along +z of the NED world.
  // Initial standard deviations (initialize(); the anchor takes pose ones from the marker).
  double initial_position_sigma_m = 1.0;
  double initial_velocity_sigma_mps = 0.3;
  double initial_attitude_sigma_rad = 0.05;  ///< YAML: initial_attitude_sigma_deg.
  double initial_gyro_bias_sigma_radps = 0.01;
  double initial_accel_bias_sigma_mps2 = 0.1;
  // Measurements.
  double velocity_sigma_mps = 0.05;    ///< RGB-D velocity std when the estimate has none.
  double marker_gate_chi2 = 22.46;     ///< 6 dof, 99.9 %.
  double velocity_gate_chi2 = 16.27;   ///< 3 dof, 99.9 %.
  double max_measurement_age_s = 0.1;  ///< older (or newer) than the state by more: rejected.
  double degraded_after_s = 5.0;       ///< no accepted marker for this long: degraded.
  /// Consecutive gated markers after which the filter re-anchors on the marker (it has more
  /// likely diverged than the map has moved); 0 disables.
  int reanchor_after_gated_markers = 10;
  // When the pose may be flown on (check_position): beyond any of these it is invalid.
  /// No accepted marker for longer than this: the pose is dead reckoning, invalid.
  double position_max_age_s = 5.0;
  /// Horizontal 1-sigma position bound, sqrt(P_xx + P_yy): the covariance grows without markers.
  double position_max_sigma_m = 0.5;
  /// This many marker frames (stamps) in a row whose markers all failed the chi-square gate:
  /// the filter disagrees with the map, invalid until a marker is accepted or it re-anchors.
  int position_inconsistent_after_frames = 3;
  /// This many RGB-D velocity updates in a row failing their gate: between markers the pose is
  /// the velocity integrated, and a filter that refuses the velocity drifts unseen by P.
  int position_inconsistent_after_velocities = 10;
};

/// Reads the `navigation:` section (keys as in NavigationConfig, `initial_attitude_sigma_deg`
/// in degrees); strict: unknown keys rejected, ranges checked, errors name file and key.
void read_config(config::StrictMap& section, NavigationConfig& out);
/// Loads the `navigation:` section of a YAML file (other top-level sections are left alone).
NavigationConfig load_navigation_config(const std::string& path);

/// Nominal (whole) state.
struct NominalState {
  Eigen::Vector3d p_W_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_W_mps = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_W_B = Eigen::Quaterniond::Identity();
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();
};

enum class UpdateStatus { kAccepted, kGated, kRejected };

/// Outcome of one input. kGated: a valid measurement failing the Mahalanobis test; kRejected:
/// unusable input (non-finite, stale, bad covariance, not initialised). Neither changes the state.
struct UpdateResult {
  UpdateStatus status = UpdateStatus::kRejected;
  const char* reason = "";  ///< Static text.
  double nis = 0.0;         ///< Normalised innovation squared (updates only).

  [[nodiscard]] bool accepted() const { return status == UpdateStatus::kAccepted; }
};

/// Why the pose may not be flown on; kNone while valid. Values travel on the link
/// (VehicleState.position_invalid_reason), so they are never renumbered.
enum class PositionInvalid : std::uint8_t {
  kNone = 0,
  kNotAnchored = 1,          ///< Not initialised, or no marker seen yet.
  kNoMarker = 2,             ///< No accepted marker for longer than position_max_age_s.
  kCovarianceOverBound = 3,  ///< Horizontal sigma above position_max_sigma_m.
  /// Markers of position_inconsistent_after_frames frames, or position_inconsistent_after_
  /// velocities velocities, gated in a row.
  kInnovationInconsistent = 4,
};
/// Plain words for the operator ("no marker", ...).
const char* to_string(PositionInvalid reason);

/// Whether the pose may be flown on, and the figures behind it.
struct PositionCheck {
  bool valid = false;
  PositionInvalid reason = PositionInvalid::kNotAnchored;
  double age_s = 0.0;               ///< Since the last accepted marker (0 before the first).
  double sigma_horizontal_m = 0.0;  ///< sqrt(P_xx + P_yy).
};

struct NavigationHealth {
  bool initialized = false;
  bool anchored = false;          ///< a marker has fixed position and yaw in the map.
  bool degraded = true;           ///< no accepted marker for >= degraded_after_s (or never).
  double position_sigma_m = 0.0;  ///< sqrt(trace(P_pp)).
  double time_since_marker_s = 0.0;
  long imu_samples = 0;
  long markers_accepted = 0;
  long markers_gated = 0;
  long velocities_accepted = 0;
  long velocities_gated = 0;
  long inputs_rejected = 0;
  long reanchors = 0;
  int disagreeing_marker_frames = 0;  ///< Marker stamps in a row with every marker gated.
  int consecutive_gated_velocities = 0;
  double last_marker_nis = 0.0;  ///< NIS of the last marker update (accepted or gated).
  const char* last_reason = "";  ///< of the last gated or rejected input.
};

class NavigationFilter {
 public:
  /// @param T_B_C  camera extrinsics (B <- C).
  NavigationFilter(const NavigationConfig& config, const Eigen::Isometry3d& T_B_C);

  /// Starts from a nominal state (e.g. level attitude from the accelerometer, zero velocity)
  /// with the configured initial covariance; position and yaw stay unanchored until a marker.
  UpdateResult initialize(std::int64_t t_ns, const NominalState& state);

  /// Sets position and full attitude from a camera pose in the map with its covariance
  /// (see update_marker) while keeping the velocity in H, so the velocity output does not jump
  /// (bumpless switch from velocity-only to marker-referenced flight). Initialises if needed.
  UpdateResult anchor_to_marker(std::int64_t t_ns, const Eigen::Isometry3d& T_W_C,
                                const Matrix6d& covariance);

  /// Mechanisation over (t_prev, t_ns] with the mean of the previous and this sample: gyro in
  /// rad/s, specific force in m/s^2, both body frame. The first sample after initialize() only
  /// sets the time.
  UpdateResult predict(std::int64_t t_ns, const Eigen::Vector3d& gyro_radps,
                       const Eigen::Vector3d& accel_mps2);

  /// Marker pose T_W_C (from a detection through the marker map). Covariance order
  /// (p, theta): p_W_C error in W (m), then rotation error local to C (rad) with
  /// R_meas = R_true Exp(theta). Anchors instead if the filter is not yet anchored.
  UpdateResult update_marker(std::int64_t t_ns, const Eigen::Isometry3d& T_W_C,
                             const Matrix6d& covariance);

  /// Vehicle velocity in H (core paper eq. 5) with its 3x3 covariance.
  UpdateResult update_velocity(std::int64_t t_ns, const Eigen::Vector3d& v_H_mps,
                               const Eigen::Matrix3d& covariance);
  /// The core chain's estimate, with velocity_sigma_mps as its standard deviation.
  UpdateResult update_velocity(const estimator::VelocityEstimate& estimate);

  [[nodiscard]] const NominalState& state() const { return state_; }
  [[nodiscard]] const ErrorCovariance& covariance() const { return P_; }
  [[nodiscard]] std::int64_t t_ns() const { return t_ns_; }
  /// Health at the filter's current time.
  [[nodiscard]] NavigationHealth health() const;
  /// May the pose be flown on at t_now_ns (the age counts from the later of t_now_ns and the
  /// filter's time, so an IMU that stops does not freeze it): anchored, a marker accepted within
  /// position_max_age_s, horizontal sigma within position_max_sigma_m, and fewer than
  /// position_inconsistent_after_frames marker frames in a row whose every marker was
  /// gated (markers of one frame share a stamp) and fewer than
  /// position_inconsistent_after_velocities velocity updates gated in a row. The first failing
  /// check is the reason, in that order. Allocates nothing.
  [[nodiscard]] PositionCheck check_position(std::int64_t t_now_ns) const;
  [[nodiscard]] Eigen::Isometry3d T_W_B() const;
  /// Velocity in H, what the velocity tracker consumes.
  [[nodiscard]] Eigen::Vector3d v_H_mps() const;
  [[nodiscard]] const NavigationConfig& config() const { return config_; }

 private:
  template <int kDim>
  UpdateResult correct(const Eigen::Matrix<double, kDim, 1>& residual,
                       const Eigen::Matrix<double, kDim, kErrorStateSize>& H,
                       const Eigen::Matrix<double, kDim, kDim>& R, double gate_chi2);
  UpdateResult check_stamp(std::int64_t t_ns) const;
  UpdateResult reject(const char* reason);
  /// Books a marker update's outcome against its frame (its stamp).
  void note_marker_outcome(std::int64_t t_ns, bool accepted);
  [[nodiscard]] int disagreeing_marker_frames() const;

  NavigationConfig config_;
  Eigen::Matrix3d R_B_C_;
  Eigen::Vector3d p_B_C_m_;
  NominalState state_;
  ErrorCovariance P_ = ErrorCovariance::Identity();
  std::int64_t t_ns_ = 0;
  bool initialized_ = false;
  bool have_imu_ = false;
  Eigen::Vector3d gyro_prev_radps_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_prev_mps2_ = Eigen::Vector3d::Zero();
  std::int64_t t_last_marker_ns_ = 0;
  int consecutive_gated_markers_ = 0;
  double last_marker_nis_ = 0.0;
  std::int64_t t_marker_frame_ns_ = -1;  ///< Stamp of the marker frame being booked.
  bool frame_accepted_ = false;
  bool frame_gated_ = false;
  int disagreeing_frames_ = 0;  ///< Complete frames in a row with every marker gated.
  int consecutive_gated_velocities_ = 0;
  NavigationHealth counters_;
};

/// Yaw psi of R_WB (ZYX Euler, core paper §3) and the rotation R_WH = Rz(psi).
double yaw_rad(const Eigen::Matrix3d& R_W_B);
Eigen::Matrix3d R_W_H(const Eigen::Matrix3d& R_W_B);

/// Measurement models with their Jacobians w.r.t. the error state (exposed for tests and for
/// callers that fuse their own measurements).
/// Marker: residual (p_meas - p̂_WC, log(R̂_WCᵀ R_meas)) for a predicted camera pose.
Eigen::Matrix<double, 6, kErrorStateSize> marker_jacobian(const NominalState& state,
                                                          const Eigen::Matrix3d& R_B_C,
                                                          const Eigen::Vector3d& p_B_C_m);
/// Velocity in H: h = R_WHᵀ v_W; its Jacobian involves the yaw part of dtheta.
Eigen::Vector3d predict_velocity_horizontal(const NominalState& state);
Eigen::Matrix<double, 3, kErrorStateSize> velocity_jacobian(const NominalState& state);

const char* to_string(UpdateStatus status);

}  // namespace hq::navigation
