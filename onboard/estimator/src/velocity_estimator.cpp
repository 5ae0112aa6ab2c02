#include "hq/estimator/velocity_estimator.hpp"

#include "hq/config/strict_yaml.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace hq::estimator {
namespace {

// A learnt unseen acceleration beyond this many unseen_accel_sigma_mps2 is no accelerometer's:
// the odometry that taught it was wrong.
constexpr double kUnseenAccelBoundSigmas = 3.0;
// The heading rate is singular at 90 deg of pitch, which no flying multirotor reaches.
constexpr double kMinCosPitch = 0.05;

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
  section.read_positive("max_imu_disagreement_mps", out.max_imu_disagreement_mps, 100.0);
  section.read("imu_disagreement_growth_mps2", out.imu_disagreement_growth_mps2, 0.0, 100.0);
  section.read("reacquire_frames", out.reacquire_frames, 1, 30);
  section.read("unseen_accel_time_constant_s", out.unseen_accel_time_constant_s, 0.0, 600.0);
  section.read("unseen_accel_sigma_mps2", out.unseen_accel_sigma_mps2, 0.0, 10.0);
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
  unseen_accel_H_mps2_.setZero();
  unseen_accel_learnt_s_ = 0.0;
}

void VelocityEstimator::anchor_coast(std::int64_t t_ns, const Eigen::Vector3d& v_H_mps,
                                     bool from_odometry, const Eigen::Vector3d& v_H_raw_mps) {
  coast_anchored_ = config_.inertial_coast_s > 0.0;
  t_coast_anchor_ns_ = t_ns;
  t_coast_ns_ = attitude_.initialized() ? attitude_.t_ns() : t_ns;
  coast_v_H_mps_ = v_H_mps;
  coast_v_H_raw_mps_ = v_H_raw_mps;
  coast_from_odometry_ = from_odometry;
}

void VelocityEstimator::learn_unseen_accel(std::int64_t t_ns, const Eigen::Vector3d& v_H_raw_mps) {
  // Only between two tracked frames: the coast then predicted this frame's velocity from the
  // last one's with the accelerometer and what it has learnt, and the rest is what it missed.
  // Eq. 1's velocities, as level_on_velocity's: under a 1 rad/s yaw the 1-euro filter's lag
  // turns with H and taught 0.01 m/s^2 the accelerometer did not miss.
  const double span_s = 1e-9 * static_cast<double>(t_ns - t_coast_anchor_ns_);
  if (config_.unseen_accel_time_constant_s <= 0.0 || !coast_anchored_ || !coast_from_odometry_ ||
      !(span_s > 0.0) || span_s > config_.max_frame_gap_s) {
    return;
  }
  // The coast already added what was learnt: this frame's sample is that plus its miss.
  const Eigen::Vector3d missed_mps2 =
      (v_H_raw_mps - coast_v_H_raw_mps_) / span_s + unseen_accel_H_mps2_;
  if (!missed_mps2.allFinite()) return;
  unseen_accel_H_mps2_ += span_s / (config_.unseen_accel_time_constant_s + span_s) *
                          (missed_mps2 - unseen_accel_H_mps2_);
  unseen_accel_learnt_s_ += span_s;
  const double bound_mps2 = kUnseenAccelBoundSigmas * config_.unseen_accel_sigma_mps2;
  const double learnt_mps2 = unseen_accel_H_mps2_.norm();
  if (config_.unseen_accel_sigma_mps2 > 0.0 && learnt_mps2 > bound_mps2) {
    unseen_accel_H_mps2_ *= bound_mps2 / learnt_mps2;
  }
}

void VelocityEstimator::level_on_velocity(std::int64_t t_ns, const Eigen::Vector3d& v_H_raw_mps) {
  // Between two tracked frames the coast integrated the accelerometer levelled by the filter's
  // roll and pitch; what it missed of the velocity is, to first order, their tilt error. Eq.
  // 1's velocities, not the 1-euro filtered ones: the filter's lag (0.05-0.16 s) would read
  // every change of acceleration as a tilt.
  const double span_s = 1e-9 * static_cast<double>(t_ns - t_coast_anchor_ns_);
  if (coast_anchored_ && coast_from_odometry_ && span_s > 0.0 &&
      span_s <= config_.max_frame_gap_s) {
    attitude_.level_on_velocity(t_ns, (v_H_raw_mps - coast_v_H_raw_mps_) / span_s, span_s);
  }
}

double VelocityEstimator::coast_horizon_s() const {
  if (config_.unseen_accel_sigma_mps2 <= 0.0) return config_.inertial_coast_s;
  // The low-pass has learnt all but exp(-t / tau) of a constant unseen acceleration.
  const double unlearnt_share =
      config_.unseen_accel_time_constant_s > 0.0
          ? std::exp(-unseen_accel_learnt_s_ / config_.unseen_accel_time_constant_s)
          : 1.0;
  const double unlearnt_mps2 = config_.unseen_accel_sigma_mps2 * unlearnt_share;
  return std::min(config_.inertial_coast_s, config_.coast_max_velocity_error_mps / unlearnt_mps2);
}

double VelocityEstimator::imu_gate_mps(std::int64_t t_ns) const {
  const double coast_s = std::max(0.0, 1e-9 * static_cast<double>(t_ns - t_coast_anchor_ns_));
  return config_.max_imu_disagreement_mps + config_.imu_disagreement_growth_mps2 * coast_s;
}

void VelocityEstimator::hold_at_rest(std::int64_t t_ns) {
  anchor_coast(t_ns, Eigen::Vector3d::Zero(), false, Eigen::Vector3d::Zero());
}

VelocityEstimate VelocityEstimator::between_frames(std::int64_t t_ns, const char* reason) {
  return unavailable(t_ns, reason);
}

FilterStatus VelocityEstimator::update_imu(std::int64_t t_ns, const Eigen::Vector3d& gyro_radps,
                                           const Eigen::Vector3d& accel_mps2) {
  const FilterStatus status = attitude_.update(t_ns, gyro_radps, accel_mps2);
  if (!accepted(status)) return status;
  // omega_hat of Fig. 4: the low-passed gyro, with the complementary filter's bias removed.
  gyro_low_pass_.update(t_ns, gyro_radps - attitude_.gyro_bias_radps());
  if (coast_anchored_ && t_ns > t_coast_ns_) {
    // a_H = R_H_B f_B + g e_z (z down): specific force rotated with the filter's roll and pitch.
    const double dt_s =
        std::min(1e-9 * static_cast<double>(t_ns - t_coast_ns_), config_.complementary.max_dt_s);
    const double roll_rad = attitude_.roll_rad();
    const double pitch_rad = attitude_.pitch_rad();
    const Eigen::Vector3d a_H = R_horizontal_body(roll_rad, pitch_rad) * accel_mps2 +
                                Eigen::Vector3d(0.0, 0.0, kGravityMps2) + unseen_accel_H_mps2_;
    // H turns with the heading: a velocity fixed in the world turns the other way in H,
    // v_H' = Rz(d psi)^T v_H, with the Euler heading rate psi' = (q s_phi + r c_phi) / c_theta.
    const Eigen::Vector3d omega_B = gyro_radps - attitude_.gyro_bias_radps();
    const double heading_rate_radps =
        (omega_B.y() * std::sin(roll_rad) + omega_B.z() * std::cos(roll_rad)) /
        std::max(std::cos(pitch_rad), kMinCosPitch);
    const Eigen::AngleAxisd turn(-heading_rate_radps * dt_s, Eigen::Vector3d::UnitZ());
    coast_v_H_mps_ = turn * coast_v_H_mps_ + a_H * dt_s;
    coast_v_H_raw_mps_ = turn * coast_v_H_raw_mps_ + a_H * dt_s;
    t_coast_ns_ = t_ns;
  }
  return status;
}

VelocityEstimate VelocityEstimator::unavailable(std::int64_t t_ns, const char* reason) {
  VelocityEstimate estimate;
  estimate.t_ns = t_ns;
  estimate.status = EstimateStatus::kUnavailable;
  estimate.reason = reason;
  const std::int64_t since_ns = ever_ok_ ? t_last_ok_ns_ : t_first_update_ns_;
  estimate.unavailable_for_s = std::max(0.0, 1e-9 * static_cast<double>(t_ns - since_ns));
  if (attitude_.initialized()) {
    estimate.roll_rad = attitude_.roll_rad();
    estimate.pitch_rad = attitude_.pitch_rad();
  }
  const double coast_s = 1e-9 * static_cast<double>(t_ns - t_coast_anchor_ns_);
  const bool imu_fresh =
      attitude_.initialized() && gyro_low_pass_.initialized() &&
      1e-9 * static_cast<double>(t_ns - attitude_.t_ns()) <= config_.max_imu_age_s;
  if (coast_anchored_ && imu_fresh && coast_s <= coast_horizon_s() && coast_v_H_mps_.allFinite()) {
    estimate.status = EstimateStatus::kInertial;
    estimate.v_H_mps = coast_v_H_mps_;
    estimate.omega_body_radps = gyro_low_pass_.value();
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

Eigen::Vector3d VelocityEstimator::raw_body_velocity(const Eigen::Isometry3d& T_raw, double dt_s,
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

bool VelocityEstimator::raw_velocity_disagrees_with_the_imu(std::int64_t t_ns,
                                                            const Eigen::Vector3d& v_B_raw) const {
  if (!coast_anchored_ || !attitude_.initialized()) return false;
  const Eigen::Vector3d v_H_raw =
      R_horizontal_body(attitude_.roll_rad(), attitude_.pitch_rad()) * v_B_raw;
  return (v_H_raw - coast_v_H_raw_mps_).norm() > imu_gate_mps(t_ns);
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

  const double dt_s = 1e-9 * static_cast<double>(t_ns - t_prev_frame_ns_);
  if (!have_previous_ || dt_s > config_.max_frame_gap_s) {
    // Eq. 2 needs two consecutive accepted poses.
    reseed(t_ns, odometry.T_O_C);
    return unavailable(t_ns, "waiting for a second accepted odometry frame");
  }
  if (!(dt_s > 0.0)) return unavailable(t_ns, "odometry stamp not after the previous frame");

  VelocityEstimate estimate;
  estimate.t_ns = t_ns;
  const Eigen::Isometry3d& T_raw = odometry.T_O_C;
  const Eigen::Vector3d v_B_raw = raw_body_velocity(T_raw, dt_s, estimate.v_C_raw_mps);
  // The gate, on eq. 1's velocity before the 1-euro filter sees the pose: a run of wrong frames
  // rejected only after filtering still dragged the filter, and the first right frame after it
  // carried half their error through the gate (README "Re-acquired twice"). A rejected pose
  // restarts the filter instead, warm-up included; the warm-up's frames are checked too.
  if (raw_velocity_disagrees_with_the_imu(t_ns, v_B_raw)) {
    reseed(t_ns, T_raw);
    return unavailable(t_ns, "odometry velocity disagrees with the IMU");
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

  if (1e-9 * static_cast<double>(t_ns - t_seed_ns_) < config_.warmup_s) {
    return unavailable(t_ns, "pose filter warming up after a (re)start");
  }
  if (!attitude_.initialized() || !gyro_low_pass_.initialized()) {
    return unavailable(t_ns, "no IMU sample yet");
  }
  if (1e-9 * static_cast<double>(t_ns - attitude_.t_ns()) > config_.max_imu_age_s) {
    return unavailable(t_ns, "IMU samples too old");
  }
  const Eigen::Vector3d& omega_B = gyro_low_pass_.value();
  // eq. 4: Q_v_Q = R_QC Ck_v_Ck - Q_omega_Q x Q_p_C, i.e. v_B = R_B_C v_C - omega_B x p_B_C
  // (removes the lever-arm velocity of the camera's centre).
  const Eigen::Vector3d v_B = R_B_C_ * v_C - omega_B.cross(p_B_C_m_);
  const double roll_rad = attitude_.roll_rad();
  const double pitch_rad = attitude_.pitch_rad();
  // eq. 5: H_v_Q = R_HQ Q_v_Q, i.e. v_H = R_H_B v_B with R_H_B = Ry(theta) Rx(phi).
  const Eigen::Vector3d v_H = R_horizontal_body(roll_rad, pitch_rad) * v_B;

  if (coast_anchored_ && (v_H - coast_v_H_mps_).norm() > imu_gate_mps(t_ns)) {
    return unavailable(t_ns, "odometry velocity disagrees with the IMU");
  }
  agreeing_frames_ = std::min(agreed_before + 1, config_.reacquire_frames);
  if (agreeing_frames_ < config_.reacquire_frames) {
    return unavailable(t_ns, "odometry re-acquired, waiting for the next frame to agree");
  }
  estimate.status = EstimateStatus::kOk;
  estimate.reason = "";
  estimate.v_B_mps = v_B;
  estimate.v_H_mps = v_H;
  estimate.omega_body_radps = omega_B;
  estimate.roll_rad = roll_rad;
  estimate.pitch_rad = pitch_rad;
  estimate.unavailable_for_s = 0.0;
  ever_ok_ = true;
  t_last_ok_ns_ = t_ns;
  // The odometry's bias is the rest after the levelling's (OnboardChain removes that one from
  // the gyro it gives the odometry); taken from accepted frames only.
  if (config_.gyro_bias_from_odometry) {
    attitude_.set_vision_gyro_bias(R_B_C_ * odometry.gyro_bias_radps);
  }
  const Eigen::Vector3d v_H_raw = R_horizontal_body(roll_rad, pitch_rad) * v_B_raw;
  level_on_velocity(t_ns, v_H_raw);
  learn_unseen_accel(t_ns, v_H_raw);
  anchor_coast(t_ns, v_H, true, v_H_raw);
  return estimate;
}

}  // namespace hq::estimator
