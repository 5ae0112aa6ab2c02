#include "hq/sim/imu.hpp"

#include <cmath>

namespace hq::sim {

ImuModel::ImuModel(const ImuParams& params, std::uint64_t seed) : params_(params), rng_(seed) {
  gyro_bias_ = params_.gyro_initial_bias_sigma_radps * gaussian3();
  accel_bias_ = params_.accel_initial_bias_sigma_mps2 * gaussian3();
}

Eigen::Vector3d ImuModel::gaussian3() {
  const double x = normal_(rng_);
  const double y = normal_(rng_);
  const double z = normal_(rng_);
  return {x, y, z};
}

ImuSample ImuModel::measure(std::int64_t t_ns, const Eigen::Vector3d& omega_B_radps,
                            const Eigen::Vector3d& f_B_mps2) {
  const double dt_s = 1.0 / params_.rate_hz;
  // Discrete white noise sigma = density / sqrt(dt); bias walk sigma = density * sqrt(dt).
  const double inv_sqrt_dt = 1.0 / std::sqrt(dt_s);
  const double sqrt_dt = std::sqrt(dt_s);
  ImuSample sample;
  sample.t_ns = t_ns;
  sample.omega_B_radps =
      omega_B_radps + gyro_bias_ + params_.gyro_noise_density * inv_sqrt_dt * gaussian3();
  sample.f_B_mps2 =
      f_B_mps2 + accel_bias_ + params_.accel_noise_density * inv_sqrt_dt * gaussian3();
  gyro_bias_ += params_.gyro_random_walk * sqrt_dt * gaussian3();
  accel_bias_ += params_.accel_random_walk * sqrt_dt * gaussian3();
  return sample;
}

}  // namespace hq::sim
