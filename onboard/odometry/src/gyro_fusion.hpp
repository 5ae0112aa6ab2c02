#pragma once
// The gyro in the alignment (private to hq_odometry): the rotation prior's mean and
// information from the gyro rotations given to track(), the residual rate bias learnt from the
// vision's own rotation against them, and (adapt_vision_information) the vision's honest scale.

#include "hq/odometry/dense_odometry.hpp"

#include "normal_equations.hpp"
#include <Eigen/Geometry>

#include <cstdint>

namespace hq::odometry::detail {

/// The residual rate bias of the gyro rotations given to track() (camera axes, rad/s): a random
/// walk, observed each frame through the vision-only rotation against the gyro's.
class GyroBiasFilter {
 public:
  void reset(double initial_sigma_radps);
  /// The random walk up to t_ns.
  void propagate(std::int64_t t_ns, double random_walk);
  /// innovation: the observed bias minus the estimate (rad/s), with its noise covariance.
  /// Returns false, leaving the estimate, for a non-finite or gated observation.
  bool update(const Eigen::Vector3d& innovation, const Eigen::Matrix3d& noise, double gate_chi2);

  [[nodiscard]] const Eigen::Vector3d& bias() const { return bias_; }
  [[nodiscard]] const Eigen::Matrix3d& covariance() const { return covariance_; }

 private:
  Eigen::Vector3d bias_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance_ = Eigen::Matrix3d::Zero();
  std::int64_t t_ns_ = -1;
};

/// The gyro rotations since the reference, chained with the bias estimate removed: the
/// rotation prior's mean (frame to keyframe as frame to frame). Independent of the vision,
/// unlike the last estimate times the gyro step, whose error is the same keyframe's vision
/// error again and would be counted twice. A frame without a gyro step breaks the chain until
/// the next reference.
struct GyroChain {
  Eigen::Matrix3d R_ref_cur = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d noise_covariance = Eigen::Matrix3d::Zero();  // white noise, reference axes
  double span_s = 0.0;
  bool intact = true;
};

/// This frame's gyro: its step since the previous frame and the chain since the reference, bias
/// estimate removed, each with its covariance (white noise plus the bias still unknown).
struct GyroSteps {
  Eigen::Matrix3d R_prev_cur = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d step_covariance = Eigen::Matrix3d::Zero();   // current axes, rad^2
  GyroChain chain;                                             // extended by the step
  Eigen::Matrix3d chain_covariance = Eigen::Matrix3d::Zero();  // reference axes, rad^2
};

/// What one alignment that used the gyro prior says about the gyro and about the vision: the
/// vision's own minimum near it (Aligner::vision_only()), against the gyro chain's rotation.
/// One Gauss-Newton step of the data term from the joint minimum would be cheaper but goes
/// about half the way: the Student-t reweighted Hessian overstates the robust cost's curvature
/// there.
struct GyroObservation {
  Eigen::Vector3d bias_innovation = Eigen::Vector3d::Zero();    // rad/s, camera axes
  Eigen::Matrix3d vision_covariance = Eigen::Matrix3d::Zero();  // independent pixels, ditto
  Eigen::Matrix3d gyro_covariance = Eigen::Matrix3d::Zero();    // the chain's white noise
  double span_s = 0.0;
  double overconfidence = 1.0;  // this frame's sample of 1 / the vision's honest scale
};

/// The inverse of a covariance, symmetrised against rounding.
Eigen::Matrix3d symmetric_inverse(const Eigen::Matrix3d& covariance);

class GyroFusion {
 public:
  explicit GyroFusion(const OdometryConfig& config);

  /// Forgets the bias estimate, the learnt scale and the chain.
  void reset();
  /// A new reference starts a new chain.
  void restart_chain() { chain_ = GyroChain{}; }
  /// After a frame against the same reference: its steps extend the chain (or, without a
  /// gyro step, break it until the next reference).
  void keep_chain(const GyroSteps* steps);

  /// The bias estimate's random walk up to the frame at t_ns (when it is estimated).
  void propagate(std::int64_t t_ns);

  /// The gyro of a frame step_s after the previous one, bias estimate removed. False for a
  /// prior without rotation information (R_depth_colour alone), one that is not finite or
  /// positive definite, no interval, or a chain broken since the reference.
  bool steps(const RotationPrior& prior, double step_s, GyroSteps& out) const;

  /// A covariance's prior information in the data term's units (its normal equations carry
  /// the independent-pixel information): divided by the vision's honest scale.
  [[nodiscard]] Eigen::Matrix3d prior_information(const Eigen::Matrix3d& covariance) const;

  /// What the vision alignment T_cur_ref_vision with its normal equations says against the
  /// gyro chain, whose rotation R_ref_prior was the prior. False when either side cannot say.
  bool observe(const Eigen::Isometry3d& T_cur_ref_vision, const NormalEquations& vision_normal,
               const Eigen::Matrix3d& R_ref_prior, const GyroSteps& gyro,
               GyroObservation& out) const;

  /// Learns from a gyro observation of a frame that tracked: the vision's honest scale from
  /// every such frame, and (learn_bias) the gyro bias.
  void learn(const GyroObservation& o, bool learn_bias);

  [[nodiscard]] const Eigen::Vector3d& bias() const { return bias_.bias(); }
  /// The data term's honest share of its independent-pixel information.
  [[nodiscard]] double vision_scale() const { return vision_scale_; }

 private:
  const OdometryConfig& config_;
  GyroBiasFilter bias_;
  GyroChain chain_;  // up to the last accepted frame
  // The configured vision_information_scale, then (adapt_vision_information) as the gyro
  // observes it.
  double vision_scale_ = 1.0;
  int vision_scale_samples_ = 0;
  double log_overconfidence_ = 0.0;  // running mean of the samples' logs
};

}  // namespace hq::odometry::detail
