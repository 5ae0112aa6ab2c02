// The filter on the simulator's IMU and truth (hq::sim): its IMU model, biases and dynamics are
// independent of the analytic trajectory in navigation_filter_test.cpp.
#include "hq/geometry/lie.hpp"
#include "hq/navigation/navigation_filter.hpp"
#include "hq/sim/scripted_flight.hpp"
#include "hq/sim/simulator.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>

namespace hq::navigation {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

/// The simulator's world is NWU (core paper §3); the filter's is NED: R_ned_nwu = Rx(pi).
const Matrix3d kR_ned_nwu = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();

TEST(NavigationSim, CircleFlightOnSimulatedImuWithMarkersAndVelocity) {
  sim::SimConfig config = sim::default_sim_config(64, 48);
  config.seed = 11;
  const sim::World world = sim::load_world("onboard/sim/worlds/room.yaml");
  sim::Simulator simulator(config, world);
  const sim::FlightScript script = sim::script_for_world(world, sim::FlightScript::Kind::kCircle);
  const Eigen::Isometry3d T_body_camera = config.camera.T_body_camera;
  NavigationFilter filter(NavigationConfig{}, T_body_camera);

  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal(0.0, 1.0);
  const auto noise = [&](double sigma) -> Vector3d {
    const double x = normal(rng);
    const double y = normal(rng);
    const double z = normal(rng);
    return sigma * Vector3d(x, y, z);
  };
  const double marker_sigma_m = 0.02, marker_sigma_rad = 0.02, velocity_sigma_mps = 0.05;
  Matrix6d marker_cov = Matrix6d::Zero();
  marker_cov.diagonal().head<3>().setConstant(marker_sigma_m * marker_sigma_m);
  marker_cov.diagonal().tail<3>().setConstant(marker_sigma_rad * marker_sigma_rad);
  const Matrix3d velocity_cov = Matrix3d::Identity() * velocity_sigma_mps * velocity_sigma_mps;

  {
    const sim::TruthState& truth = simulator.truth();
    NominalState start;
    start.q_world_body = Eigen::Quaterniond(kR_ned_nwu * truth.T_world_body.linear());
    start.p_world_m = kR_ned_nwu * truth.T_world_body.translation();
    filter.initialize(0, start);
  }
  std::array<sim::ImuSample, 64> imu{};
  double position_sq = 0.0, velocity_sq = 0.0, raw_marker_sq = 0.0, raw_velocity_sq = 0.0;
  long samples = 0, raw_markers = 0, raw_velocities = 0;
  const std::int64_t end_ns = 20'000'000'000;
  for (std::int64_t t_ns = sim::kScriptControlPeriodNs; t_ns <= end_ns;
       t_ns += sim::kScriptControlPeriodNs) {
    simulator.set_command(
        sim::scripted_command(simulator, script, 1e-9 * static_cast<double>(t_ns)));
    simulator.step_to(t_ns);
    const std::size_t n = simulator.take_imu(imu.data(), imu.size());
    for (std::size_t i = 0; i < n; ++i) {
      filter.predict(imu[i].t_ns, imu[i].omega_body_radps, imu[i].f_body_mps2);
    }
    const sim::TruthState& truth = simulator.truth();
    const Matrix3d R_WB = kR_ned_nwu * truth.T_world_body.linear();
    const Vector3d p_WB = kR_ned_nwu * truth.T_world_body.translation();
    const Vector3d v_W = kR_ned_nwu * truth.v_world_mps;
    const long step = t_ns / sim::kScriptControlPeriodNs;
    if (step % 7 == 0) {  // ~28.6 Hz, as the RGB-D chain
      const Vector3d v_H = R_world_horizontal(R_WB).transpose() * v_W;
      const Vector3d measured = v_H + noise(velocity_sigma_mps);
      raw_velocity_sq += (measured - v_H).squaredNorm();
      ++raw_velocities;
      filter.update_velocity(simulator.t_ns(), measured, velocity_cov);
    }
    if (step % 20 == 0) {  // 10 Hz markers
      Eigen::Isometry3d T_WB = Eigen::Isometry3d::Identity();
      T_WB.linear() = R_WB;
      T_WB.translation() = p_WB;
      Eigen::Isometry3d T_WC = T_WB * T_body_camera;
      const Vector3d p_true = T_WC.translation();
      T_WC.translation() += noise(marker_sigma_m);
      T_WC.linear() = T_WC.linear() * geometry::exp_so3(noise(marker_sigma_rad));
      raw_marker_sq += (T_WC.translation() - p_true).squaredNorm();
      ++raw_markers;
      filter.update_marker(simulator.t_ns(), T_WC, marker_cov);
      if (t_ns >= 5'000'000'000) {
        position_sq += (filter.state().p_world_m - p_WB).squaredNorm();
        velocity_sq += (filter.state().v_world_mps - v_W).squaredNorm();
        ++samples;
      }
    }
  }
  const double position_rms = std::sqrt(position_sq / static_cast<double>(samples));
  const double velocity_rms = std::sqrt(velocity_sq / static_cast<double>(samples));
  const double raw_marker_rms = std::sqrt(raw_marker_sq / static_cast<double>(raw_markers));
  const double raw_velocity_rms = std::sqrt(raw_velocity_sq / static_cast<double>(raw_velocities));
  const NavigationHealth health = filter.health();
  std::printf(
      "simulator circle 20 s: position RMS %.4f m (raw marker %.4f m), velocity RMS %.4f "
      "m/s (raw %.4f m/s), markers gated %ld, velocities gated %ld, IMU samples %ld\n",
      position_rms, raw_marker_rms, velocity_rms, raw_velocity_rms, health.markers_gated,
      health.velocities_gated, health.imu_samples);
  EXPECT_FALSE(simulator.collided());
  EXPECT_GT(health.imu_samples, 9000);
  EXPECT_LT(position_rms, 0.5 * raw_marker_rms);
  EXPECT_LT(velocity_rms, 0.5 * raw_velocity_rms);
  EXPECT_LE(health.markers_gated, 3);
}

}  // namespace
}  // namespace hq::navigation
