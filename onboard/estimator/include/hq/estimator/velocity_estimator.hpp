#pragma once
/// Vehicle velocity in the horizontal frame H from dense RGB-D odometry and IMU, §3.2 and Fig. 4
/// of the core paper: 1€-filtered camera poses (eq. 2), lever-arm compensation with the
/// low-passed gyro (eq. 4), rotation into H with complementary-filter roll/pitch (eq. 5).
///
/// Frames (hq/geometry/frames.hpp): B body FRD (the core paper's Q), H horizontal (yaw kept),
/// C camera (optical: z forward, x right, y down), Ck the camera at frame k, O the odometry
/// origin (= C0). Comments citing an equation keep the paper's letters (Q_v_Q is v_B).
/// Pure: stamps and data in, estimate out; nothing allocated per update.

#include "hq/estimator/complementary_filter.hpp"
#include "hq/estimator/one_euro_filter.hpp"
#include "hq/odometry/dense_odometry.hpp"

#include <Eigen/Core>

#include <cstdint>

namespace hq::estimator {

struct VelocityEstimatorConfig {
  OneEuroConfig one_euro_position{1.0, 2.0, 1.0};  ///< On p_O_Ck (m): beta in Hz per m/s.
  OneEuroConfig one_euro_rotation{1.0, 1.0, 1.0};  ///< On R_O_Ck: beta in Hz per rad/s.
  ComplementaryConfig complementary;
  double gyro_cutoff_hz = 15.0;    ///< Low-pass on omega_B before eq. 4.
  double min_valid_ratio = 0.05;   ///< Odometry with fewer usable pixels is rejected.
  double max_mean_error = 2500.0;  ///< Odometry mean weighted error (intensity^2) bound.
  double max_frame_gap_s = 0.5;    ///< Longer gaps re-seed the pose filter (no eq. 2 over it).
  double max_imu_age_s = 0.2;      ///< Attitude older than this makes the estimate unavailable.
  /// After a (re)seed the 1€ speed starts at 0 and eq. 2 reads low (0.05 of 0.3 m/s on the
  /// first frame): with velocity_output one_euro no estimate until the filter has run this
  /// long, and v_H_one_euro_mps stays zero meanwhile.
  double warmup_s = 0.2;
  /// Without usable odometry, v_H is propagated from the last good value (or from rest on the
  /// ground) with the accelerometer for at most this long; an MPU-class bias of 0.05 m/s^2
  /// grows to 0.1 m/s in 2 s. 0 disables the coast.
  double inertial_coast_s = 2.0;
  /// The velocity the chain flies on is a Kalman filter's: the IMU's acceleration predicts it
  /// between frames (the high frequencies, no lag) and each frame's odometry velocity corrects
  /// it (the low frequencies, no drift). kFused: that filter's velocity, at the frame's time.
  /// kOneEuro: the core paper's eq. 2-5 on 1-euro filtered poses, which lags 30-150 ms on real
  /// recordings (the filter keeps running for the record either way).
  enum class VelocityOutput { kFused, kOneEuro };
  VelocityOutput velocity_output = VelocityOutput::kFused;
  /// The odometry's position error per frame and axis (m): a frame's velocity (eq. 1, two
  /// poses dt apart) is measured with sqrt(2) this / dt of noise, more where the odometry's own
  /// covariance says so (a degenerate direction). 1 mm: the DVO pair error on fr1 (the bench's
  /// pairs, 1.5-3 mm over two poses); 30 Hz frames then give 0.043 m/s per axis.
  double vision_position_sigma_m = 0.001;
  /// The accelerometer's white noise on the airframe (m/s^2/sqrt(Hz)): the sensor's (BMI088
  /// 0.002) and the motors' vibration. 0.035 is PX4 EKF2's EKF2_ACC_NOISE (0.35 m/s^2 per
  /// 100 Hz step).
  double accel_noise_density_mps2 = 0.035;
  /// An odometry velocity whose innovation against the IMU-propagated one has a squared
  /// Mahalanobis distance above this (3 degrees of freedom: 16.27 rejects 0.1 % of consistent
  /// ones) is rejected: a wrong match, not a manoeuvre, which the accelerometer sees. The
  /// covariance is the filter's, which grows over a coast with the accelerometer's noise and
  /// its unseen acceleration (unseen_accel_sigma_mps2), and the frame's measurement noise.
  double velocity_gate_chi2 = 16.27;
  /// Consecutive frames that must pass that gate before their velocity is used, after any
  /// frame that was not (a start, a loss, a rejection). One wrong frame between lost ones is
  /// how the depth term flew off in the textureless world (docs/estimator.md, "A re-acquired
  /// velocity"): alone it passed the gate, and the vehicle chased its 0.6 m/s. 1: the first frame
  /// is taken.
  int reacquire_frames = 2;
  /// The acceleration the accelerometer does not see (its bias, and the tilt error the
  /// complementary filter makes of it: a vehicle held "level" on a biased accelerometer
  /// accelerates while the IMU reads nothing) is the fused filter's second state, in H,
  /// estimated from how far each frame's velocity lands from the IMU's prediction and added to
  /// every prediction. This is how much it may be before the odometry has checked it: its
  /// prior standard deviation per axis (an MPU-class bias of 0.05 m/s^2 and the level's error
  /// give a horizontal norm under 0.1 nine times in ten). What is still unlearnt (the filter's
  /// standard deviation of it) sets how long a coast may last (coast_max_velocity_error_mps);
  /// the estimate is bounded to three times it, so that wrong but accepted odometry cannot
  /// teach the coast an acceleration no accelerometer misses. 0: none (not estimated).
  double unseen_accel_sigma_mps2 = 0.1;
  /// How fast it may change (m/s^2/sqrt(s)): the tilt error drifts with the gyro's residual
  /// bias (0.1 deg/s tilts gravity's share by 0.017 m/s^3) and the airframe's manoeuvres.
  double unseen_accel_random_walk = 0.02;
  /// The coast ends (the vehicle hovers level) once the velocity error it may have gathered
  /// from the unlearnt acceleration reaches this: a coast one tracked frame after a start is
  /// 1 s, not inertial_coast_s, because nothing has checked the accelerometer yet.
  double coast_max_velocity_error_mps = 0.1;
  /// Each accepted frame hands the odometry's estimate of the gyro's residual bias (from the
  /// vision's rotation against the gyro's, odometry.estimate_gyro_bias) to the attitude filter
  /// (ComplementaryFilter::set_vision_gyro_bias), so a coast's attitude does not drift at it.
  bool gyro_bias_from_odometry = true;
};

/// Reads the `estimator:` section: {one_euro_position: {...}, one_euro_rotation: {...},
/// complementary: {...}, gyro_cutoff_hz, min_valid_ratio, max_mean_error, max_frame_gap_s,
/// max_imu_age_s, warmup_s, inertial_coast_s, velocity_output (fused | one_euro),
/// vision_position_sigma_m, accel_noise_density_mps2, velocity_gate_chi2, reacquire_frames,
/// unseen_accel_sigma_mps2, unseen_accel_random_walk, coast_max_velocity_error_mps,
/// gyro_bias_from_odometry}.
void read_config(config::StrictMap& section, VelocityEstimatorConfig& out);

/// kOk: this frame's odometry velocity was used (eqs. 1-5, fused with the IMU). kInertial:
/// odometry unusable, v_H propagated on the IMU from the last good value for at most
/// inertial_coast_s (degraded but flyable). kUnavailable: neither; the velocities are zero and
/// not to be used.
enum class EstimateStatus { kOk, kInertial, kUnavailable };

/// One velocity estimate. Unless ok(), reason says why odometry is not used and
/// unavailable_for_s for how long.
struct VelocityEstimate {
  std::int64_t t_ns = 0;
  EstimateStatus status = EstimateStatus::kUnavailable;
  const char* reason = "";                                ///< Static text.
  Eigen::Vector3d v_C_mps = Eigen::Vector3d::Zero();      ///< eq. 2: v_Ck in Ck, filtered.
  Eigen::Vector3d v_C_raw_mps = Eigen::Vector3d::Zero();  ///< eq. 1: raw poses.
  /// The velocity to fly on (VelocityEstimatorConfig::velocity_output): eq. 4 and 5 of the
  /// fused velocity, or of eq. 2's.
  Eigen::Vector3d v_B_mps = Eigen::Vector3d::Zero();  ///< eq. 4 (the paper's Q_v_Q).
  Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();  ///< eq. 5 (the paper's H_v_Q).
  /// Eq. 5 of eq. 2's 1-euro velocity, whichever velocity_output is (zero until the 1-euro
  /// filter has warmed up).
  Eigen::Vector3d v_H_one_euro_mps = Eigen::Vector3d::Zero();
  /// v_H_mps's covariance (m^2/s^2): the fused filter's, or the measurement's for kOneEuro.
  Eigen::Matrix3d v_H_covariance = Eigen::Matrix3d::Zero();
  /// The frame's squared Mahalanobis distance against the IMU's prediction (0 without one).
  double innovation_chi2 = 0.0;
  Eigen::Vector3d omega_B_radps = Eigen::Vector3d::Zero();  ///< low-passed, bias removed.
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  double unavailable_for_s = 0.0;  ///< Time since the last kOk estimate (0 when kOk).

  [[nodiscard]] bool ok() const { return status == EstimateStatus::kOk; }
  /// ok() or a bounded inertial coast: good enough to close the velocity loop on.
  [[nodiscard]] bool usable() const { return status != EstimateStatus::kUnavailable; }
};

class VelocityEstimator {
 public:
  /// @param R_B_C, p_B_C_m  the camera's extrinsics (the paper's R_QC and Q_p_C), constant.
  VelocityEstimator(const VelocityEstimatorConfig& config, const Eigen::Matrix3d& R_B_C,
                    const Eigen::Vector3d& p_B_C_m);

  /// IMU sample at IMU rate, body frame B (FRD); accel is specific force. Rejected samples
  /// (NaN, non-increasing stamp) are reported and ignored.
  FilterStatus update_imu(std::int64_t t_ns, const Eigen::Vector3d& gyro_radps,
                          const Eigen::Vector3d& accel_mps2);

  /// One odometry frame (its T_O_C is the pose of Ck in O). Rejected or first frames
  /// give kUnavailable with a reason; never a made-up number.
  VelocityEstimate update(std::int64_t t_ns, const odometry::OdometryResult& odometry);

  /// The vehicle is known to be at rest (landed, motors idle): re-anchors the inertial coast at
  /// zero velocity (a zero-velocity update), so a take-off can climb on the IMU until the floor
  /// comes into the depth camera's range.
  void hold_at_rest(std::int64_t t_ns);
  /// The estimate between frames (camera silent): the inertial coast while it lasts, else
  /// unavailable with `reason`.
  VelocityEstimate between_frames(std::int64_t t_ns, const char* reason);

  [[nodiscard]] const ComplementaryFilter& attitude() const { return attitude_; }
  /// The acceleration in H the accelerometer misses, as learnt so far (m/s^2).
  [[nodiscard]] const Eigen::Vector3d& unseen_accel_H_mps2() const { return unseen_accel_H_mps2_; }
  /// How long a coast may last now: inertial_coast_s, shortened while the accelerometer's
  /// unseen acceleration is not yet learnt (unseen_accel_sigma_mps2).
  [[nodiscard]] double coast_horizon_s() const;
  /// The IMU-propagated velocity's covariance now (m^2/s^2): what an odometry velocity is
  /// gated against, with its own noise.
  [[nodiscard]] Eigen::Matrix3d velocity_covariance() const { return P_.topLeftCorner<3, 3>(); }
  void reset();

 private:
  /// No odometry velocity this frame: the inertial coast if it is still within its horizon,
  /// else kUnavailable; `reason` says why odometry was not used.
  VelocityEstimate unavailable(std::int64_t t_ns, const char* reason);
  /// Why a tracked frame's odometry cannot be used (lost, too little of the image, too large an
  /// error, a non-finite pose), or null when it can.
  [[nodiscard]] const char* unusable_odometry(const odometry::OdometryResult& odometry) const;
  /// from_odometry: v_H_mps is a tracked frame's (the next one's may teach the unseen
  /// acceleration), not a rest assumption.
  /// v_H_raw_mps is the same frame's unfiltered (eq. 1) velocity, which a second coast
  /// integrates for level_on_velocity.
  void anchor_coast(std::int64_t t_ns, const Eigen::Vector3d& v_H_mps, bool from_odometry,
                    const Eigen::Vector3d& v_H_raw_mps);
  /// A tracked frame's unfiltered (eq. 1) velocity against the coast's prediction of it from
  /// the last one levels the attitude (ComplementaryFilter::level_on_velocity).
  void level_on_velocity(std::int64_t t_ns, const Eigen::Vector3d& v_H_raw_mps);
  /// Eq. 1's camera velocity since the previous frame (into v_C_raw_mps) and the body's mean
  /// velocity over it, lever arm removed.
  Eigen::Vector3d raw_v_B(const Eigen::Isometry3d& T_raw, double dt_s,
                          Eigen::Vector3d& v_C_raw_mps) const;
  /// The acceleration in H the coast integrates: specific force levelled, gravity, and the
  /// unseen acceleration learnt.
  [[nodiscard]] Eigen::Vector3d acceleration_H(const Eigen::Vector3d& accel_mps2) const;
  /// Eq. 1's velocity measures the mean over the frame interval; this is the velocity at the
  /// frame's time it implies, with the IMU's acceleration over the interval
  /// (v(t_k) = mean + 1/dt int (t - t_k-1) a dt), in H.
  [[nodiscard]] Eigen::Vector3d velocity_at_frame_H(const Eigen::Vector3d& v_H_mean_mps,
                                                    double dt_s) const;
  /// The frame velocity's noise in H: vision_position_sigma_m, or the odometry's own
  /// covariance where larger, over two poses dt apart.
  [[nodiscard]] Eigen::Matrix3d measurement_covariance_H(const odometry::OdometryResult& odometry,
                                                         double dt_s) const;
  /// The squared Mahalanobis distance of a frame velocity against the IMU's prediction (0
  /// while there is none).
  [[nodiscard]] double innovation_chi2(const Eigen::Vector3d& z_H_mps,
                                       const Eigen::Matrix3d& R_H) const;
  /// The fused filter's covariance over one IMU step: the heading's turn, the accelerometer's
  /// noise, the unseen acceleration's walk.
  void propagate_covariance(const Eigen::Matrix3d& R_turn, double dt_s);
  /// How long a coast may last with this much of the unseen acceleration unlearnt (m/s^2).
  [[nodiscard]] double horizon_for_unlearnt(double unlearnt_mps2) const;
  /// Starts the fused filter: the unseen acceleration zero with its prior.
  void start_filter();
  /// A frame velocity that passed every check: fused, and what follows from it (the motion's
  /// acceleration, the gyro bias, the coast's anchor).
  void take_frame(std::int64_t t_ns, const Eigen::Vector3d& z_H_mps, const Eigen::Matrix3d& R_H,
                  const Eigen::Vector3d& v_H_mean_raw_mps,
                  const Eigen::Vector3d& gyro_bias_C_radps);
  /// Kalman update of the fused velocity with a frame velocity (its first value without one).
  void fuse(const Eigen::Vector3d& z_H_mps, const Eigen::Matrix3d& R_H);
  /// Restarts the pose filter at this pose: velocity resumes after the next accepted frame.
  void reseed(std::int64_t t_ns, const Eigen::Isometry3d& T_O_Ck);

  VelocityEstimatorConfig config_;
  Eigen::Matrix3d R_B_C_;
  Eigen::Vector3d p_B_C_m_;
  ComplementaryFilter attitude_;
  LowPassFilter<3> gyro_low_pass_;
  PoseOneEuroFilter pose_filter_;
  Eigen::Isometry3d T_O_Ck_prev_filtered_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_O_Ck_prev_raw_ = Eigen::Isometry3d::Identity();
  bool have_previous_ = false;
  int agreeing_frames_ = 0;  ///< Consecutive frames that passed the IMU gate, up to now.
  std::int64_t t_prev_frame_ns_ = 0;
  std::int64_t t_seed_ns_ = 0;
  bool ever_ok_ = false;
  bool ever_updated_ = false;
  std::int64_t t_last_ok_ns_ = 0;
  std::int64_t t_first_update_ns_ = 0;
  bool coast_anchored_ = false;
  std::int64_t t_coast_anchor_ns_ = 0;
  double coast_horizon_at_anchor_s_ = 0.0;  ///< coast_horizon_s() of the coast under way.
  std::int64_t t_coast_ns_ = 0;             ///< Stamp of the last IMU sample integrated.
  /// The fused filter: velocity (the coast between frames) and unseen acceleration
  /// (unseen_accel_H_mps2_), both in H, and their joint covariance in that order.
  Eigen::Vector3d coast_v_H_mps_ = Eigen::Vector3d::Zero();
  Eigen::Matrix<double, 6, 6> P_ = Eigen::Matrix<double, 6, 6>::Zero();
  /// int (t - t_prev_frame) a_H dt over the IMU samples since the previous frame.
  Eigen::Vector3d lag_moment_H_ = Eigen::Vector3d::Zero();
  std::int64_t t_lag_moment_ns_ = 0;  ///< Stamp of the last IMU sample in lag_moment_H_.
  bool coast_from_odometry_ = false;
  /// The same coast from the anchoring frame's unfiltered velocity: what level_on_velocity
  /// compares the next frame's with.
  Eigen::Vector3d coast_v_H_raw_mps_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d unseen_accel_H_mps2_ = Eigen::Vector3d::Zero();
  /// The vehicle's own acceleration in H, taken out of the accelerometer before it levels the
  /// attitude.
  Eigen::Vector3d motion_accel_H_mps2_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_H_fused_last_mps_ = Eigen::Vector3d::Zero();  ///< After the last update.
  bool coast_levelling_paused_ = false;  ///< This coast has paused the accelerometer's levelling.
};

const char* to_string(EstimateStatus status);

}  // namespace hq::estimator
