#include "hq/estimator/velocity_estimator.hpp"

#include "hq/base/monotonic_clock.hpp"
#include "hq/config/strict_yaml.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace hq::estimator {
namespace {

using VelocityOutput = VelocityEstimatorConfig::VelocityOutput;

// A learnt unseen acceleration beyond this many unseen_accel_sigma_mps2 is no accelerometer's:
// the odometry that taught it was wrong.
constexpr double kUnseenAccelBoundSigmas = 3.0;
// The heading rate is singular at 90 deg of pitch, which no flying multirotor reaches.
constexpr double kMinCosPitch = 0.05;
// A landed vehicle's velocity is zero but for the frame's vibration and the floor's give.
constexpr double kRestVelocitySigmaMps = 0.01;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

}  // namespace

const char* to_string(EstimateStatus status) {
  switch (status) {
    case EstimateStatus::kOk:
      return "ok";
    case EstimateStatus::kInertial:
      return "inertial";
    case EstimateStatus::kUnavailable:
      break;
  }
  return "unavailable";
}

void read_config(config::StrictMap& section, VelocityEstimatorConfig& out) {
  config::StrictMap position = section.child("one_euro_position");
  read_config(position, out.one_euro_position);
  config::StrictMap rotation = section.child("one_euro_rotation");
  read_config(rotation, out.one_euro_rotation);
  config::StrictMap complementary = section.child("complementary");
  read_config(complementary, out.complementary);
  section.read_positive("gyro_cutoff_hz", out.gyro_cutoff_hz, 1000.0);
  section.read("min_valid_ratio", out.min_valid_ratio, 0.0, 1.0);
  section.read_positive("max_mean_error", out.max_mean_error, 65025.0);
  section.read_positive("max_frame_gap_s", out.max_frame_gap_s, 10.0);
  section.read_positive("max_imu_age_s", out.max_imu_age_s, 10.0);
  section.read("warmup_s", out.warmup_s, 0.0, 10.0);
  section.read("inertial_coast_s", out.inertial_coast_s, 0.0, 10.0);
  std::string output = out.velocity_output == VelocityOutput::kFused ? "fused" : "one_euro";
  section.read("velocity_output", output, {"fused", "one_euro"});
  out.velocity_output = output == "fused" ? VelocityOutput::kFused : VelocityOutput::kOneEuro;
  section.read_positive("vision_position_sigma_m", out.vision_position_sigma_m, 1.0);
  section.read_positive("accel_noise_density_mps2", out.accel_noise_density_mps2, 10.0);
  section.read_positive("velocity_gate_chi2", out.velocity_gate_chi2, 1e6);
  section.read("reacquire_frames", out.reacquire_frames, 1, 30);
  section.read("unseen_accel_sigma_mps2", out.unseen_accel_sigma_mps2, 0.0, 10.0);
  section.read("unseen_accel_random_walk", out.unseen_accel_random_walk, 0.0, 10.0);
  section.read_positive("coast_max_velocity_error_mps", out.coast_max_velocity_error_mps, 10.0);
  section.read("gyro_bias_from_odometry", out.gyro_bias_from_odometry);
  section.finish();
}

VelocityEstimator::VelocityEstimator(const VelocityEstimatorConfig& config,
                                     const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m)
    : config_(config),
      R_B_C_(R_B_C),
      p_B_C_m_(p_B_C_m),
      attitude_(config.complementary),
      gyro_low_pass_(config.gyro_cutoff_hz),
      pose_filter_(config.one_euro_position, config.one_euro_rotation) {}

void VelocityEstimator::reset() {
  attitude_.reset();
  gyro_low_pass_.reset();
  pose_filter_.reset();
  have_previous_ = false;
  agreeing_frames_ = 0;
  ever_ok_ = false;
  ever_updated_ = false;
  coast_anchored_ = false;
  coast_from_odometry_ = false;
  P_.setZero();
  lag_moment_H_.setZero();
  unseen_accel_H_mps2_.setZero();
  motion_accel_H_mps2_.setZero();
  coast_levelling_paused_ = false;
}

void VelocityEstimator::anchor_coast(std::int64_t t_ns, const Eigen::Vector3d& v_H_mps,
                                     bool from_odometry, const Eigen::Vector3d& v_H_raw_mps) {
  coast_anchored_ = true;
  t_coast_anchor_ns_ = t_ns;
  coast_horizon_at_anchor_s_ =
      horizon_for_unlearnt(std::sqrt(P_.bottomRightCorner<3, 3>().diagonal().maxCoeff()));
  t_coast_ns_ = attitude_.initialized() ? attitude_.t_ns() : t_ns;
  coast_v_H_mps_ = v_H_mps;
  coast_v_H_raw_mps_ = v_H_raw_mps;
  coast_from_odometry_ = from_odometry;
}

void VelocityEstimator::level_on_velocity(std::int64_t t_ns, const Eigen::Vector3d& v_H_raw_mps) {
  // Between two tracked frames the coast integrated the accelerometer levelled by the filter's
  // roll and pitch; what it missed of the velocity is, to first order, their tilt error. Eq.
  // 1's velocities, not the 1-euro filtered ones: the filter's lag (0.05-0.16 s) would read
  // every change of acceleration as a tilt.
  const double span_s = hq::to_seconds(t_ns - t_coast_anchor_ns_);
  if (coast_anchored_ && coast_from_odometry_ && span_s > 0.0 &&
      span_s <= config_.max_frame_gap_s) {
    attitude_.level_on_velocity(t_ns, (v_H_raw_mps - coast_v_H_raw_mps_) / span_s, span_s);
  }
}

double VelocityEstimator::coast_horizon_s() const {
  // A coast's length is set when it starts: the unseen acceleration's uncertainty still grows
  // during it, but that growth is what the horizon already allowed for.
  if (coast_anchored_) return coast_horizon_at_anchor_s_;
  return horizon_for_unlearnt(config_.unseen_accel_sigma_mps2);
}

double VelocityEstimator::horizon_for_unlearnt(double unlearnt_mps2) const {
  if (config_.unseen_accel_sigma_mps2 <= 0.0 || !(unlearnt_mps2 > 0.0)) {
    return config_.inertial_coast_s;
  }
  return std::min(config_.inertial_coast_s, config_.coast_max_velocity_error_mps / unlearnt_mps2);
}

void VelocityEstimator::hold_at_rest(std::int64_t t_ns) {
  if (!coast_anchored_) start_filter();
  motion_accel_H_mps2_.setZero();
  anchor_coast(t_ns, Eigen::Vector3d::Zero(), false, Eigen::Vector3d::Zero());
  // Known: the velocity, not the unseen acceleration (no odometry has checked it).
  P_.topLeftCorner<3, 3>() =
      kRestVelocitySigmaMps * kRestVelocitySigmaMps * Eigen::Matrix3d::Identity();
  P_.topRightCorner<3, 3>().setZero();
  P_.bottomLeftCorner<3, 3>().setZero();
}

void VelocityEstimator::start_filter() {
  P_.setZero();
  const double sigma_u = config_.unseen_accel_sigma_mps2;
  P_.bottomRightCorner<3, 3>() = sigma_u * sigma_u * Eigen::Matrix3d::Identity();
  unseen_accel_H_mps2_.setZero();
}

VelocityEstimate VelocityEstimator::between_frames(std::int64_t t_ns, const char* reason) {
  return unavailable(t_ns, reason);
}

FilterStatus VelocityEstimator::update_imu(std::int64_t t_ns, const Eigen::Vector3d& gyro_radps,
                                           const Eigen::Vector3d& accel_mps2) {
  // The accelerometer levels the attitude on gravity: what it reads of the vehicle's own
  // acceleration (the fused velocity's, as PX4's attitude estimator compensates with GPS
  // velocity) is taken out first, or every manoeuvre tilts the attitude.
  Eigen::Vector3d gravity_reading_mps2 = accel_mps2;
  if (attitude_.initialized() && accel_mps2.allFinite()) {
    gravity_reading_mps2 -=
        R_H_B_from_tilt(attitude_.roll_rad(), attitude_.pitch_rad()).transpose() *
        motion_accel_H_mps2_;
  }
  const FilterStatus status = attitude_.update(t_ns, gyro_radps, gravity_reading_mps2);
  if (!accepted(status)) return status;
  // omega_hat of Fig. 4: the low-passed gyro, with the complementary filter's bias removed.
  gyro_low_pass_.update(t_ns, gyro_radps - attitude_.gyro_bias_radps());
  if (have_previous_ && t_ns > t_prev_frame_ns_ && t_ns > t_lag_moment_ns_) {
    // The acceleration weighted by its time since the previous frame (velocity_at_frame_H).
    const double dt_s =
        std::min(hq::to_seconds(t_ns - std::max(t_lag_moment_ns_, t_prev_frame_ns_)),
                 config_.complementary.max_dt_s);
    const double since_frame_s = hq::to_seconds(t_ns - t_prev_frame_ns_);
    lag_moment_H_ += since_frame_s * dt_s * acceleration_H(accel_mps2);
    t_lag_moment_ns_ = t_ns;
  }
  if (coast_anchored_ && t_ns > t_coast_ns_) {
    // a_H = R_H_B f_B + g e_z (z down): specific force rotated with the filter's roll and pitch.
    const double dt_s =
        std::min(hq::to_seconds(t_ns - t_coast_ns_), config_.complementary.max_dt_s);
    const double roll_rad = attitude_.roll_rad();
    const double pitch_rad = attitude_.pitch_rad();
    const Eigen::Vector3d a_H = acceleration_H(accel_mps2);
    // H turns with the heading: a velocity fixed in the world turns the other way in H,
    // v_H' = Rz(d psi)^T v_H, with the Euler heading rate psi' = (q s_phi + r c_phi) / c_theta.
    const Eigen::Vector3d omega_B = gyro_radps - attitude_.gyro_bias_radps();
    const double heading_rate_radps =
        (omega_B.y() * std::sin(roll_rad) + omega_B.z() * std::cos(roll_rad)) /
        std::max(std::cos(pitch_rad), kMinCosPitch);
    const Eigen::AngleAxisd turn(-heading_rate_radps * dt_s, Eigen::Vector3d::UnitZ());
    coast_v_H_mps_ = turn * coast_v_H_mps_ + a_H * dt_s;
    coast_v_H_raw_mps_ = turn * coast_v_H_raw_mps_ + a_H * dt_s;
    // Held in H as the world's velocity would be: the next frame's acceleration is a change in
    // the world, not H's turn.
    v_H_fused_last_mps_ = turn * v_H_fused_last_mps_;
    propagate_covariance(turn.toRotationMatrix(), dt_s);
    t_coast_ns_ = t_ns;
  }
  return status;
}

VelocityEstimate VelocityEstimator::unavailable(std::int64_t t_ns, const char* reason) {
  // Without a frame taken nothing measures the motion's acceleration any more: held, the last
  // one tilted the attitude through a whole coast (8 deg in 1.9 s in the unseen campaign).
  // Nor may the accelerometer level on it: a coast keeps the attitude tracking gave it, which
  // carries what the accelerometer misses (a bias held level is a tilt).
  motion_accel_H_mps2_.setZero();
  if (coast_from_odometry_ && !coast_levelling_paused_) {
    attitude_.pause_levelling(t_coast_anchor_ns_);
    coast_levelling_paused_ = true;
  }
  VelocityEstimate estimate;
  estimate.t_ns = t_ns;
  estimate.status = EstimateStatus::kUnavailable;
  estimate.reason = reason;
  const std::int64_t since_ns = ever_ok_ ? t_last_ok_ns_ : t_first_update_ns_;
  estimate.unavailable_for_s = std::max(0.0, hq::to_seconds(t_ns - since_ns));
  if (attitude_.initialized()) {
    estimate.roll_rad = attitude_.roll_rad();
    estimate.pitch_rad = attitude_.pitch_rad();
  }
  const double coast_s = hq::to_seconds(t_ns - t_coast_anchor_ns_);
  const bool imu_fresh = attitude_.initialized() && gyro_low_pass_.initialized() &&
                         hq::to_seconds(t_ns - attitude_.t_ns()) <= config_.max_imu_age_s;
  if (coast_anchored_ && config_.inertial_coast_s > 0.0 && imu_fresh &&
      coast_s <= coast_horizon_s() && coast_v_H_mps_.allFinite()) {
    estimate.status = EstimateStatus::kInertial;
    estimate.v_H_mps = coast_v_H_mps_;
    estimate.v_B_mps =
        R_H_B_from_tilt(estimate.roll_rad, estimate.pitch_rad).transpose() * coast_v_H_mps_;
    estimate.v_H_covariance = P_.topLeftCorner<3, 3>();
    estimate.omega_B_radps = gyro_low_pass_.value();
  }
  return estimate;
}

void VelocityEstimator::reseed(std::int64_t t_ns, const Eigen::Isometry3d& T_O_Ck) {
  pose_filter_.reset();
  pose_filter_.update(t_ns, T_O_Ck);
  T_O_Ck_prev_filtered_ = pose_filter_.pose();
  T_O_Ck_prev_raw_ = T_O_Ck;
  have_previous_ = pose_filter_.initialized();
  t_prev_frame_ns_ = t_ns;
  t_seed_ns_ = t_ns;
  lag_moment_H_.setZero();
  t_lag_moment_ns_ = t_ns;
}

const char* VelocityEstimator::unusable_odometry(const odometry::OdometryResult& odometry) const {
  if (!odometry.ok()) return "odometry lost";
  if (odometry.valid_ratio < config_.min_valid_ratio) {
    return "odometry valid_ratio below min_valid_ratio";
  }
  if (!(odometry.mean_weighted_error <= config_.max_mean_error)) {
    return "odometry mean_weighted_error above max_mean_error";
  }
  if (!odometry.T_O_C.matrix().allFinite()) return "odometry pose not finite";
  return nullptr;
}

Eigen::Vector3d VelocityEstimator::raw_v_B(const Eigen::Isometry3d& T_raw, double dt_s,
                                           Eigen::Vector3d& v_C_raw_mps) const {
  // eq. 1 (raw, for evaluation): v_Ck = R_O_Ck^T (p_O_Ck - p_O_Ck-1) / dT.
  v_C_raw_mps =
      T_raw.linear().transpose() * (T_raw.translation() - T_O_Ck_prev_raw_.translation()) / dt_s;
  // The body's mean velocity over the same interval, in its frame at the end (what
  // level_on_velocity compares): over it the camera's lever arm swept (I - R_Bk_Bk-1) p_B_C, a
  // chord, not omega x p_B_C, which under a 1 rad/s yaw is 2 mm/s apart and reads as a tilt.
  const Eigen::Matrix3d R_Bk_B_prev =
      R_B_C_ * T_raw.linear().transpose() * T_O_Ck_prev_raw_.linear() * R_B_C_.transpose();
  return R_B_C_ * v_C_raw_mps - (Eigen::Matrix3d::Identity() - R_Bk_B_prev) * p_B_C_m_ / dt_s;
}

Eigen::Vector3d VelocityEstimator::acceleration_H(const Eigen::Vector3d& accel_mps2) const {
  // a_H = R_H_B f_B + g e_z (z down): specific force rotated with the filter's roll and pitch,
  // and what the accelerometer misses, as learnt.
  return R_H_B_from_tilt(attitude_.roll_rad(), attitude_.pitch_rad()) * accel_mps2 +
         Eigen::Vector3d(0.0, 0.0, kGravityMps2) + unseen_accel_H_mps2_;
}

Eigen::Vector3d VelocityEstimator::velocity_at_frame_H(const Eigen::Vector3d& v_H_mean_mps,
                                                       double dt_s) const {
  return v_H_mean_mps + lag_moment_H_ / dt_s;
}

Eigen::Matrix3d VelocityEstimator::measurement_covariance_H(
    const odometry::OdometryResult& odometry, double dt_s) const {
  const double sigma_m = config_.vision_position_sigma_m;
  Eigen::Matrix3d position_C = sigma_m * sigma_m * Eigen::Matrix3d::Identity();
  // The odometry's own translation covariance (marginal, of T_ref_cur's twist): it only says
  // more than the floor along directions the view hardly constrains.
  const Eigen::LDLT<odometry::Matrix6d> information(odometry.information);
  if (information.info() == Eigen::Success && information.isPositive() &&
      odometry.information.allFinite() && odometry.information.diagonal().minCoeff() > 0.0) {
    const odometry::Matrix6d covariance = information.solve(odometry::Matrix6d::Identity());
    if (covariance.allFinite()) {
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(
          covariance.topLeftCorner<3, 3>().eval());
      const Eigen::Vector3d floored = eigen.eigenvalues().cwiseMax(sigma_m * sigma_m);
      position_C = eigen.eigenvectors() * floored.asDiagonal() * eigen.eigenvectors().transpose();
    }
  }
  // Two poses' errors over dt, turned into H.
  const Eigen::Matrix3d R_H_C =
      R_H_B_from_tilt(attitude_.roll_rad(), attitude_.pitch_rad()) * R_B_C_;
  return 2.0 / (dt_s * dt_s) * R_H_C * position_C * R_H_C.transpose();
}

void VelocityEstimator::propagate_covariance(const Eigen::Matrix3d& R_turn, double dt_s) {
  // v' = R_turn v + (a + u) dt, u' = u: F = [R_turn, dt I; 0, I].
  Matrix6d F = Matrix6d::Identity();
  F.topLeftCorner<3, 3>() = R_turn;
  F.topRightCorner<3, 3>() = dt_s * Eigen::Matrix3d::Identity();
  P_ = F * P_ * F.transpose();
  // The accelerometer's white noise on the velocity; the unseen acceleration's random walk.
  const double q_a = config_.accel_noise_density_mps2;
  P_.diagonal().head<3>().array() += q_a * q_a * dt_s;
  if (config_.unseen_accel_sigma_mps2 > 0.0) {
    const double q_u = config_.unseen_accel_random_walk;
    P_.diagonal().tail<3>().array() += q_u * q_u * dt_s;
  }
}

double VelocityEstimator::innovation_chi2(const Eigen::Vector3d& z_H_mps,
                                          const Eigen::Matrix3d& R_H) const {
  if (!coast_anchored_ || !attitude_.initialized()) return 0.0;
  const Eigen::Vector3d innovation = z_H_mps - coast_v_H_mps_;
  const Eigen::Matrix3d S = P_.topLeftCorner<3, 3>() + R_H;
  return innovation.dot(S.ldlt().solve(innovation));
}

void VelocityEstimator::fuse(const Eigen::Vector3d& z_H_mps, const Eigen::Matrix3d& R_H) {
  if (!coast_anchored_) {
    start_filter();
    coast_v_H_mps_ = z_H_mps;
    P_.topLeftCorner<3, 3>() = R_H;
    return;
  }
  // Kalman update with H = [I 0]: K = P H^T S^-1 = P.leftCols<3>() S^-1.
  const Eigen::Matrix3d S = P_.topLeftCorner<3, 3>() + R_H;
  const Eigen::Matrix<double, 6, 3> PHt = P_.leftCols<3>();
  const Eigen::Matrix<double, 6, 3> K = S.ldlt().solve(PHt.transpose()).transpose();
  const Eigen::Vector3d innovation = z_H_mps - coast_v_H_mps_;
  const Eigen::Matrix<double, 6, 1> correction = K * innovation;
  coast_v_H_mps_ += correction.head<3>();
  const Matrix6d P = P_ - K * PHt.transpose();
  P_ = 0.5 * (P + P.transpose());
  if (config_.unseen_accel_sigma_mps2 <= 0.0) return;
  unseen_accel_H_mps2_ += correction.tail<3>();
  const double bound_mps2 = kUnseenAccelBoundSigmas * config_.unseen_accel_sigma_mps2;
  const double learnt_mps2 = unseen_accel_H_mps2_.norm();
  if (learnt_mps2 > bound_mps2) unseen_accel_H_mps2_ *= bound_mps2 / learnt_mps2;
}

VelocityEstimate VelocityEstimator::update(std::int64_t t_ns,
                                           const odometry::OdometryResult& odometry) {
  if (!ever_updated_) {
    ever_updated_ = true;
    t_first_update_ns_ = t_ns;
  }
  // Any return before the gate has passed breaks the run of agreeing frames.
  const int agreed_before = agreeing_frames_;
  agreeing_frames_ = 0;
  if (odometry.status == odometry::TrackingStatus::kFirstFrame) {
    // A new odometry reference: the pose chain restarts, so no velocity across it.
    reseed(t_ns, odometry.T_O_C);
    return unavailable(t_ns, "first odometry frame");
  }
  if (const char* reason = unusable_odometry(odometry)) {
    have_previous_ = false;
    return unavailable(t_ns, reason);
  }
  const double dt_s = hq::to_seconds(t_ns - t_prev_frame_ns_);
  if (!have_previous_ || dt_s > config_.max_frame_gap_s) {
    // Eq. 2 needs two consecutive accepted poses.
    reseed(t_ns, odometry.T_O_C);
    return unavailable(t_ns, "waiting for a second accepted odometry frame");
  }
  if (!(dt_s > 0.0)) return unavailable(t_ns, "odometry stamp not after the previous frame");
  VelocityEstimate estimate;
  estimate.t_ns = t_ns;
  const Eigen::Isometry3d& T_raw = odometry.T_O_C;
  const Eigen::Vector3d v_B_raw = raw_v_B(T_raw, dt_s, estimate.v_C_raw_mps);
  const bool have_attitude = attitude_.initialized() && gyro_low_pass_.initialized();
  // The gate, before the 1-euro filter sees the pose: wrong frames rejected only after it still
  // dragged it. A rejected pose restarts the filter instead.
  const Eigen::Matrix3d R_H = measurement_covariance_H(odometry, dt_s);
  const Eigen::Vector3d v_H_mean_raw =
      R_H_B_from_tilt(attitude_.roll_rad(), attitude_.pitch_rad()) * v_B_raw;
  const Eigen::Vector3d z_H = velocity_at_frame_H(v_H_mean_raw, dt_s);
  estimate.innovation_chi2 = have_attitude ? innovation_chi2(z_H, R_H) : 0.0;
  if (estimate.innovation_chi2 > config_.velocity_gate_chi2) {
    reseed(t_ns, T_raw);
    VelocityEstimate rejected = unavailable(t_ns, "odometry velocity disagrees with the IMU");
    rejected.v_C_raw_mps = estimate.v_C_raw_mps;
    rejected.innovation_chi2 = estimate.innovation_chi2;
    return rejected;
  }
  if (!accepted(pose_filter_.update(t_ns, odometry.T_O_C))) {
    return unavailable(t_ns, "odometry pose rejected by the pose filter");
  }
  // eq. 2 of the core paper, not eq. 1: differentiating the 1€-filtered pose keeps noise out of v.
  const Eigen::Isometry3d& T_hat = pose_filter_.pose();
  const Eigen::Vector3d v_C = T_hat.linear().transpose() *
                              (T_hat.translation() - T_O_Ck_prev_filtered_.translation()) / dt_s;
  estimate.v_C_mps = v_C;
  T_O_Ck_prev_filtered_ = T_hat;
  T_O_Ck_prev_raw_ = T_raw;
  t_prev_frame_ns_ = t_ns;
  lag_moment_H_.setZero();
  t_lag_moment_ns_ = t_ns;
  const bool one_euro_output = config_.velocity_output == VelocityOutput::kOneEuro;
  const bool warming_up = hq::to_seconds(t_ns - t_seed_ns_) < config_.warmup_s;
  if (one_euro_output && warming_up) {
    return unavailable(t_ns, "pose filter warming up after a (re)start");
  }
  if (!have_attitude) return unavailable(t_ns, "no IMU sample yet");
  if (hq::to_seconds(t_ns - attitude_.t_ns()) > config_.max_imu_age_s) {
    return unavailable(t_ns, "IMU samples too old");
  }
  const Eigen::Vector3d& omega_B = gyro_low_pass_.value();
  // eq. 4: Q_v_Q = R_QC Ck_v_Ck - Q_omega_Q x Q_p_C, i.e. v_B = R_B_C v_C - omega_B x p_B_C
  // (removes the lever-arm velocity of the camera's centre).
  const Eigen::Vector3d v_B_one_euro = R_B_C_ * v_C - omega_B.cross(p_B_C_m_);
  const double roll_rad = attitude_.roll_rad();
  const double pitch_rad = attitude_.pitch_rad();
  // eq. 5: H_v_Q = R_HQ Q_v_Q, i.e. v_H = R_H_B v_B with R_H_B = Ry(theta) Rx(phi).
  const Eigen::Matrix3d R_H_B = R_H_B_from_tilt(roll_rad, pitch_rad);
  if (!warming_up) estimate.v_H_one_euro_mps = R_H_B * v_B_one_euro;
  agreeing_frames_ = std::min(agreed_before + 1, config_.reacquire_frames);
  if (agreeing_frames_ < config_.reacquire_frames) {
    return unavailable(t_ns, "odometry re-acquired, waiting for the next frame to agree");
  }
  take_frame(t_ns, z_H, R_H, v_H_mean_raw, odometry.gyro_bias_radps);
  estimate.status = EstimateStatus::kOk;
  estimate.reason = "";
  if (one_euro_output) {
    estimate.v_H_mps = estimate.v_H_one_euro_mps;
    estimate.v_B_mps = v_B_one_euro;
    estimate.v_H_covariance = R_H;
  } else {
    estimate.v_H_mps = coast_v_H_mps_;
    estimate.v_B_mps = R_H_B.transpose() * coast_v_H_mps_;
    estimate.v_H_covariance = P_.topLeftCorner<3, 3>();
  }
  estimate.omega_B_radps = omega_B;
  estimate.roll_rad = roll_rad;
  estimate.pitch_rad = pitch_rad;
  estimate.unavailable_for_s = 0.0;
  return estimate;
}

void VelocityEstimator::take_frame(std::int64_t t_ns, const Eigen::Vector3d& z_H_mps,
                                   const Eigen::Matrix3d& R_H,
                                   const Eigen::Vector3d& v_H_mean_raw_mps,
                                   const Eigen::Vector3d& gyro_bias_C_radps) {
  const bool had_filter = coast_anchored_ && t_coast_anchor_ns_ < t_ns;
  const double since_anchor_s = hq::to_seconds(t_ns - t_coast_anchor_ns_);
  fuse(z_H_mps, R_H);
  motion_accel_H_mps2_.setZero();
  if (had_filter && coast_from_odometry_ && since_anchor_s <= config_.max_frame_gap_s) {
    // The fused velocity's change since the last frame it took.
    motion_accel_H_mps2_ = (coast_v_H_mps_ - v_H_fused_last_mps_) / since_anchor_s;
  }
  v_H_fused_last_mps_ = coast_v_H_mps_;
  ever_ok_ = true;
  t_last_ok_ns_ = t_ns;
  // The odometry's bias is the rest after the levelling's (OnboardChain removes that one from
  // the gyro it gives the odometry); taken from accepted frames only.
  if (config_.gyro_bias_from_odometry) {
    attitude_.set_vision_gyro_bias(R_B_C_ * gyro_bias_C_radps);
  }
  level_on_velocity(t_ns, v_H_mean_raw_mps);
  anchor_coast(t_ns, coast_v_H_mps_, true, v_H_mean_raw_mps);
  coast_levelling_paused_ = false;
}

}  // namespace hq::estimator
