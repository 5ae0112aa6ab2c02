#include "gyro_fusion.hpp"

#include "hq/geometry/lie.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>

namespace hq::odometry::detail {

namespace {

// The range of one frame's sample of the vision's overconfidence (adapt_vision_information),
// averaged in the log domain. A consistent vision's samples are chi-square(3) / 3, below 0.01
// with probability 5e-4: the floor keeps the samples where the gyro's own uncertainty exceeds
// the disagreement (the moment estimate is then negative) from dominating the average, the
// ceiling bounds a frame where vision slipped. Not tuning values.
constexpr double kMinOverconfidenceSample = 0.01;
constexpr double kMaxOverconfidenceSample = 1e6;

}  // namespace

void GyroBiasFilter::reset(double initial_sigma_radps) {
  bias_.setZero();
  covariance_ = Eigen::Matrix3d::Identity() * initial_sigma_radps * initial_sigma_radps;
  t_ns_ = -1;
}

void GyroBiasFilter::propagate(std::int64_t t_ns, double random_walk) {
  if (t_ns_ >= 0 && t_ns > t_ns_) {
    const double dt_s = 1e-9 * static_cast<double>(t_ns - t_ns_);
    covariance_.diagonal().array() += random_walk * random_walk * dt_s;
  }
  t_ns_ = t_ns;
}

bool GyroBiasFilter::update(const Eigen::Vector3d& innovation, const Eigen::Matrix3d& noise,
                            double gate_chi2) {
  const Eigen::Matrix3d S = covariance_ + noise;
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(S);
  if (!innovation.allFinite() || !S.allFinite() || ldlt.info() != Eigen::Success ||
      !ldlt.isPositive()) {
    return false;
  }
  if (innovation.dot(ldlt.solve(innovation)) > gate_chi2) return false;
  const Eigen::Matrix3d gain = ldlt.solve(covariance_).transpose();  // P S^-1, S symmetric
  bias_ += gain * innovation;
  const Eigen::Matrix3d updated = (Eigen::Matrix3d::Identity() - gain) * covariance_;
  covariance_ = 0.5 * (updated + updated.transpose());
  return true;
}

Eigen::Matrix3d symmetric_inverse(const Eigen::Matrix3d& covariance) {
  const Eigen::Matrix3d inverse = covariance.inverse();
  return 0.5 * (inverse + inverse.transpose());
}

GyroFusion::GyroFusion(const OdometryConfig& config) : config_(config) { reset(); }

void GyroFusion::reset() {
  chain_ = GyroChain{};
  bias_.reset(config_.gyro_bias_sigma_radps);
  vision_scale_ = config_.vision_information_scale;
  vision_scale_samples_ = 0;
  log_overconfidence_ = 0.0;
}

void GyroFusion::keep_chain(const GyroSteps* steps) {
  if (steps != nullptr) {
    chain_ = steps->chain;
  } else {
    chain_.intact = false;
  }
}

void GyroFusion::propagate(std::int64_t t_ns) {
  if (config_.estimate_gyro_bias) bias_.propagate(t_ns, config_.gyro_bias_random_walk);
}

// The bias still unknown adds P_b dt^2 to a step and, being the same in every step,
// R P_b R^T span^2 to the chain.
bool GyroFusion::steps(const RotationPrior& prior, double step_s, GyroSteps& out) const {
  if (prior.information.isZero()) return false;  // R_depth_colour alone
  const Eigen::LDLT<Eigen::Matrix3d> information(prior.information);
  if (!prior.R_prev_cur.allFinite() || !prior.information.allFinite() || step_s <= 0.0 ||
      information.info() != Eigen::Success || !information.isPositive()) {
    return false;
  }
  const Eigen::Matrix3d noise = information.solve(Eigen::Matrix3d::Identity());
  if (!noise.allFinite()) return false;
  out.R_prev_cur = prior.R_prev_cur * geometry::exp_so3(-bias_.bias() * step_s);
  out.step_covariance = noise + bias_.covariance() * step_s * step_s;
  out.chain = chain_;
  out.chain.R_ref_cur = chain_.R_ref_cur * out.R_prev_cur;
  const Eigen::Matrix3d& R = out.chain.R_ref_cur;
  out.chain.noise_covariance += R * noise * R.transpose();
  out.chain.span_s += step_s;
  out.chain_covariance = out.chain.noise_covariance + R * bias_.covariance() * R.transpose() *
                                                          out.chain.span_s * out.chain.span_s;
  return out.chain.intact;
}

Eigen::Matrix3d GyroFusion::prior_information(const Eigen::Matrix3d& covariance) const {
  // Weighing the prior against the honest scale x of the data term equals dividing the prior
  // by x: one 3x3 here instead of rescaling every iteration's 6x6 (and the costs stay in the
  // data term's units).
  const double prior_weight = config_.rotation_prior_information_scale / vision_scale_;
  return prior_weight * symmetric_inverse(covariance);
}

bool GyroFusion::observe(const Eigen::Isometry3d& T_cur_ref_vision,
                         const NormalEquations& vision_normal, const Eigen::Matrix3d& R_ref_prior,
                         const GyroSteps& gyro, GyroObservation& out) const {
  const Matrix6d H =
      independent_pixel_information(vision_normal, config_.estimate_brightness_offset);
  const Eigen::LDLT<Matrix6d> data(H);
  if (gyro.chain.span_s <= 0.0 || data.info() != Eigen::Success || !data.isPositive()) {
    return false;
  }
  // Reference axes: R_vision = exp(e) R_chain. A bias left over, b - b_estimate in camera
  // axes, turns the chain by about R (b - b_estimate) span.
  const Eigen::Vector3d e =
      geometry::log_so3(T_cur_ref_vision.linear().transpose() * R_ref_prior.transpose());
  const Eigen::Matrix3d vision_covariance =
      data.solve(Matrix6d::Identity()).bottomRightCorner<3, 3>();
  const Eigen::LDLT<Eigen::Matrix3d> vision(vision_covariance);
  if (!e.allFinite() || vision.info() != Eigen::Success || !vision.isPositive()) return false;
  // E[e e^T] = k C + G for vision overconfident by k: the moment estimate of k from this
  // frame, k = (e^T C^-1 e - tr(C^-1 G)) / 3. A consistent vision's samples scatter below 1
  // as often as above, so they are only kept in range here; the scale is bounded once
  // averaged (no better than independent pixels).
  const double k = (e.dot(vision.solve(e)) - vision.solve(gyro.chain_covariance).trace()) / 3.0;
  out.overconfidence = std::clamp(k, kMinOverconfidenceSample, kMaxOverconfidenceSample);
  const Eigen::Matrix3d& R = gyro.chain.R_ref_cur;
  out.span_s = gyro.chain.span_s;
  out.bias_innovation = -R.transpose() * e / out.span_s;
  out.vision_covariance = R.transpose() * vision_covariance * R;
  out.gyro_covariance = R.transpose() * gyro.chain.noise_covariance * R;
  return out.bias_innovation.allFinite() && std::isfinite(out.overconfidence);
}

// The scale is a running geometric mean of the frames' samples (one frame where vision
// slipped moves it by a factor, not a multiple) over the last vision_information_frames; the
// configured scale holds until the first sample. The bias learns from the last frame against
// each reference only: the observations within one keyframe share its vision and chain
// errors, so only one of them is independent.
void GyroFusion::learn(const GyroObservation& o, bool learn_bias) {
  if (config_.adapt_vision_information) {
    vision_scale_samples_ = std::min(vision_scale_samples_ + 1, config_.vision_information_frames);
    const double alpha = 1.0 / vision_scale_samples_;
    log_overconfidence_ = (1.0 - alpha) * log_overconfidence_ + alpha * std::log(o.overconfidence);
    // A consistent vision's samples are chi-square(3) / 3, whose log has mean
    // psi(3/2) + ln(2/3) = -0.369: the geometric mean is 0.69 of the mean.
    constexpr double kChiSquare3GeometricMean = 0.6915;
    vision_scale_ = std::min(1.0, kChiSquare3GeometricMean / std::exp(log_overconfidence_));
  }
  // Frame to frame the vision's own per-step rotation error is a drift, as constant as a
  // bias and indistinguishable from one (measured in simulation: f2f with the depth term
  // learnt its 0.2 deg/s drift as the gyro's bias); against a keyframe it is bounded, so
  // learn_bias is the last frame against each keyframe only.
  if (learn_bias) {
    // Weighed with the scale that includes this frame: the first frames of a vision far
    // more overconfident than the configured scale must not teach the bias its error.
    const Eigen::Matrix3d noise =
        (o.vision_covariance / vision_scale_ + o.gyro_covariance) / (o.span_s * o.span_s);
    bias_.update(o.bias_innovation, noise, config_.gyro_bias_gate_chi2);
  }
}

}  // namespace hq::odometry::detail
