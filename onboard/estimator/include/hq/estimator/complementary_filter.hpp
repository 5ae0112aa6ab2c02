#pragma once
/// Attitude from IMU: the explicit complementary filter on SO(3) with gyro bias estimation
/// (Mahony, Hamel, Pflimlin, IEEE TAC 2008), and a first-order low-pass for gyro rates. Both give
/// the roll/pitch and omega estimates of the core paper, §3.2 and Fig. 4.
///
/// Frames (hq/geometry/frames.hpp): B the body, FRD (the core paper's Q); N the level NWU world
/// (the core paper's W) with the filter's (unobservable, drifting) yaw. The filter integrates
/// in the gravity-aligned NED frame that shares N's yaw (N turned by Rx(pi), no letter of its
/// own): R_ned_B = Rz(psi) Ry(theta) Rx(phi) (ZYX, aerospace), so roll phi and pitch theta
/// are the core paper's, and R_N_B = Rx(pi) R_ned_B, as its R_WQ = Rx(pi) Rz(psi) Ry(theta)
/// Rx(phi).

#include "hq/base/monotonic_clock.hpp"
#include "hq/estimator/one_euro_filter.hpp"

#include <Eigen/Core>

#include <cstdint>

namespace hq::estimator {

/// Standard gravity (m/s^2).
inline constexpr double kGravityMps2 = 9.80665;

/// R_H_B (the core paper's R_HQ): body B into the horizontal frame H (B with roll and pitch
/// removed, yaw kept, origin at B, z_H along gravity), R_H_B = Ry(pitch) Rx(roll), so
/// v_H = R_H_B v_B (eq. 5 of the core paper; the paper prints R_QH = Rz(theta) Rx(phi), which
/// we read as this rotation's transpose).
Eigen::Matrix3d R_H_B_from_tilt(double roll_rad, double pitch_rad);

struct ComplementaryConfig {
  double k_p = 1.0;                   ///< Proportional gain on the accelerometer error (1/s).
  double k_i = 0.05;                  ///< Integral gain: gyro bias estimation (1/s^2).
  double accel_tolerance_mps2 = 3.0;  ///< Accel used only when | |a| - g | is within this.
  double max_bias_radps = 0.2;        ///< Bias estimate clamped per axis.
  double max_dt_s = 0.1;              ///< A larger gap re-initialises from the accelerometer.
  bool init_from_accel = true;        ///< First sample sets roll/pitch from the accelerometer.
  /// Gains on the tilt that a measured velocity gives (level_on_velocity): 0 turns it off.
  /// Off by default: each frame's velocity difference carries the odometry's noise over one
  /// frame interval, which on real Kinect frames (0.06 m/s per axis, fr1/xyz) is 1.8 m/s^2 of
  /// apparent acceleration, and at 0.3 it tilted the attitude enough to throw the fused
  /// velocity 0.24 m/s RMS off on the whole fr1/xyz (0.06 without). The fused filter's unseen
  /// acceleration (VelocityEstimatorConfig::unseen_accel_sigma_mps2) carries a tilt's effect on
  /// the velocity instead, weighed by the measurement's noise.
  double velocity_k_p = 0.0;  ///< 1/s
  /// 0: wrong but accepted odometry velocities (the depth term's in a plain corner) taught the
  /// gyro a bias that tilted the next coast 2.5 deg off; the accelerometer's term learns it.
  double velocity_k_i = 0.0;  ///< 1/s^2
  /// After a velocity-aided correction, or from the last frame a coast started after
  /// (pause_levelling), the accelerometer's own levelling stays off this long: a multirotor's
  /// accelerometer reads its thrust, not gravity, whenever it accelerates, and the two
  /// levellings pulling apart lose k_p / (k_p + velocity_k_p) of every tilt. At least the
  /// inertial coast's length, so a coast keeps the attitude tracking gave it.
  double accel_levelling_pause_s = 2.0;
};

/// Reads {k_p, k_i, accel_tolerance_mps2, max_bias_radps, max_dt_s, init_from_accel,
/// velocity_k_p, velocity_k_i, accel_levelling_pause_s}.
void read_config(config::StrictMap& section, ComplementaryConfig& out);

/// Mahony 2008 explicit complementary filter with bias (its eq. 32 with one vector, gravity).
class ComplementaryFilter {
 public:
  explicit ComplementaryFilter(const ComplementaryConfig& config = {});

  /// One IMU sample in the body frame B (FRD). accel is the specific force (at rest it points
  /// up, i.e. -z for a level vehicle). Non-finite input is rejected and reported.
  FilterStatus update(std::int64_t t_ns, const Eigen::Vector3d& gyro_radps,
                      const Eigen::Vector3d& accel_mps2);

  /// Velocity-aided levelling (the tilt a velocity measurement sees; cf. Hua 2010,
  /// velocity-aided attitude estimation). accel_error_H is the horizontal frame H's acceleration
  /// that this filter's roll and pitch missed over the last span_s: a velocity measured at both
  /// ends minus what the specific force, rotated into H with this filter's attitude, integrated
  /// to. A tilt error delta (body) puts g R_H_B (u x delta) into it, u the body's down, so
  /// (R_H_B^T a / g) x u is delta's observable part, corrected with velocity_k_p and
  /// velocity_k_i as Mahony's accelerometer term. Errors beyond accel_tolerance_mps2 are not
  /// used (not a tilt: a wrong velocity). Returns whether it was used.
  bool level_on_velocity(std::int64_t t_ns, const Eigen::Vector3d& accel_error_H_mps2,
                         double span_s);

  /// Keeps the attitude tracking gave it: the accelerometer's own levelling pauses for
  /// accel_levelling_pause_s from t_ns, as after a velocity-aided correction. For a coast,
  /// where nothing measures the vehicle's acceleration any more and the accelerometer would
  /// level on it.
  void pause_levelling(std::int64_t t_ns);

  /// Body B in the gravity-aligned NED frame with N's yaw.
  [[nodiscard]] const Eigen::Matrix3d& R_ned_B() const { return R_ned_B_; }
  /// Body B in N (NWU, the core paper's W), yaw as integrated by the filter.
  [[nodiscard]] Eigen::Matrix3d R_N_B() const;
  [[nodiscard]] double roll_rad() const;
  [[nodiscard]] double pitch_rad() const;
  /// The gyro residual bias the vision measured beyond this filter's own estimate (the
  /// odometry's, turned into B): added to it from now on. Non-finite input is ignored; bounded
  /// per axis by max_bias_radps. The accelerometer (k_i) cannot see a yaw bias and learns a tilt
  /// one slowly, and while the velocity aids the levelling it is paused: a coast then drifts
  /// at whatever bias is left (about 0.8 deg/s in the unseen-space campaign).
  void set_vision_gyro_bias(const Eigen::Vector3d& bias_radps);
  /// The whole gyro bias estimate: what the levelling learnt plus what the vision measured.
  [[nodiscard]] Eigen::Vector3d gyro_bias_radps() const { return bias_radps_ + vision_bias_radps_; }
  /// The bias the levelling (accelerometer, velocity) learnt alone: the odometry's gyro prior is
  /// corrected by this one, so that what the odometry estimates is the rest.
  [[nodiscard]] const Eigen::Vector3d& levelling_gyro_bias_radps() const { return bias_radps_; }
  [[nodiscard]] bool initialized() const { return initialized_; }
  [[nodiscard]] std::int64_t t_ns() const { return t_ns_; }
  void reset();

 private:
  void initialize(const Eigen::Vector3d& accel_mps2);

  ComplementaryConfig config_;
  Eigen::Matrix3d R_ned_B_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d bias_radps_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d vision_bias_radps_ = Eigen::Vector3d::Zero();
  bool initialized_ = false;
  std::int64_t t_ns_ = 0;
  bool velocity_aided_ = false;
  std::int64_t t_velocity_aided_ns_ = 0;
};

/// First-order low-pass of an N-vector with irregular dt: y += dt / (tau + dt) (x - y).
template <int N>
class LowPassFilter {
 public:
  using Vector = Eigen::Matrix<double, N, 1>;

  explicit LowPassFilter(double cutoff_hz = 20.0) : tau_s_(1.0 / (2.0 * M_PI * cutoff_hz)) {}

  FilterStatus update(std::int64_t t_ns, const Vector& x) {
    if (!x.allFinite()) return FilterStatus::kRejectedNonFinite;
    if (!initialized_) {
      y_ = x;
      t_ns_ = t_ns;
      initialized_ = true;
      return FilterStatus::kFirstSample;
    }
    const double dt_s = hq::to_seconds(t_ns - t_ns_);
    if (!(dt_s > 0.0)) return FilterStatus::kRejectedTime;
    y_ += dt_s / (tau_s_ + dt_s) * (x - y_);
    t_ns_ = t_ns;
    return FilterStatus::kOk;
  }

  [[nodiscard]] const Vector& value() const { return y_; }
  [[nodiscard]] bool initialized() const { return initialized_; }
  [[nodiscard]] std::int64_t t_ns() const { return t_ns_; }
  void reset() { initialized_ = false; }

 private:
  double tau_s_;
  bool initialized_ = false;
  std::int64_t t_ns_ = 0;
  Vector y_ = Vector::Zero();
};

}  // namespace hq::estimator
