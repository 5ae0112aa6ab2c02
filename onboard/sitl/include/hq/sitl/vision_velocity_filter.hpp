#pragma once
/// The velocity estimate of hq-sim --sitl's flight controller, fused as PX4's EKF2 fuses external
/// vision velocity (docs.px4.io "Using Vision or Motion Capture Systems", EKF2 tuning): a Kalman
/// filter on the velocity in NED, propagated with the IMU's acceleration (specific force turned
/// into NED with the FC's attitude, plus gravity) and updated by each vision velocity at its own
/// stamp: the innovation is taken against the velocity the filter had then, from a short history,
/// as EKF2 fuses on a delayed horizon. Per-axis innovation gate as EKF2_EVV_GATE; a changed
/// reset_counter re-initialises on the measurement instead of fusing its jump. Pure and
/// allocation-free.

#include <Eigen/Core>

#include <array>
#include <cstdint>

namespace hq::sitl {

struct VisionVelocityFilterConfig {
  /// Process noise of the velocity (m/s^2/sqrt(Hz)): EKF2_ACC_NOISE (0.35 m/s^2 per 10 ms
  /// step, 0.035 per sqrt(Hz)) plus the accelerometer bias this filter does not estimate (the
  /// simulated IMU's is drawn with 0.05 m/s^2 sigma).
  double accel_noise_density_mps2 = 0.1;
  /// EKF2_EVV_NOISE: the least velocity standard deviation used (m/s), and the one used when
  /// the message's covariance is unknown.
  double min_velocity_sigma_mps = 0.1;
  double gate_sigma = 3.0;  ///< EKF2_EVV_GATE: innovation test in standard deviations.
  /// Vision older than this (no fused measurement) no longer drives the estimate: stale.
  std::int64_t stale_after_ns = 500'000'000;
};

enum class VisionFuse { kFused, kReset, kRejectedGate, kRejectedStamp };

class VisionVelocityFilter {
 public:
  explicit VisionVelocityFilter(const VisionVelocityFilterConfig& config = {});
  /// One IMU step to t_ns with the acceleration in NED (m/s^2, gravity included).
  void predict(std::int64_t t_ns, const Eigen::Vector3d& a_NED_mps2);
  /// A finite vision velocity in NED measured at t_meas_ns, covariance R_NED (unknown: NaN or
  /// non-positive diagonal, then the floor). A reset_counter other than the last one's, or the
  /// first measurement, re-initialises.
  VisionFuse fuse(std::int64_t t_meas_ns, const Eigen::Vector3d& z_NED_mps,
                  const Eigen::Matrix3d& R_NED, std::uint8_t reset_counter);
  /// A vision velocity was fused within stale_after_ns of t_ns.
  [[nodiscard]] bool fresh(std::int64_t t_ns) const;
  [[nodiscard]] const Eigen::Vector3d& v_NED_mps() const { return v_NED_mps_; }
  [[nodiscard]] const Eigen::Matrix3d& covariance() const { return P_; }

 private:
  static constexpr std::size_t kHistory = 512;  ///< 1 s of IMU steps at 500 Hz.
  struct Past {
    std::int64_t t_ns = 0;
    Eigen::Vector3d v_NED_mps = Eigen::Vector3d::Zero();
  };
  /// The velocity the filter had at t_ns (the newest step not after it), or false when the
  /// history does not reach back that far or t_ns is ahead of the last step.
  bool velocity_at(std::int64_t t_ns, Eigen::Vector3d& v_NED_mps) const;
  [[nodiscard]] Eigen::Matrix3d floored(const Eigen::Matrix3d& R_NED) const;

  VisionVelocityFilterConfig config_;
  Eigen::Vector3d v_NED_mps_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d P_ = Eigen::Matrix3d::Zero();
  bool initialised_ = false;
  std::uint8_t reset_counter_ = 0;
  std::int64_t t_last_ns_ = -1;
  std::int64_t t_last_fused_ns_ = -1;
  std::array<Past, kHistory> history_{};
  std::size_t history_next_ = 0;
  std::size_t history_count_ = 0;
};

}  // namespace hq::sitl
