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
#include <fmt/format.h>
#include <random>

namespace hq::navigation {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

/// The simulator's world is NWU (core paper §3); the filter's is NED: R_ned_nwu = Rx(pi).
const Matrix3d kR_ned_nwu = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();

/// Noisy measurements of the simulator's truth, as the RGB-D chain and the marker stage give
/// them, with the squared error each measurement carried (the raw error to beat).
class NoisyMeasurements {
 public:
  static constexpr double kMarkerSigma_m = 0.02;
  static constexpr double kMarkerSigma_rad = 0.02;
  static constexpr double kVelocitySigma_mps = 0.05;

  NoisyMeasurements() {
    marker_cov_.diagonal().head<3>().setConstant(kMarkerSigma_m * kMarkerSigma_m);
    marker_cov_.diagonal().tail<3>().setConstant(kMarkerSigma_rad * kMarkerSigma_rad);
  }

  /// v_H (core eq. 5) of the true body velocity, plus noise, into the filter.
  void velocity(NavigationFilter& filter, std::int64_t t_ns, const Matrix3d& R_W_B,
                const Vector3d& v_W_mps) {
    const Vector3d v_H = R_W_H(R_W_B).transpose() * v_W_mps;
    const Vector3d measured = v_H + noise(kVelocitySigma_mps);
    raw_velocity_sq_ += (measured - v_H).squaredNorm();
    ++raw_velocities_;
    filter.update_velocity(t_ns, measured, velocity_cov_);
  }

  /// The true camera pose T_W_C with position and rotation noise into the filter.
  void marker(NavigationFilter& filter, std::int64_t t_ns, const Eigen::Isometry3d& T_W_B,
              const Eigen::Isometry3d& T_B_C) {
    Eigen::Isometry3d T_W_C = T_W_B * T_B_C;
    const Vector3d p_true = T_W_C.translation();
    T_W_C.translation() += noise(kMarkerSigma_m);
    T_W_C.linear() = T_W_C.linear() * geometry::exp_so3(noise(kMarkerSigma_rad));
    raw_marker_sq_ += (T_W_C.translation() - p_true).squaredNorm();
    ++raw_markers_;
    filter.update_marker(t_ns, T_W_C, marker_cov_);
  }

  [[nodiscard]] double raw_marker_rms_m() const {
    return std::sqrt(raw_marker_sq_ / static_cast<double>(raw_markers_));
  }
  [[nodiscard]] double raw_velocity_rms_mps() const {
    return std::sqrt(raw_velocity_sq_ / static_cast<double>(raw_velocities_));
  }

 private:
  Vector3d noise(double sigma) {
    const double x = normal_(rng_);
    const double y = normal_(rng_);
    const double z = normal_(rng_);
    return sigma * Vector3d(x, y, z);
  }

  std::mt19937_64 rng_{3};
  std::normal_distribution<double> normal_{0.0, 1.0};
  Matrix6d marker_cov_ = Matrix6d::Zero();
  Matrix3d velocity_cov_ = Matrix3d::Identity() * kVelocitySigma_mps * kVelocitySigma_mps;
  double raw_marker_sq_ = 0.0;
  double raw_velocity_sq_ = 0.0;
  long raw_markers_ = 0;
  long raw_velocities_ = 0;
};

/// The simulator's truth in the filter's NED world W.
struct TruthInW {
  Eigen::Isometry3d T_W_B = Eigen::Isometry3d::Identity();
  Vector3d v_W_mps = Vector3d::Zero();
};

TruthInW truth_in_W(const sim::TruthState& truth) {
  TruthInW out;
  out.T_W_B.linear() = kR_ned_nwu * truth.T_N_B.linear();
  out.T_W_B.translation() = kR_ned_nwu * truth.T_N_B.translation();
  out.v_W_mps = kR_ned_nwu * truth.v_N_mps;
  return out;
}

TEST(NavigationSim, CircleFlightOnSimulatedImuWithMarkersAndVelocity) {
  sim::SimConfig config = sim::default_sim_config(64, 48);
  config.seed = 11;
  const sim::World world = sim::load_world("onboard/sim/worlds/room.yaml");
  sim::Simulator simulator(config, world);
  const sim::FlightScript script = sim::script_for_world(world, sim::FlightScript::Kind::kCircle);
  const Eigen::Isometry3d T_B_C = config.camera.T_B_C;
  NavigationFilter filter(NavigationConfig{}, T_B_C);
  NoisyMeasurements measure;
  {
    const TruthInW start_truth = truth_in_W(simulator.truth());
    NominalState start;
    start.q_W_B = Eigen::Quaterniond(start_truth.T_W_B.linear());
    start.p_W_m = start_truth.T_W_B.translation();
    filter.initialize(0, start);
  }
  std::array<sim::ImuSample, 64> imu{};
  double position_sq = 0.0, velocity_sq = 0.0;
  long samples = 0;
  const std::int64_t end_ns = 20'000'000'000;
  for (std::int64_t t_ns = sim::kScriptControlPeriodNs; t_ns <= end_ns;
       t_ns += sim::kScriptControlPeriodNs) {
    simulator.set_command(
        sim::scripted_command(simulator, script, 1e-9 * static_cast<double>(t_ns)));
    simulator.step_to(t_ns);
    const std::size_t n = simulator.take_imu(imu.data(), imu.size());
    for (std::size_t i = 0; i < n; ++i) {
      filter.predict(imu[i].t_ns, imu[i].omega_B_radps, imu[i].f_B_mps2);
    }
    const TruthInW truth = truth_in_W(simulator.truth());
    const long step = t_ns / sim::kScriptControlPeriodNs;
    if (step % 7 == 0) {  // ~28.6 Hz, as the RGB-D chain
      measure.velocity(filter, simulator.t_ns(), truth.T_W_B.linear(), truth.v_W_mps);
    }
    if (step % 20 == 0) {  // 10 Hz markers
      measure.marker(filter, simulator.t_ns(), truth.T_W_B, T_B_C);
      if (t_ns >= 5'000'000'000) {
        position_sq += (filter.state().p_W_m - truth.T_W_B.translation()).squaredNorm();
        velocity_sq += (filter.state().v_W_mps - truth.v_W_mps).squaredNorm();
        ++samples;
      }
    }
  }
  const double position_rms = std::sqrt(position_sq / static_cast<double>(samples));
  const double velocity_rms = std::sqrt(velocity_sq / static_cast<double>(samples));
  const NavigationHealth health = filter.health();
  fmt::print(
      "simulator circle 20 s: position RMS {:.4f} m (raw marker {:.4f} m), velocity RMS {:.4f} m/s "
      "(raw {:.4f} m/s), markers gated {}, velocities gated {}, IMU samples {}\n",
      position_rms, measure.raw_marker_rms_m(), velocity_rms, measure.raw_velocity_rms_mps(),
      health.markers_gated, health.velocities_gated, health.imu_samples);
  EXPECT_FALSE(simulator.collided());
  EXPECT_GT(health.imu_samples, 9000);
  EXPECT_LT(position_rms, 0.5 * measure.raw_marker_rms_m());
  EXPECT_LT(velocity_rms, 0.5 * measure.raw_velocity_rms_mps());
  EXPECT_LE(health.markers_gated, 3);
}

}  // namespace
}  // namespace hq::navigation
