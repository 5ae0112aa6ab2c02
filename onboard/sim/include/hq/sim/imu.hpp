#pragma once
/// MEMS IMU model: white noise plus bias random walk on gyro and accelerometer, seeded.
/// Continuous-time densities are discretised at the sample period (Furgale/Kalibr IMU model).

#include <Eigen/Core>

#include <cstdint>
#include <random>

namespace hq::sim {

/// One IMU sample in the body NED frame Q.
struct ImuSample {
  std::int64_t t_ns = 0;
  Eigen::Vector3d omega_B_radps = Eigen::Vector3d::Zero();  ///< gyro.
  Eigen::Vector3d f_B_mps2 = Eigen::Vector3d::Zero();       ///< specific force (accel).
};

struct ImuParams {
  double rate_hz = 500.0;
  double gyro_noise_density = 1.7e-4;   ///< rad/s/sqrt(Hz) (MPU-6000 class: 0.01 deg/s/rtHz)
  double gyro_random_walk = 2.0e-5;     ///< rad/s^2/sqrt(Hz)
  double accel_noise_density = 2.0e-3;  ///< m/s^2/sqrt(Hz) (about 200 ug/rtHz)
  double accel_random_walk = 3.0e-3;    ///< m/s^3/sqrt(Hz)
  double gyro_initial_bias_sigma_radps = 0.005;
  double accel_initial_bias_sigma_mps2 = 0.05;
};

class ImuModel {
 public:
  ImuModel(const ImuParams& params, std::uint64_t seed);
  /// A measurement of the true body rate and specific force at t_ns; advances the biases by
  /// one sample period. Allocates nothing.
  ImuSample measure(std::int64_t t_ns, const Eigen::Vector3d& omega_B_radps,
                    const Eigen::Vector3d& f_B_mps2);
  [[nodiscard]] const Eigen::Vector3d& gyro_bias_radps() const { return gyro_bias_; }
  [[nodiscard]] const Eigen::Vector3d& accel_bias_mps2() const { return accel_bias_; }

 private:
  Eigen::Vector3d gaussian3();
  ImuParams params_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  Eigen::Vector3d gyro_bias_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_bias_ = Eigen::Vector3d::Zero();
};

}  // namespace hq::sim
