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
  double warmup_s = 0.2;           ///< After a (re)seed the 1€ speed starts at 0 and eq. 2
                                   ///< reads low (0.05 of 0.3 m/s on the first frame); no
                                   ///< estimate until the filter has run this long.
  /// Without usable odometry, v_H is propagated from the last good value (or from rest on the
  /// ground) with the accelerometer for at most this long; an MPU-class bias of 0.05 m/s^2
  /// grows to 0.1 m/s in 2 s. 0 disables the coast.
  double inertial_coast_s = 2.0;
  /// An odometry velocity further than this from the IMU-propagated one at the coast's anchor
  /// (the last accepted frame, or rest) is rejected: a wrong match, not a manoeuvre, which the
  /// accelerometer sees. The gate widens by imu_disagreement_growth_mps2 per second since the
  /// anchor, as the coast's own error may, and stays shut after the coast has ended: a vehicle
  /// lost for a second must not take the first velocity it is offered. Tighter than this
  /// rejects good frames: eq. 2's velocity still lags after a warm-up (README "The gate").
  double max_imu_disagreement_mps = 0.5;
  /// How fast the coast's velocity may go wrong: about twice what the campaigns measure (0.084
  /// m/s RMS over coasts of up to 2 s). At 0.3 the gate was 1 m/s wide after 1.7 s lost, and
  /// the depth term's wrong returns came through it (README "Re-acquired twice").
  double imu_disagreement_growth_mps2 = 0.15;
  /// Consecutive frames that must pass that gate before their velocity is used, after any
  /// frame that was not (a start, a loss, a rejection). One wrong frame between lost ones is
  /// how the depth term flew off in the textureless world (README "Re-acquired twice"): alone
  /// it passed the gate, and the vehicle chased its 0.6 m/s. 1: the first frame is taken.
  int reacquire_frames = 2;
  /// The acceleration the accelerometer does not see (its bias, and the tilt error the
  /// complementary filter makes of it: a vehicle held "level" on a biased accelerometer
  /// accelerates while the IMU reads nothing) is learnt while the odometry tracks, from how far
  /// each frame's velocity lands from the coast's prediction, low-passed with this time
  /// constant, and added to the coast. 0: not learnt.
  double unseen_accel_time_constant_s = 5.0;
  /// How much acceleration the accelerometer may miss before the odometry has checked it: its
  /// bias and the level's error (an MPU-class 0.05 m/s^2 per axis gives a horizontal norm under
  /// 0.1 nine times in ten). What is still unlearnt, this x exp(-tracked time / the time
  /// constant), sets how long a coast may last (coast_max_velocity_error_mps); what is learnt
  /// is bounded to three times it, so that wrong but accepted odometry cannot teach the coast
  /// an acceleration no accelerometer misses. 0: neither.
  double unseen_accel_sigma_mps2 = 0.1;
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
/// max_imu_age_s, warmup_s, inertial_coast_s, max_imu_disagreement_mps,
/// imu_disagreement_growth_mps2, reacquire_frames, unseen_accel_time_constant_s,
/// unseen_accel_sigma_mps2, coast_max_velocity_error_mps, gyro_bias_from_odometry}.
void read_config(config::StrictMap& section, VelocityEstimatorConfig& out);

/// kOk: from odometry (eqs. 1-5). kInertial: odometry unusable, v_H propagated on the IMU from
/// the last good value for at most inertial_coast_s (degraded but flyable). kUnavailable:
/// neither; the velocities are zero and not to be used.
enum class EstimateStatus { kOk, kInertial, kUnavailable };

/// One velocity estimate. Unless ok(), reason says why odometry is not used and
/// unavailable_for_s for how long.
struct VelocityEstimate {
  std::int64_t t_ns = 0;
  EstimateStatus status = EstimateStatus::kUnavailable;
  const char* reason = "";                                     ///< Static text.
  Eigen::Vector3d v_C_mps = Eigen::Vector3d::Zero();           ///< eq. 2: v_Ck in Ck, filtered.
  Eigen::Vector3d v_C_raw_mps = Eigen::Vector3d::Zero();       ///< eq. 1: raw poses.
  Eigen::Vector3d v_B_mps = Eigen::Vector3d::Zero();           ///< eq. 4 (the paper's Q_v_Q).
  Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();           ///< eq. 5 (the paper's H_v_Q).
  Eigen::Vector3d omega_body_radps = Eigen::Vector3d::Zero();  ///< low-passed, bias removed.
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
  /// How far an odometry velocity may be from the coast's now and be accepted.
  [[nodiscard]] double imu_gate_mps(std::int64_t t_ns) const;
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
  Eigen::Vector3d raw_body_velocity(const Eigen::Isometry3d& T_raw, double dt_s,
                                    Eigen::Vector3d& v_C_raw_mps) const;
  /// The IMU gate on eq. 1's velocity: false while there is no coast to compare with.
  [[nodiscard]] bool raw_velocity_disagrees_with_the_imu(std::int64_t t_ns,
                                                         const Eigen::Vector3d& v_B_raw) const;
  /// A tracked frame's unfiltered (eq. 1) velocity against the coast's prediction of it:
  /// unseen_accel_H_mps2_.
  void learn_unseen_accel(std::int64_t t_ns, const Eigen::Vector3d& v_H_raw_mps);
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
  std::int64_t t_coast_ns_ = 0;  ///< Stamp of the last IMU sample integrated.
  Eigen::Vector3d coast_v_H_mps_ = Eigen::Vector3d::Zero();
  bool coast_from_odometry_ = false;
  /// The same coast from the anchoring frame's unfiltered velocity: what level_on_velocity
  /// compares the next frame's with.
  Eigen::Vector3d coast_v_H_raw_mps_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d unseen_accel_H_mps2_ = Eigen::Vector3d::Zero();
  double unseen_accel_learnt_s_ = 0.0;  ///< Tracked time the learning has seen since reset.
};

const char* to_string(EstimateStatus status);

}  // namespace hq::estimator
