#include "hq/navigation/navigation_filter.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/estimator/velocity_estimator.hpp"
#include "hq/geometry/lie.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>

namespace hq::navigation {
namespace {

using geometry::exp_so3;
using geometry::hat;
using geometry::log_so3;
using Matrix3d = Eigen::Matrix3d;
using Vector3d = Eigen::Vector3d;

constexpr double kNsPerS = 1e9;
/// A marker rotation further than this from orthonormal is a broken input, not noise.
constexpr double kMaxRotationDefect = 1e-3;
/// Below this |cos(pitch)| the yaw Jacobian is clamped (the vehicle never flies there).
constexpr double kMinCosPitch = 1e-3;

double seconds(std::int64_t dt_ns) { return static_cast<double>(dt_ns) / kNsPerS; }

bool is_finite(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

bool nominal_finite(const NominalState& s) {
  return s.p_W_m.allFinite() && s.v_W_mps.allFinite() && s.q_W_B.coeffs().allFinite() &&
         s.gyro_bias_radps.allFinite() && s.accel_bias_mps2.allFinite();
}

/// Symmetric positive definite within what LLT can tell.
template <int kDim>
bool positive_definite(const Eigen::Matrix<double, kDim, kDim>& M) {
  if (!M.allFinite() || !M.isApprox(M.transpose(), 1e-9)) return false;
  const Eigen::LLT<Eigen::Matrix<double, kDim, kDim>> llt(M);
  return llt.info() == Eigen::Success;
}

/// R_meas projected back onto SO(3), or false if it is far from a rotation.
bool clean_rotation(const Matrix3d& R, Matrix3d& out) {
  if ((R.transpose() * R - Matrix3d::Identity()).cwiseAbs().maxCoeff() > kMaxRotationDefect ||
      R.determinant() < 0.0) {
    return false;
  }
  out = geometry::orthonormalize(R);
  return true;
}

Matrix3d rot_z(double psi) { return Eigen::AngleAxisd(psi, Vector3d::UnitZ()).toRotationMatrix(); }

}  // namespace

void read_config(config::StrictMap& section, NavigationConfig& out) {
  section.read_positive("gyro_noise_density_radps_rthz", out.gyro_noise_density_radps_rthz, 1.0);
  section.read_positive("gyro_bias_walk_radps2_rthz", out.gyro_bias_walk_radps2_rthz, 1.0);
  section.read_positive("accel_noise_density_mps2_rthz", out.accel_noise_density_mps2_rthz, 10.0);
  section.read_positive("accel_bias_walk_mps3_rthz", out.accel_bias_walk_mps3_rthz, 10.0);
  section.read("gravity_mps2", out.gravity_mps2, 9.7, 9.9);
  section.read_positive("initial_position_sigma_m", out.initial_position_sigma_m, 100.0);
  section.read_positive("initial_velocity_sigma_mps", out.initial_velocity_sigma_mps, 10.0);
  section.read_deg_as_rad("initial_attitude_sigma_deg", out.initial_attitude_sigma_rad, 1e-6, 30.0);
  section.read_positive("initial_gyro_bias_sigma_radps", out.initial_gyro_bias_sigma_radps, 1.0);
  section.read_positive("initial_accel_bias_sigma_mps2", out.initial_accel_bias_sigma_mps2, 5.0);
  section.read_positive("velocity_sigma_mps", out.velocity_sigma_mps, 10.0);
  section.read_positive("marker_gate_chi2", out.marker_gate_chi2, 1e6);
  section.read_positive("velocity_gate_chi2", out.velocity_gate_chi2, 1e6);
  section.read_positive("max_measurement_age_s", out.max_measurement_age_s, 10.0);
  section.read_positive("degraded_after_s", out.degraded_after_s, 600.0);
  section.read("reanchor_after_gated_markers", out.reanchor_after_gated_markers, 0, 1000);
  section.read_positive("position_max_age_s", out.position_max_age_s, 600.0);
  section.read_positive("position_max_sigma_m", out.position_max_sigma_m, 100.0);
  section.read("position_inconsistent_after_frames", out.position_inconsistent_after_frames, 1,
               1000);
  section.read("position_inconsistent_after_velocities", out.position_inconsistent_after_velocities,
               1, 100000);
  section.finish();
}

NavigationConfig load_navigation_config(const std::string& path) {
  const YAML::Node root = config::load_yaml_file(path);
  if (!root.IsMap() || !root["navigation"]) {
    throw InputError(path + ": navigation section missing, expected a `navigation:` mapping");
  }
  config::StrictMap section(root["navigation"], path, "navigation");
  NavigationConfig out;
  read_config(section, out);
  return out;
}

double yaw_rad(const Matrix3d& R_W_B) { return std::atan2(R_W_B(1, 0), R_W_B(0, 0)); }

Matrix3d R_W_H(const Matrix3d& R_W_B) { return rot_z(yaw_rad(R_W_B)); }

Eigen::Matrix<double, 6, kErrorStateSize> marker_jacobian(const NominalState& state,
                                                          const Matrix3d& R_B_C,
                                                          const Vector3d& p_B_C_m) {
  // p_WC = p_WB + R_WB p_BC and R_WC = R_WB R_BC with R_WB = R̂ Exp(dtheta):
  // dp_WC = dp - R̂ [p_BC]x dtheta;  log(R̂_WCᵀ R_WC) = R_BCᵀ dtheta.
  const Matrix3d R = state.q_W_B.toRotationMatrix();
  Eigen::Matrix<double, 6, kErrorStateSize> H = Eigen::Matrix<double, 6, kErrorStateSize>::Zero();
  H.block<3, 3>(0, kIndexPosition).setIdentity();
  H.block<3, 3>(0, kIndexAttitude) = -R * hat(p_B_C_m);
  H.block<3, 3>(3, kIndexAttitude) = R_B_C.transpose();
  return H;
}

Vector3d predict_velocity_horizontal(const NominalState& state) {
  // eq. 5 of the core paper with the whole rotation: H_v = R_WHᵀ W_v.
  return R_W_H(state.q_W_B.toRotationMatrix()).transpose() * state.v_W_mps;
}

Eigen::Matrix<double, 3, kErrorStateSize> velocity_jacobian(const NominalState& state) {
  const Matrix3d R = state.q_W_B.toRotationMatrix();
  const double psi = yaw_rad(R);
  const double pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  const double cos_pitch = std::max(std::cos(pitch), kMinCosPitch);
  const double tan_pitch = std::sin(pitch) / cos_pitch;
  const Matrix3d R_WH_T = rot_z(psi).transpose();
  const Vector3d h = R_WH_T * state.v_W_mps;
  // ZYX Euler kinematics: psi_dot = (s_theta c_psi w_x + s_theta s_psi w_y) / c_theta + w_z for a
  // world-frame rate w; a local error dtheta is the world rotation R̂ dtheta.
  const Eigen::RowVector3d d_psi_d_theta_W(tan_pitch * std::cos(psi), tan_pitch * std::sin(psi),
                                           1.0);
  const Eigen::RowVector3d d_psi_d_dtheta = d_psi_d_theta_W * R;
  // d(Rz(psi)ᵀ v)/d psi = -e_z x (Rz(psi)ᵀ v).
  const Vector3d d_h_d_psi = -Vector3d::UnitZ().cross(h);
  Eigen::Matrix<double, 3, kErrorStateSize> H = Eigen::Matrix<double, 3, kErrorStateSize>::Zero();
  H.block<3, 3>(0, kIndexVelocity) = R_WH_T;
  H.block<3, 3>(0, kIndexAttitude) = d_h_d_psi * d_psi_d_dtheta;
  return H;
}

NavigationFilter::NavigationFilter(const NavigationConfig& config, const Eigen::Isometry3d& T_B_C)
    : config_(config), R_B_C_(T_B_C.linear()), p_B_C_m_(T_B_C.translation()) {}

UpdateResult NavigationFilter::reject(const char* reason) {
  ++counters_.inputs_rejected;
  counters_.last_reason = reason;
  return UpdateResult{UpdateStatus::kRejected, reason, 0.0};
}

UpdateResult NavigationFilter::initialize(std::int64_t t_ns, const NominalState& state) {
  if (!nominal_finite(state)) return reject("non-finite initial state");
  state_ = state;
  state_.q_W_B.normalize();
  P_.setZero();
  const auto set_block = [this](int index, double sigma) {
    P_.block<3, 3>(index, index) = Matrix3d::Identity() * sigma * sigma;
  };
  set_block(kIndexPosition, config_.initial_position_sigma_m);
  set_block(kIndexVelocity, config_.initial_velocity_sigma_mps);
  set_block(kIndexAttitude, config_.initial_attitude_sigma_rad);
  set_block(kIndexGyroBias, config_.initial_gyro_bias_sigma_radps);
  set_block(kIndexAccelBias, config_.initial_accel_bias_sigma_mps2);
  t_ns_ = t_ns;
  t_last_marker_ns_ = t_ns;
  initialized_ = true;
  have_imu_ = false;
  counters_.anchored = false;
  consecutive_gated_markers_ = 0;
  t_marker_frame_ns_ = -1;
  frame_accepted_ = false;
  frame_gated_ = false;
  disagreeing_frames_ = 0;
  consecutive_gated_velocities_ = 0;
  return UpdateResult{UpdateStatus::kAccepted, "initialised", 0.0};
}

UpdateResult NavigationFilter::anchor_to_marker(std::int64_t t_ns, const Eigen::Isometry3d& T_W_C,
                                                const Matrix6d& covariance) {
  if (!is_finite(T_W_C)) return reject("non-finite marker pose");
  if (!positive_definite<6>(covariance)) return reject("marker covariance not positive definite");
  Matrix3d R_WC;
  if (!clean_rotation(T_W_C.linear(), R_WC)) return reject("marker rotation not a rotation");
  if (initialized_) {
    const UpdateResult stamp = check_stamp(t_ns);
    if (!stamp.accepted()) return reject(stamp.reason);
  } else {
    NominalState start;
    start.q_W_B = Eigen::Quaterniond(R_WC * R_B_C_.transpose());
    start.p_W_m = T_W_C.translation() - R_WC * R_B_C_.transpose() * p_B_C_m_;
    initialize(t_ns, start);
  }
  const Matrix3d R_old = state_.q_W_B.toRotationMatrix();
  const Vector3d v_H = R_W_H(R_old).transpose() * state_.v_W_mps;
  const Matrix3d R_new = R_WC * R_B_C_.transpose();
  // Bumpless: the velocity keeps its H coordinates, so it turns with the new yaw.
  const Matrix3d R_WH_new = R_W_H(R_new);
  const Matrix3d R_turn = R_WH_new * R_W_H(R_old).transpose();
  state_.q_W_B = Eigen::Quaterniond(R_new).normalized();
  state_.p_W_m = T_W_C.translation() - R_new * p_B_C_m_;
  state_.v_W_mps = R_WH_new * v_H;

  // Pose error of the body from the camera's: dtheta_B = R_BC dtheta_C,
  // dp_B = dp_C + R̂ [p_BC]x dtheta_B; pose blocks decorrelated from the rest.
  Matrix6d A = Matrix6d::Zero();
  A.block<3, 3>(0, 0).setIdentity();
  A.block<3, 3>(0, 3) = R_new * hat(p_B_C_m_) * R_B_C_;
  A.block<3, 3>(3, 3) = R_B_C_;
  const Matrix6d pose_cov = A * covariance * A.transpose();
  ErrorCovariance P_new = ErrorCovariance::Zero();
  // Velocity rows turn with the yaw; biases are untouched.
  Eigen::Matrix<double, kErrorStateSize, kErrorStateSize> T_turn =
      Eigen::Matrix<double, kErrorStateSize, kErrorStateSize>::Identity();
  T_turn.block<3, 3>(kIndexVelocity, kIndexVelocity) = R_turn;
  P_new = T_turn * P_ * T_turn.transpose();
  P_new.block<6, kErrorStateSize>(kIndexPosition, 0).setZero();
  P_new.block<kErrorStateSize, 6>(0, kIndexPosition).setZero();
  P_new.block<3, kErrorStateSize>(kIndexAttitude, 0).setZero();
  P_new.block<kErrorStateSize, 3>(0, kIndexAttitude).setZero();
  P_new.block<3, 3>(kIndexPosition, kIndexPosition) = pose_cov.block<3, 3>(0, 0);
  P_new.block<3, 3>(kIndexPosition, kIndexAttitude) = pose_cov.block<3, 3>(0, 3);
  P_new.block<3, 3>(kIndexAttitude, kIndexPosition) = pose_cov.block<3, 3>(3, 0);
  P_new.block<3, 3>(kIndexAttitude, kIndexAttitude) = pose_cov.block<3, 3>(3, 3);
  P_ = 0.5 * (P_new + P_new.transpose());
  counters_.anchored = true;
  ++counters_.reanchors;
  t_last_marker_ns_ = t_ns_;
  consecutive_gated_markers_ = 0;
  note_marker_outcome(t_ns, true);
  ++counters_.markers_accepted;
  return UpdateResult{UpdateStatus::kAccepted, "anchored on marker", 0.0};
}

UpdateResult NavigationFilter::predict(std::int64_t t_ns, const Vector3d& gyro_radps,
                                       const Vector3d& accel_mps2) {
  if (!initialized_) return reject("not initialised");
  if (!gyro_radps.allFinite() || !accel_mps2.allFinite()) return reject("non-finite IMU sample");
  if (have_imu_ && t_ns <= t_ns_) return reject("non-increasing IMU stamp");
  if (!have_imu_) {
    // The first sample only fixes the interval start (its stamp may precede initialize's).
    have_imu_ = true;
    t_ns_ = std::max(t_ns_, t_ns);
    gyro_prev_radps_ = gyro_radps;
    accel_prev_mps2_ = accel_mps2;
    ++counters_.imu_samples;
    return UpdateResult{UpdateStatus::kAccepted, "first IMU sample", 0.0};
  }
  const double dt = seconds(t_ns - t_ns_);
  // Mean of the two samples bounding the interval; biases removed.
  const Vector3d omega = 0.5 * (gyro_prev_radps_ + gyro_radps) - state_.gyro_bias_radps;
  const Vector3d f = 0.5 * (accel_prev_mps2_ + accel_mps2) - state_.accel_bias_mps2;
  const Matrix3d R0 = state_.q_W_B.toRotationMatrix();
  const Matrix3d delta_R = exp_so3(omega * dt);
  const Matrix3d R_mid = R0 * exp_so3(0.5 * dt * omega);
  const Vector3d a_W = R_mid * f + Vector3d(0.0, 0.0, config_.gravity_mps2);

  state_.p_W_m += state_.v_W_mps * dt + 0.5 * a_W * dt * dt;
  state_.v_W_mps += a_W * dt;
  state_.q_W_B = Eigen::Quaterniond(R0 * delta_R).normalized();

  // Error dynamics (local attitude error, Solà 2017 §5.3.3), first order in dt.
  ErrorCovariance F = ErrorCovariance::Identity();
  F.block<3, 3>(kIndexPosition, kIndexVelocity) = Matrix3d::Identity() * dt;
  F.block<3, 3>(kIndexVelocity, kIndexAttitude) = -R_mid * hat(f) * dt;
  F.block<3, 3>(kIndexVelocity, kIndexAccelBias) = -R_mid * dt;
  F.block<3, 3>(kIndexAttitude, kIndexAttitude) = delta_R.transpose();
  F.block<3, 3>(kIndexAttitude, kIndexGyroBias) = -Matrix3d::Identity() * dt;
  ErrorCovariance P_next = F * P_ * F.transpose();
  const auto add_noise = [&P_next, dt](int index, double density) {
    P_next.block<3, 3>(index, index).diagonal().array() += density * density * dt;
  };
  add_noise(kIndexVelocity, config_.accel_noise_density_mps2_rthz);
  add_noise(kIndexAttitude, config_.gyro_noise_density_radps_rthz);
  add_noise(kIndexGyroBias, config_.gyro_bias_walk_radps2_rthz);
  add_noise(kIndexAccelBias, config_.accel_bias_walk_mps3_rthz);
  P_ = 0.5 * (P_next + P_next.transpose());

  t_ns_ = t_ns;
  gyro_prev_radps_ = gyro_radps;
  accel_prev_mps2_ = accel_mps2;
  ++counters_.imu_samples;
  return UpdateResult{UpdateStatus::kAccepted, "predicted", 0.0};
}

UpdateResult NavigationFilter::check_stamp(std::int64_t t_ns) const {
  if (!initialized_) return UpdateResult{UpdateStatus::kRejected, "not initialised", 0.0};
  if (std::abs(seconds(t_ns - t_ns_)) > config_.max_measurement_age_s) {
    return UpdateResult{UpdateStatus::kRejected, "measurement stamp too far from the state's", 0.0};
  }
  return UpdateResult{UpdateStatus::kAccepted, "", 0.0};
}

template <int kDim>
UpdateResult NavigationFilter::correct(const Eigen::Matrix<double, kDim, 1>& residual,
                                       const Eigen::Matrix<double, kDim, kErrorStateSize>& H,
                                       const Eigen::Matrix<double, kDim, kDim>& R,
                                       double gate_chi2) {
  using MatrixD = Eigen::Matrix<double, kDim, kDim>;
  const MatrixD S = H * P_ * H.transpose() + R;
  const Eigen::LLT<MatrixD> llt(S);
  if (llt.info() != Eigen::Success) return reject("innovation covariance not positive definite");
  const double nis = residual.dot(llt.solve(residual));
  if (!std::isfinite(nis)) return reject("non-finite innovation");
  if (nis > gate_chi2) {
    counters_.last_reason = "Mahalanobis gate";
    return UpdateResult{UpdateStatus::kGated, "Mahalanobis gate", nis};
  }
  // K = P Hᵀ S⁻¹, computed as (S⁻¹ H P)ᵀ since S and P are symmetric.
  const Eigen::Matrix<double, kErrorStateSize, kDim> K = llt.solve(H * P_).transpose();
  const Eigen::Matrix<double, kErrorStateSize, 1> dx = K * residual;
  // Joseph form keeps P positive semi-definite under rounding and suboptimal gains.
  const ErrorCovariance I_KH = ErrorCovariance::Identity() - K * H;
  ErrorCovariance P_new = I_KH * P_ * I_KH.transpose() + K * R * K.transpose();

  NominalState next = state_;
  next.p_W_m += dx.template segment<3>(kIndexPosition);
  next.v_W_mps += dx.template segment<3>(kIndexVelocity);
  const Vector3d dtheta = dx.template segment<3>(kIndexAttitude);
  next.q_W_B = Eigen::Quaterniond(next.q_W_B.toRotationMatrix() * exp_so3(dtheta)).normalized();
  next.gyro_bias_radps += dx.template segment<3>(kIndexGyroBias);
  next.accel_bias_mps2 += dx.template segment<3>(kIndexAccelBias);
  // Reset of the error state: dtheta+ = dtheta - dtheta_hat, whose Jacobian for the attitude
  // block is I - [dtheta_hat/2]x (Solà 2017 §6.3).
  ErrorCovariance G = ErrorCovariance::Identity();
  G.block<3, 3>(kIndexAttitude, kIndexAttitude) -= 0.5 * hat(dtheta);
  P_new = G * P_new * G.transpose();
  P_new = 0.5 * (P_new + P_new.transpose());
  if (!nominal_finite(next) || !P_new.allFinite())
    return reject("update produced non-finite state");
  state_ = next;
  P_ = P_new;
  return UpdateResult{UpdateStatus::kAccepted, "updated", nis};
}

UpdateResult NavigationFilter::update_marker(std::int64_t t_ns, const Eigen::Isometry3d& T_W_C,
                                             const Matrix6d& covariance) {
  if (!initialized_ || !counters_.anchored) {
    return anchor_to_marker(t_ns, T_W_C, covariance);
  }
  if (!is_finite(T_W_C)) return reject("non-finite marker pose");
  if (!positive_definite<6>(covariance)) return reject("marker covariance not positive definite");
  Matrix3d R_meas;
  if (!clean_rotation(T_W_C.linear(), R_meas)) {
    return reject("marker rotation not a rotation");
  }
  const UpdateResult stamp = check_stamp(t_ns);
  if (!stamp.accepted()) return reject(stamp.reason);

  const Matrix3d R_WB = state_.q_W_B.toRotationMatrix();
  const Matrix3d R_WC_pred = R_WB * R_B_C_;
  const Vector3d p_WC_pred = state_.p_W_m + R_WB * p_B_C_m_;
  Eigen::Matrix<double, 6, 1> residual;
  residual.head<3>() = T_W_C.translation() - p_WC_pred;
  residual.tail<3>() = log_so3(geometry::orthonormalize(R_WC_pred.transpose() * R_meas));
  const UpdateResult result = correct<6>(residual, marker_jacobian(state_, R_B_C_, p_B_C_m_),
                                         covariance, config_.marker_gate_chi2);
  last_marker_nis_ = result.nis;
  if (result.status == UpdateStatus::kGated) {
    note_marker_outcome(t_ns, false);
    ++counters_.markers_gated;
    ++consecutive_gated_markers_;
    if (config_.reanchor_after_gated_markers > 0 &&
        consecutive_gated_markers_ >= config_.reanchor_after_gated_markers) {
      // Consistently gated markers: the filter has diverged from the map; trust the map.
      return anchor_to_marker(t_ns, T_W_C, covariance);
    }
    return result;
  }
  if (result.accepted()) {
    note_marker_outcome(t_ns, true);
    ++counters_.markers_accepted;
    consecutive_gated_markers_ = 0;
    t_last_marker_ns_ = t_ns_;
  }
  return result;
}

UpdateResult NavigationFilter::update_velocity(std::int64_t t_ns, const Vector3d& v_H_mps,
                                               const Matrix3d& covariance) {
  if (!v_H_mps.allFinite()) return reject("non-finite velocity");
  if (!positive_definite<3>(covariance)) {
    return reject("velocity covariance not positive definite");
  }
  const UpdateResult stamp = check_stamp(t_ns);
  if (!stamp.accepted()) return reject(stamp.reason);
  const Vector3d residual = v_H_mps - predict_velocity_horizontal(state_);
  const UpdateResult result =
      correct<3>(residual, velocity_jacobian(state_), covariance, config_.velocity_gate_chi2);
  if (result.status == UpdateStatus::kGated) {
    ++counters_.velocities_gated;
    ++consecutive_gated_velocities_;
  }
  if (result.accepted()) {
    ++counters_.velocities_accepted;
    consecutive_gated_velocities_ = 0;
  }
  return result;
}

UpdateResult NavigationFilter::update_velocity(const estimator::VelocityEstimate& estimate) {
  if (!estimate.ok()) return reject("velocity estimate unavailable");
  const double variance = config_.velocity_sigma_mps * config_.velocity_sigma_mps;
  return update_velocity(estimate.t_ns, estimate.v_H_mps, Matrix3d::Identity() * variance);
}

void NavigationFilter::note_marker_outcome(std::int64_t t_ns, bool accepted) {
  // One frame brings several markers (one stamp); a frame disagrees when none of its markers
  // passed the gate. A far marker of a frame gated beside accepted ones is no disagreement.
  if (t_ns != t_marker_frame_ns_) {
    if (frame_accepted_) {
      disagreeing_frames_ = 0;
    } else if (frame_gated_) {
      ++disagreeing_frames_;
    }
    t_marker_frame_ns_ = t_ns;
    frame_accepted_ = false;
    frame_gated_ = false;
  }
  (accepted ? frame_accepted_ : frame_gated_) = true;
}

int NavigationFilter::disagreeing_marker_frames() const {
  if (frame_accepted_) return 0;
  return disagreeing_frames_ + (frame_gated_ ? 1 : 0);
}

PositionCheck NavigationFilter::check_position(std::int64_t t_now_ns) const {
  PositionCheck check;
  const Eigen::Matrix2d P_xy = P_.block<2, 2>(kIndexPosition, kIndexPosition);
  check.sigma_horizontal_m = std::sqrt(std::max(0.0, P_xy.trace()));
  if (!initialized_ || !counters_.anchored) {
    check.reason = PositionInvalid::kNotAnchored;
    return check;
  }
  check.age_s = seconds(std::max(t_now_ns, t_ns_) - t_last_marker_ns_);
  if (!(check.age_s <= config_.position_max_age_s)) {
    check.reason = PositionInvalid::kNoMarker;
  } else if (!(check.sigma_horizontal_m <= config_.position_max_sigma_m)) {
    // NaN fails here too: a broken covariance is never a valid pose.
    check.reason = PositionInvalid::kCovarianceOverBound;
  } else if (disagreeing_marker_frames() >= config_.position_inconsistent_after_frames ||
             consecutive_gated_velocities_ >= config_.position_inconsistent_after_velocities) {
    check.reason = PositionInvalid::kInnovationInconsistent;
  } else {
    check.valid = true;
    check.reason = PositionInvalid::kNone;
  }
  return check;
}

NavigationHealth NavigationFilter::health() const {
  NavigationHealth health = counters_;
  health.disagreeing_marker_frames = disagreeing_marker_frames();
  health.consecutive_gated_velocities = consecutive_gated_velocities_;
  health.last_marker_nis = last_marker_nis_;
  health.initialized = initialized_;
  health.position_sigma_m = std::sqrt(P_.block<3, 3>(kIndexPosition, kIndexPosition).trace());
  health.time_since_marker_s = initialized_ ? seconds(t_ns_ - t_last_marker_ns_) : 0.0;
  health.degraded = !initialized_ || !counters_.anchored ||
                    health.time_since_marker_s >= config_.degraded_after_s;
  return health;
}

Eigen::Isometry3d NavigationFilter::T_W_B() const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = state_.q_W_B.toRotationMatrix();
  T.translation() = state_.p_W_m;
  return T;
}

Vector3d NavigationFilter::v_H_mps() const { return predict_velocity_horizontal(state_); }

const char* to_string(PositionInvalid reason) {
  switch (reason) {
    case PositionInvalid::kNone:
      return "valid";
    case PositionInvalid::kNotAnchored:
      return "no marker seen yet";
    case PositionInvalid::kNoMarker:
      return "no marker";
    case PositionInvalid::kCovarianceOverBound:
      return "position uncertainty over bound";
    case PositionInvalid::kInnovationInconsistent:
      return "markers or velocity disagree with the estimate";
  }
  return "unknown";
}

const char* to_string(UpdateStatus status) {
  switch (status) {
    case UpdateStatus::kAccepted:
      return "accepted";
    case UpdateStatus::kGated:
      return "gated";
    case UpdateStatus::kRejected:
      return "rejected";
  }
  return "unknown";
}

}  // namespace hq::navigation
