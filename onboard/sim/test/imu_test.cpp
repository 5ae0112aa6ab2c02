#include "hq/sim/imu.hpp"

#include "hq/sim/simulator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace hq::sim {
namespace {

World empty_world() {
  World world;
  world.floor.half_u_m = world.floor.half_v_m = 10.0;
  return world;
}

TEST(ImuTest, AtRestLevelReadsMinusGAlongBodyZWithinNoise) {
  SimConfig config = default_sim_config(64, 48);
  const World world = empty_world();
  Simulator sim(config, world);
  sim.step_to(2'000'000'000);
  std::vector<ImuSample> samples(2000);
  const std::size_t n = sim.take_imu(samples.data(), samples.size());
  ASSERT_EQ(n, 500u);  // 1 s ring buffer keeps the last second at 500 Hz
  Eigen::Vector3d mean_f = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_w = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    mean_f += samples[i].f_B_mps2 / static_cast<double>(n);
    mean_w += samples[i].omega_B_radps / static_cast<double>(n);
  }
  double var_fz = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    var_fz += std::pow(samples[i].f_B_mps2.z() - mean_f.z(), 2) / static_cast<double>(n - 1);
  }
  // Initial bias sigma 0.05 m/s^2 and 0.005 rad/s: 4 sigma bounds.
  EXPECT_NEAR(mean_f.x(), 0.0, 0.2);
  EXPECT_NEAR(mean_f.y(), 0.0, 0.2);
  EXPECT_NEAR(mean_f.z(), -9.81, 0.2);
  EXPECT_LT(mean_w.norm(), 0.035);
  // White noise sigma = density * sqrt(rate) = 2e-3 * sqrt(500) = 0.045 m/s^2.
  const double expected_sigma = config.imu.accel_noise_density * std::sqrt(config.imu.rate_hz);
  EXPECT_NEAR(std::sqrt(var_fz), expected_sigma, 0.15 * expected_sigma);
}

TEST(ImuTest, NoiseFreeModelReturnsTruth) {
  ImuParams p;
  p.gyro_noise_density = p.gyro_random_walk = p.accel_noise_density = p.accel_random_walk = 0.0;
  p.gyro_initial_bias_sigma_radps = p.accel_initial_bias_sigma_mps2 = 0.0;
  ImuModel imu(p, 3);
  const ImuSample s = imu.measure(7, Eigen::Vector3d(0.1, 0.2, 0.3), Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(s.t_ns, 7);
  EXPECT_EQ(s.omega_B_radps, Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_EQ(s.f_B_mps2, Eigen::Vector3d(1, 2, 3));
}

TEST(ImuTest, BiasWalksWithConfiguredDensity) {
  ImuParams p;
  p.gyro_initial_bias_sigma_radps = p.accel_initial_bias_sigma_mps2 = 0.0;
  double sum_sq = 0.0;
  const int runs = 200;
  const int steps = 500;  // 1 s
  for (int r = 0; r < runs; ++r) {
    ImuModel imu(p, static_cast<std::uint64_t>(r) + 100);
    for (int i = 0; i < steps; ++i)
      imu.measure(i, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
    sum_sq += imu.accel_bias_mps2().squaredNorm() / 3.0;
  }
  // After 1 s the bias standard deviation is random_walk * sqrt(1 s).
  EXPECT_NEAR(std::sqrt(sum_sq / runs), p.accel_random_walk, 0.15 * p.accel_random_walk);
}

}  // namespace
}  // namespace hq::sim
