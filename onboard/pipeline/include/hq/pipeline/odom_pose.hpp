#pragma once
/// The vehicle's integrated pose in a world-fixed odometry frame "odom" (ROS REP 105): where the
/// vehicle is relative to where the chain started, by dead reckoning, never jumping.
///
/// odom is NED-like and fixed to the world: its origin is the body's position when the chain
/// started, x along the heading the body had then, y right, z down. The position integrates
/// the estimate's velocity v_H (eq. 5, horizontal frame H) turned into odom by the yaw of H in
/// odom, which integrates the gyro's yaw rate in H. Nothing measures the heading (no compass), so
/// the yaw is relative to the start: yaw_relative_to_start is always true here, and a ROS
/// consumer must treat the world heading as unknown.
///
/// Uncertainty (1-sigma), grown, never shrunk (nothing observes the position):
///   yaw:      + yaw_drift_radps x dt (what is left of the gyro's yaw bias)
///   position: a random part, the estimator's velocity noise (its covariance, horizontal
///             trace) integrated as noise correlated over velocity_error_correlation_s
///             (variance + 2 tau sigma_v^2 dt), plus a systematic part summed linearly:
///             (velocity_error_fraction + sigma_yaw) |v| dt while the estimate is usable (a
///             scale error, and the yaw's error turning the path), and blind_drift_mps dt
///             while airborne with no usable estimate (the safe hover drifts at an unknown
///             speed; the position stands still then).
/// On the floor (landed) the velocity is known to be zero: the position neither moves nor grows
/// (the yaw integrates the gyro always).
///
/// With the marker stage anchored, the marker filter's pose p_W/yaw_W (VehicleState.p_W_m)
/// is absolute in the map frame W; the odom pose goes on independently, so map -> odom is
/// T_W_B x T_odom_B^-1 (it changes as the odometry drifts; ROS's map -> odom transform).

#include "hq/estimator/velocity_estimator.hpp"

#include <Eigen/Core>

#include <cstdint>

namespace hq::pipeline {

struct OdomPoseConfig {
  /// Growth of the yaw's 1-sigma (rad/s): the gyro bias left on the yaw axis, which the
  /// levelling cannot see (odometry.gyro_bias_sigma_radps before the odometry estimates it).
  double yaw_drift_radps = 0.005;
  /// The velocity's error as a fraction of speed on top of the estimator's own sigma (scale
  /// error of the depth, the odometry's bias under motion).
  double velocity_error_fraction = 0.05;
  /// Correlation time of the estimator's velocity error (s): its filter's memory.
  double velocity_error_correlation_s = 0.5;
  /// How fast the position may drift while airborne without a usable estimate (m/s).
  double blind_drift_mps = 0.5;
};

struct OdomPoseEstimate {
  bool valid = false;  ///< False until the first step with a usable estimate or on the floor.
  Eigen::Vector3d p_odom_m = Eigen::Vector3d::Zero();  ///< Body origin in odom (NED-like).
  double yaw_rad = 0.0;                                ///< Yaw of H in odom (FRD yaw, NED sense).
  double position_sigma_m = 0.0;                       ///< Horizontal 1-sigma of p_odom_m.
  double yaw_sigma_rad = 0.0;                          ///< 1-sigma of yaw_rad.
  bool yaw_relative_to_start = true;                   ///< No absolute heading: see above.
};

class OdomPose {
 public:
  explicit OdomPose(const OdomPoseConfig& config = {}) : config_(config) {}

  /// The gyro's yaw rate about H's z (rad/s, NED sense: positive turns right), bias removed
  /// (the attitude filter's whole bias, yaw included: the odometry measures it),
  /// at IMU rate. Non-finite rates are ignored (the yaw stands, its sigma grows on).
  void on_yaw_rate(std::int64_t t_ns, double yaw_rate_H_radps);
  /// One chain output's estimate: integrates it (or grows the blind drift) since the last call.
  /// `landed`: the vehicle stands on the floor (velocity zero, nothing grows).
  const OdomPoseEstimate& on_estimate(std::int64_t t_ns, const estimator::VelocityEstimate& estimate,
                                      bool landed);

  [[nodiscard]] const OdomPoseEstimate& pose() const { return pose_; }

 private:
  OdomPoseConfig config_;
  OdomPoseEstimate pose_;
  std::int64_t t_yaw_ns_ = -1;
  std::int64_t t_position_ns_ = -1;
  double random_variance_m2_ = 0.0;  ///< The position's random part (m^2).
  double systematic_m_ = 0.0;        ///< The position's systematic part (m).
};

}  // namespace hq::pipeline
