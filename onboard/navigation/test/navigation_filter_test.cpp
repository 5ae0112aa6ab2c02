#include "hq/navigation/navigation_filter.hpp"

#include "hq/config/strict_yaml.hpp"
#include "hq/estimator/velocity_estimator.hpp"
#include "hq/geometry/lie.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <limits>
#include <random>
#include <string>

namespace hq::navigation {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;
using ::testing::HasSubstr;

constexpr double kGravity = 9.81;
constexpr std::int64_t kImuPeriodNs = 2'000'000;        // 500 Hz
constexpr std::int64_t kMarkerPeriodNs = 100'000'000;   // 10 Hz
constexpr std::int64_t kVelocityPeriodNs = 33'333'333;  // 30 Hz
constexpr double kPi = 3.14159265358979323846;

double to_s(std::int64_t t_ns) { return static_cast<double>(t_ns) * 1e-9; }

Matrix3d euler_zyx(double roll, double pitch, double yaw) {
  return (Eigen::AngleAxisd(yaw, Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Vector3d::UnitX()))
      .toRotationMatrix();
}

/// Analytic truth: a figure-eight at ~1 m/s in NED with rolling, pitching and turning body.
struct Truth {
  Vector3d p_W, v_W, a_W;
  Matrix3d R_WB;
  Vector3d omega_B;
};

Truth figure_eight(double t) {
  const double w = 2.0 * kPi / 12.0;
  Truth x;
  x.p_W = Vector3d(1.5 * std::sin(w * t), 0.8 * std::sin(2 * w * t),
                   -1.2 + 0.15 * std::sin(1.5 * w * t));
  x.v_W = Vector3d(1.5 * w * std::cos(w * t), 1.6 * w * std::cos(2 * w * t),
                   0.225 * w * std::cos(1.5 * w * t));
  x.a_W = Vector3d(-1.5 * w * w * std::sin(w * t), -3.2 * w * w * std::sin(2 * w * t),
                   -0.3375 * w * w * std::sin(1.5 * w * t));
  const double roll = 0.12 * std::sin(0.8 * t), roll_dot = 0.096 * std::cos(0.8 * t);
  const double pitch = 0.1 * std::cos(0.6 * t), pitch_dot = -0.06 * std::sin(0.6 * t);
  const double yaw = 0.6 * std::sin(0.25 * t) + 0.1 * t;
  const double yaw_dot = 0.15 * std::cos(0.25 * t) + 0.1;
  x.R_WB = euler_zyx(roll, pitch, yaw);
  // ZYX Euler rates to body rates.
  x.omega_B = Vector3d(roll_dot - yaw_dot * std::sin(pitch),
                       pitch_dot * std::cos(roll) + yaw_dot * std::cos(pitch) * std::sin(roll),
                       -pitch_dot * std::sin(roll) + yaw_dot * std::cos(pitch) * std::cos(roll));
  return x;
}

/// Camera looking forward: optical z = body x, x = body y, y = body z.
Eigen::Isometry3d T_B_C() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  T.translation() = Vector3d(0.1, 0.0, 0.05);
  return T;
}

struct ScenarioOptions {
  Vector3d gyro_bias_radps{0.01, -0.008, 0.006};
  Vector3d accel_bias_mps2{0.12, -0.09, 0.07};
  double marker_sigma_m = 0.02;
  double marker_sigma_rad = 1.0 * kPi / 180.0;
  double velocity_sigma_mps = 0.05;
  double gyro_noise = 1.7e-4;  // densities, as the default config
  double accel_noise = 2.0e-3;
  std::uint64_t seed = 7;
  bool velocity_on = true;  ///< false: no RGB-D velocity, the IMU alone between markers.
  NavigationConfig config;
};

/// Runs the filter on the figure-eight: IMU at 500 Hz, velocity in H at 30 Hz, markers at
/// 10 Hz when enabled; measurements are truth plus Gaussian noise of known covariance.
class Scenario {
 public:
  explicit Scenario(const ScenarioOptions& options = {})
      : options_(options), filter_(options.config, T_B_C()), rng_(options.seed) {
    // Unanchored start: yaw off by 0.3 rad, position unknown, velocity right in H.
    const Truth x = figure_eight(0.0);
    NominalState start;
    const Matrix3d R_start = euler_zyx(0.01, -0.01, 0.3) * x.R_WB;
    start.q_W_B = Eigen::Quaterniond(R_start);
    start.v_W_mps = R_W_H(R_start) * R_W_H(x.R_WB).transpose() * x.v_W;
    filter_.initialize(0, start);
  }

  /// Steps to t_s; markers are delivered only while markers_on, replaced by `marker_override`
  /// once if set.
  void run_to(double t_s, bool markers_on = true) {
    const auto end_ns = static_cast<std::int64_t>(std::llround(t_s * 1e9));
    while (t_ns_ < end_ns) {
      t_ns_ += kImuPeriodNs;
      step(markers_on);
    }
  }

  void step(bool markers_on) {
    const Truth x = figure_eight(to_s(t_ns_));
    const double sg = options_.gyro_noise * std::sqrt(500.0);
    const double sa = options_.accel_noise * std::sqrt(500.0);
    const Vector3d gyro = x.omega_B + options_.gyro_bias_radps + noise(sg);
    const Vector3d accel = x.R_WB.transpose() * (x.a_W - Vector3d(0, 0, kGravity)) +
                           options_.accel_bias_mps2 + noise(sa);
    last_predict_ = filter_.predict(t_ns_, gyro, accel);
    if (options_.velocity_on && t_ns_ >= next_velocity_ns_) {
      next_velocity_ns_ += kVelocityPeriodNs;
      const Vector3d v_H = R_W_H(x.R_WB).transpose() * x.v_W;
      const Vector3d measured = v_H + noise(options_.velocity_sigma_mps);
      raw_velocity_sq_ += (measured - v_H).squaredNorm();
      ++raw_velocity_n_;
      last_velocity_ = filter_.update_velocity(t_ns_, measured, velocity_covariance());
    }
    if (t_ns_ >= next_marker_ns_) {
      next_marker_ns_ += kMarkerPeriodNs;
      if (markers_on) {
        Eigen::Isometry3d T_WC = marker_truth(x);
        T_WC.translation() += noise(options_.marker_sigma_m);
        T_WC.linear() = T_WC.linear() * geometry::exp_so3(noise(options_.marker_sigma_rad));
        raw_marker_sq_ += (T_WC.translation() - marker_truth(x).translation()).squaredNorm();
        ++raw_marker_n_;
        last_marker_ = filter_.update_marker(t_ns_, T_WC, marker_covariance());
      }
      sample_errors(x);
    }
  }

  Eigen::Isometry3d marker_truth(const Truth& x) const {
    Eigen::Isometry3d T_WB = Eigen::Isometry3d::Identity();
    T_WB.linear() = x.R_WB;
    T_WB.translation() = x.p_W;
    return T_WB * T_B_C();
  }

  Matrix6d marker_covariance() const {
    Matrix6d C = Matrix6d::Zero();
    C.diagonal().head<3>().setConstant(options_.marker_sigma_m * options_.marker_sigma_m);
    C.diagonal().tail<3>().setConstant(options_.marker_sigma_rad * options_.marker_sigma_rad);
    return C;
  }
  Matrix3d velocity_covariance() const {
    return Matrix3d::Identity() * options_.velocity_sigma_mps * options_.velocity_sigma_mps;
  }

  /// Error statistics at 10 Hz, accumulated after `settle_s`.
  void sample_errors(const Truth& x) {
    const NominalState& s = filter_.state();
    position_error_m_ = (x.p_W - s.p_W_m).norm();
    velocity_error_mps_ = (x.v_W - s.v_W_mps).norm();
    if (to_s(t_ns_) < settle_s_ || !accumulate_) return;
    Eigen::Matrix<double, 9, 1> e;
    e.segment<3>(0) = x.p_W - s.p_W_m;
    e.segment<3>(3) = x.v_W - s.v_W_mps;
    e.segment<3>(6) = geometry::log_so3(s.q_W_B.toRotationMatrix().transpose() * x.R_WB);
    const Eigen::Matrix<double, 9, 9> P9 = filter_.covariance().topLeftCorner<9, 9>();
    nees_sum_ += e.dot(P9.ldlt().solve(e));
    position_sq_ += e.segment<3>(0).squaredNorm();
    velocity_sq_ += e.segment<3>(3).squaredNorm();
    ++samples_;
  }

  Vector3d noise(double sigma) {
    return Vector3d(normal_(rng_), normal_(rng_), normal_(rng_)) * sigma;
  }

  [[nodiscard]] double position_rms() const {
    return std::sqrt(position_sq_ / static_cast<double>(samples_));
  }
  [[nodiscard]] double velocity_rms() const {
    return std::sqrt(velocity_sq_ / static_cast<double>(samples_));
  }
  [[nodiscard]] double raw_marker_rms() const {
    return std::sqrt(raw_marker_sq_ / static_cast<double>(raw_marker_n_));
  }
  [[nodiscard]] double raw_velocity_rms() const {
    return std::sqrt(raw_velocity_sq_ / static_cast<double>(raw_velocity_n_));
  }
  [[nodiscard]] double mean_nees() const { return nees_sum_ / static_cast<double>(samples_); }
  [[nodiscard]] Truth truth() const { return figure_eight(to_s(t_ns_)); }
  NavigationFilter& filter() { return filter_; }
  void set_velocity_on(bool on) { options_.velocity_on = on; }
  [[nodiscard]] const ScenarioOptions& options() const { return options_; }
  [[nodiscard]] std::int64_t t_ns() const { return t_ns_; }
  [[nodiscard]] double position_error_m() const { return position_error_m_; }
  [[nodiscard]] long samples() const { return samples_; }

 private:
  ScenarioOptions options_;
  NavigationFilter filter_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  std::int64_t t_ns_ = 0;
  std::int64_t next_marker_ns_ = kMarkerPeriodNs;
  std::int64_t next_velocity_ns_ = kVelocityPeriodNs;
  UpdateResult last_predict_, last_marker_, last_velocity_;
  double settle_s_ = 5.0;
  bool accumulate_ = true;
  double position_error_m_ = 0.0, velocity_error_mps_ = 0.0;
  double position_sq_ = 0.0, velocity_sq_ = 0.0, nees_sum_ = 0.0;
  double raw_marker_sq_ = 0.0, raw_velocity_sq_ = 0.0;
  long samples_ = 0, raw_marker_n_ = 0, raw_velocity_n_ = 0;
};

TEST(SyntheticTrajectory, BodyRatesAndVelocityMatchTheTrajectory) {
  const double h = 1e-5;
  for (double t : {0.3, 2.7, 9.1}) {
    const Truth x = figure_eight(t);
    const Truth x1 = figure_eight(t + h);
    const Vector3d omega_numeric = geometry::log_so3(x.R_WB.transpose() * x1.R_WB) / h;
    EXPECT_LT((omega_numeric - x.omega_B).norm(), 1e-4) << "t=" << t;
    EXPECT_LT(((x1.p_W - x.p_W) / h - x.v_W).norm(), 1e-4);
    EXPECT_LT(((x1.v_W - x.v_W) / h - x.a_W).norm(), 1e-4);
  }
}

NominalState tilted_state() {
  NominalState s;
  s.p_W_m = Vector3d(0.4, -0.2, -1.1);
  s.v_W_mps = Vector3d(0.7, -0.3, 0.2);
  s.q_W_B = Eigen::Quaterniond(euler_zyx(0.2, -0.25, 1.1));
  return s;
}

NominalState perturbed(const NominalState& s, int index, double eps) {
  Eigen::Matrix<double, kErrorStateSize, 1> dx = Eigen::Matrix<double, kErrorStateSize, 1>::Zero();
  dx(index) = eps;
  NominalState out = s;
  out.p_W_m += dx.segment<3>(kIndexPosition);
  out.v_W_mps += dx.segment<3>(kIndexVelocity);
  out.q_W_B = Eigen::Quaterniond(s.q_W_B.toRotationMatrix() *
                                 geometry::exp_so3(dx.segment<3>(kIndexAttitude)));
  return out;
}

TEST(MeasurementModels, VelocityJacobianMatchesNumericIncludingYaw) {
  const NominalState s = tilted_state();
  const auto H = velocity_jacobian(s);
  const double eps = 1e-7;
  for (int j = 0; j < kErrorStateSize; ++j) {
    const Vector3d numeric = (predict_velocity_horizontal(perturbed(s, j, eps)) -
                              predict_velocity_horizontal(perturbed(s, j, -eps))) /
                             (2 * eps);
    EXPECT_LT((numeric - H.col(j)).norm(), 1e-6) << "column " << j;
  }
  // The attitude columns are not zero: H depends on yaw.
  EXPECT_GT((H.block<3, 3>(0, kIndexAttitude).norm()), 0.1);
}

TEST(MeasurementModels, MarkerJacobianMatchesNumeric) {
  const NominalState s = tilted_state();
  const Eigen::Isometry3d T_BC = T_B_C();
  const auto H = marker_jacobian(s, T_BC.linear(), T_BC.translation());
  const Matrix3d R_WC0 = s.q_W_B.toRotationMatrix() * T_BC.linear();
  const auto h = [&](const NominalState& x) {
    Eigen::Matrix<double, 6, 1> out;
    const Matrix3d R = x.q_W_B.toRotationMatrix();
    out.head<3>() = x.p_W_m + R * T_BC.translation();
    out.tail<3>() = geometry::log_so3(R_WC0.transpose() * R * T_BC.linear());
    return out;
  };
  const double eps = 1e-7;
  for (int j = 0; j < kErrorStateSize; ++j) {
    const Eigen::Matrix<double, 6, 1> numeric =
        (h(perturbed(s, j, eps)) - h(perturbed(s, j, -eps))) / (2 * eps);
    EXPECT_LT((numeric - H.col(j)).norm(), 1e-6) << "column " << j;
  }
}

TEST(NavigationFilter, TracksFigureEightWithMarkersAndVelocity) {
  Scenario run;
  run.run_to(30.0);
  const NavigationHealth health = run.filter().health();
  fmt::print(
      "figure-eight 30 s: position RMS {:.4f} m (raw marker {:.4f} m), velocity RMS {:.4f} m/s "
      "(raw RGB-D {:.4f} m/s), sigma_p {:.4f} m, markers {} accepted {} gated, velocities {} "
      "accepted {} gated\n",
      run.position_rms(), run.raw_marker_rms(), run.velocity_rms(), run.raw_velocity_rms(),
      health.position_sigma_m, health.markers_accepted, health.markers_gated,
      health.velocities_accepted, health.velocities_gated);
  // The fused estimate beats each sensor alone by a clear margin.
  EXPECT_LT(run.position_rms(), 0.5 * run.raw_marker_rms());
  EXPECT_LT(run.velocity_rms(), 0.5 * run.raw_velocity_rms());
  EXPECT_FALSE(health.degraded);
  EXPECT_TRUE(health.anchored);
  // At a 99.9 % gate about one in a thousand inliers is gated.
  EXPECT_LE(health.markers_gated, 3);
  EXPECT_LE(health.velocities_gated, 5);
}

TEST(NavigationFilter, BiasesConvergeTowardsTheInjectedOnes) {
  Scenario run;
  run.run_to(5.0);
  const Vector3d bg_error_5s = run.filter().state().gyro_bias_radps - run.options().gyro_bias_radps;
  const Vector3d ba_error_5s = run.filter().state().accel_bias_mps2 - run.options().accel_bias_mps2;
  run.run_to(40.0);
  const NominalState& s = run.filter().state();
  const Vector3d bg_error = s.gyro_bias_radps - run.options().gyro_bias_radps;
  const Vector3d ba_error = s.accel_bias_mps2 - run.options().accel_bias_mps2;
  const ErrorCovariance& P = run.filter().covariance();
  fmt::print(
      "gyro bias est [{:.4f} {:.4f} {:.4f}] true [{:.4f} {:.4f} {:.4f}] rad/s, |error| {:.4f} at 5 "
      "s\n",
      s.gyro_bias_radps.x(), s.gyro_bias_radps.y(), s.gyro_bias_radps.z(),
      run.options().gyro_bias_radps.x(), run.options().gyro_bias_radps.y(),
      run.options().gyro_bias_radps.z(), bg_error_5s.norm());
  fmt::print(
      "accel bias est [{:.4f} {:.4f} {:.4f}] true [{:.4f} {:.4f} {:.4f}] m/s^2, |error| {:.4f} at "
      "5 s\n",
      s.accel_bias_mps2.x(), s.accel_bias_mps2.y(), s.accel_bias_mps2.z(),
      run.options().accel_bias_mps2.x(), run.options().accel_bias_mps2.y(),
      run.options().accel_bias_mps2.z(), ba_error_5s.norm());
  fmt::print(
      "bias |error| at 40 s: gyro {:.5f} rad/s (of {:.4f}), accel {:.4f} m/s^2 (of {:.4f})\n",
      bg_error.norm(), run.options().gyro_bias_radps.norm(), ba_error.norm(),
      run.options().accel_bias_mps2.norm());
  EXPECT_LT(bg_error.norm(), 0.2 * run.options().gyro_bias_radps.norm());
  EXPECT_LT(ba_error.norm(), 0.3 * run.options().accel_bias_mps2.norm());
  for (int i = 0; i < 3; ++i) {
    EXPECT_LT(std::abs(bg_error(i)), 4.0 * std::sqrt(P(kIndexGyroBias + i, kIndexGyroBias + i)));
    EXPECT_LT(std::abs(ba_error(i)), 4.0 * std::sqrt(P(kIndexAccelBias + i, kIndexAccelBias + i)));
  }
}

TEST(NavigationFilter, OutlierMarkerIsGatedAndCountedWithoutTouchingTheState) {
  Scenario run;
  run.run_to(10.0);
  const NominalState before = run.filter().state();
  const ErrorCovariance P_before = run.filter().covariance();
  Eigen::Isometry3d T_WC = run.marker_truth(run.truth());
  T_WC.translation() += Vector3d(1.0, 0.0, 0.0);
  const long gated_before = run.filter().health().markers_gated;
  const UpdateResult result = run.filter().update_marker(run.t_ns(), T_WC, run.marker_covariance());
  fmt::print("outlier marker 1 m off: NIS {:.1f} against gate {:.2f}\n", result.nis,
             run.filter().config().marker_gate_chi2);
  EXPECT_EQ(result.status, UpdateStatus::kGated);
  EXPECT_THAT(result.reason, HasSubstr("Mahalanobis"));
  EXPECT_EQ(run.filter().health().markers_gated, gated_before + 1);
  EXPECT_EQ(run.filter().state().p_W_m, before.p_W_m);
  EXPECT_EQ(run.filter().state().v_W_mps, before.v_W_mps);
  EXPECT_EQ(run.filter().state().q_W_B.coeffs(), before.q_W_B.coeffs());
  EXPECT_EQ(run.filter().covariance(), P_before);
  run.run_to(12.0);
  EXPECT_LT(run.position_error_m(), 3.0 * run.options().marker_sigma_m);
}

TEST(NavigationFilter, MarkersWithheldFiveSecondsDriftBoundedThenReconverge) {
  Scenario run;
  run.run_to(15.0);
  // Steady-state bound: twice the position sigma with markers (about the RMS of the first test).
  const double sigma_with_markers = run.filter().health().position_sigma_m;
  const double bound_m = 2.0 * sigma_with_markers;
  ASSERT_LT(run.position_error_m(), bound_m);
  double sigma_prev = sigma_with_markers;
  bool monotonic = true;
  // GIVEN no marker from 15 s on, WHEN flying 6 s on IMU and RGB-D velocity only.
  const long velocities_before = run.filter().health().velocities_accepted;
  for (int i = 1; i <= 60; ++i) {
    run.run_to(15.0 + 0.1 * i, false);
    const double sigma = run.filter().health().position_sigma_m;
    monotonic = monotonic && sigma > sigma_prev;
    sigma_prev = sigma;
    if (i == 49) {
      EXPECT_FALSE(run.filter().health().degraded) << "4.9 s without marker";
    }
  }
  const NavigationHealth gap = run.filter().health();
  fmt::print(
      "6 s without markers: drift {:.4f} m, sigma_p {:.4f} m, time since marker {:.2f} s, "
      "velocities accepted meanwhile {}\n",
      run.position_error_m(), gap.position_sigma_m, gap.time_since_marker_s,
      gap.velocities_accepted - velocities_before);
  EXPECT_TRUE(monotonic) << "position sigma must grow without markers";
  EXPECT_TRUE(gap.degraded);
  EXPECT_GE(gap.time_since_marker_s, 5.0);
  EXPECT_GT(gap.velocities_accepted - velocities_before, 150);
  EXPECT_LT(run.position_error_m(), 0.3);
  EXPECT_LT(run.position_error_m(), 3.0 * gap.position_sigma_m);
  ASSERT_GT(run.position_error_m(), bound_m) << "the gap must have left the bound to test recovery";
  // WHEN markers return THEN the error falls back below the bound within a second, and two
  // seconds later the covariance is back near its value with markers.
  double recovered_after_s = -1.0;
  for (int i = 1; i <= 20; ++i) {
    run.run_to(21.0 + 0.1 * i, true);
    if (recovered_after_s < 0 && run.position_error_m() < bound_m) recovered_after_s = 0.1 * i;
  }
  fmt::print(
      "markers back: error below {:.4f} m (2 sigma_p before the gap) after {:.1f} s, sigma_p "
      "{:.4f} m\n",
      bound_m, recovered_after_s, run.filter().health().position_sigma_m);
  EXPECT_GT(recovered_after_s, 0.0);
  EXPECT_LE(recovered_after_s, 1.0);
  EXPECT_FALSE(run.filter().health().degraded);
  EXPECT_LT(run.filter().health().position_sigma_m, 1.5 * sigma_with_markers);
}

// GIVEN markers withheld WHEN their age passes position_max_age_s THEN the pose is invalid for
// "no marker", also when asked at a later time than the filter's (an IMU that stopped), and
// valid again with the first accepted marker.
TEST(PositionCheck, NoMarkerForLongerThanTheLimitInvalidatesUntilTheNextMarker) {
  Scenario run;
  EXPECT_FALSE(run.filter().check_position(0).valid);
  EXPECT_EQ(run.filter().check_position(0).reason, PositionInvalid::kNotAnchored);
  run.run_to(15.0);
  ASSERT_TRUE(run.filter().check_position(run.t_ns()).valid);
  const double limit_s = run.filter().config().position_max_age_s;
  run.run_to(15.0 + limit_s - 0.15, false);
  PositionCheck check = run.filter().check_position(run.t_ns());
  EXPECT_TRUE(check.valid) << "age " << check.age_s;
  EXPECT_NEAR(check.age_s, limit_s - 0.15, 0.11);
  // The filter's clock frozen: asked 0.2 s later, the age has passed the limit all the same.
  const std::int64_t later_ns = run.t_ns() + 200'000'000;
  check = run.filter().check_position(later_ns);
  EXPECT_FALSE(check.valid);
  EXPECT_EQ(check.reason, PositionInvalid::kNoMarker);
  EXPECT_STREQ(to_string(check.reason), "no marker");
  run.run_to(15.0 + limit_s + 0.15, false);
  check = run.filter().check_position(run.t_ns());
  EXPECT_FALSE(check.valid);
  EXPECT_EQ(check.reason, PositionInvalid::kNoMarker);
  EXPECT_GT(check.age_s, limit_s);
  run.run_to(15.0 + limit_s + 0.35, true);
  check = run.filter().check_position(run.t_ns());
  EXPECT_TRUE(check.valid) << to_string(check.reason);
  EXPECT_LT(check.age_s, 0.11);
}

// GIVEN no marker and no RGB-D velocity (the IMU alone) and an age limit out of the way, WHEN the
// covariance grows THEN the pose turns invalid for it, and while it was valid the error stayed
// within three times the sigma bound.
TEST(PositionCheck, CovarianceGrowthWithoutObservationsIsBounded) {
  ScenarioOptions options;
  options.config.position_max_age_s = 600.0;
  options.config.position_max_sigma_m = 0.3;
  Scenario run(options);
  run.run_to(20.0);
  ASSERT_TRUE(run.filter().check_position(run.t_ns()).valid);
  run.set_velocity_on(false);
  double invalid_after_s = -1.0;
  double worst_valid_error_m = 0.0;
  for (int i = 1; i <= 600 && invalid_after_s < 0; ++i) {
    run.run_to(20.0 + 0.1 * i, false);
    const PositionCheck check = run.filter().check_position(run.t_ns());
    if (check.valid) {
      worst_valid_error_m = std::max(worst_valid_error_m, run.position_error_m());
    } else {
      EXPECT_EQ(check.reason, PositionInvalid::kCovarianceOverBound);
      EXPECT_GT(check.sigma_horizontal_m, options.config.position_max_sigma_m);
      invalid_after_s = 0.1 * i;
    }
  }
  fmt::print(
      "no markers: invalid (sigma over {:.2f} m) after {:.1f} s, worst error while valid {:.3f} "
      "m\n",
      options.config.position_max_sigma_m, invalid_after_s, worst_valid_error_m);
  EXPECT_GT(invalid_after_s, 0.0) << "covariance never reached the bound";
  EXPECT_LT(worst_valid_error_m, 3.0 * options.config.position_max_sigma_m);
}

// GIVEN position_inconsistent_after_frames marker frames in a row whose markers all fail the
// chi-square gate THEN the pose is invalid ("markers disagree"), the NIS is reported, and a
// consistent marker clears it. A gated marker beside an accepted one of the same frame (a far,
// less accurate marker) is no disagreement.
TEST(PositionCheck, FramesOfGatedMarkersInARowMarkThePoseInconsistentUntilOneIsAccepted) {
  Scenario run;
  run.run_to(10.0);
  const int n = run.filter().config().position_inconsistent_after_frames;
  const auto outlier = [&run] {
    Eigen::Isometry3d T_WC = run.marker_truth(run.truth());
    T_WC.translation() += Vector3d(1.0, 0.0, 0.0);
    return run.filter().update_marker(run.t_ns(), T_WC, run.marker_covariance());
  };
  // One frame: an accepted marker, then several gated ones of the same stamp.
  ASSERT_TRUE(run.filter()
                  .update_marker(run.t_ns(), run.marker_truth(run.truth()), run.marker_covariance())
                  .accepted());
  const long reanchors = run.filter().health().reanchors;
  for (int i = 0; i < 2; ++i) ASSERT_EQ(outlier().status, UpdateStatus::kGated);
  EXPECT_TRUE(run.filter().check_position(run.t_ns()).valid) << "gated beside an accepted one";
  EXPECT_EQ(run.filter().health().disagreeing_marker_frames, 0);
  for (int i = 0; i < n; ++i) {
    run.run_to(to_s(run.t_ns()) + 0.02, false);
    EXPECT_TRUE(run.filter().check_position(run.t_ns()).valid) << "after " << i << " frames";
    ASSERT_EQ(outlier().status, UpdateStatus::kGated);
    ASSERT_EQ(outlier().status, UpdateStatus::kGated);  // two markers in the frame, both off
    EXPECT_GT(run.filter().health().last_marker_nis, run.filter().config().marker_gate_chi2);
  }
  ASSERT_EQ(run.filter().health().reanchors, reanchors) << "re-anchored: fewer gated markers";
  PositionCheck check = run.filter().check_position(run.t_ns());
  EXPECT_FALSE(check.valid);
  EXPECT_EQ(check.reason, PositionInvalid::kInnovationInconsistent);
  EXPECT_EQ(run.filter().health().disagreeing_marker_frames, n);
  const UpdateResult good = run.filter().update_marker(run.t_ns(), run.marker_truth(run.truth()),
                                                       run.marker_covariance());
  ASSERT_TRUE(good.accepted());
  check = run.filter().check_position(run.t_ns());
  EXPECT_TRUE(check.valid) << to_string(check.reason);
}

// GIVEN position_inconsistent_after_velocities RGB-D velocities in a row failing their gate (the
// filter no longer believes the velocity its pose integrates between markers) THEN the pose is
// invalid as inconsistent; an accepted velocity clears it.
TEST(PositionCheck, GatedVelocitiesInARowMarkThePoseInconsistent) {
  Scenario run;
  run.run_to(10.0);
  const int n = run.filter().config().position_inconsistent_after_velocities;
  const Vector3d v_H = predict_velocity_horizontal(run.filter().state());
  for (int i = 0; i < n; ++i) {
    EXPECT_TRUE(run.filter().check_position(run.t_ns()).valid) << "after " << i << " gated";
    const UpdateResult r = run.filter().update_velocity(run.t_ns(), v_H + Vector3d(2.0, 0.0, 0.0),
                                                        run.velocity_covariance());
    ASSERT_EQ(r.status, UpdateStatus::kGated);
  }
  PositionCheck check = run.filter().check_position(run.t_ns());
  EXPECT_FALSE(check.valid);
  EXPECT_EQ(check.reason, PositionInvalid::kInnovationInconsistent);
  EXPECT_EQ(run.filter().health().consecutive_gated_velocities, n);
  ASSERT_TRUE(run.filter()
                  .update_velocity(run.t_ns(), predict_velocity_horizontal(run.filter().state()),
                                   run.velocity_covariance())
                  .accepted());
  check = run.filter().check_position(run.t_ns());
  EXPECT_TRUE(check.valid) << to_string(check.reason);
}

TEST(PositionCheck, AllocatesNothing) {
  Scenario run;
  run.run_to(2.0);
  const long before = hq::testing::allocation_count();
  bool valid = false;
  for (int i = 0; i < 100; ++i) valid = run.filter().check_position(run.t_ns() + i).valid || valid;
  EXPECT_TRUE(valid);
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
}

TEST(NavigationFilter, NonFiniteInputsAreRejectedWithReasonAndStateUntouched) {
  Scenario run;
  run.run_to(3.0);
  const NominalState before = run.filter().state();
  const ErrorCovariance P_before = run.filter().covariance();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const std::int64_t t = run.t_ns();
  const Vector3d ok(0.0, 0.0, -kGravity);
  Eigen::Isometry3d T_WC = run.marker_truth(run.truth());
  Eigen::Isometry3d T_nan = T_WC;
  T_nan.translation().x() = nan;
  Eigen::Isometry3d T_inf = T_WC;
  T_inf.linear()(1, 2) = inf;
  Matrix6d C_nan = run.marker_covariance();
  C_nan(2, 2) = nan;
  Matrix3d V_inf = run.velocity_covariance();
  V_inf(0, 0) = inf;
  const UpdateResult results[] = {
      run.filter().predict(t + kImuPeriodNs, Vector3d(nan, 0, 0), ok),
      run.filter().predict(t + kImuPeriodNs, Vector3d::Zero(), Vector3d(0, inf, 0)),
      run.filter().update_marker(t, T_nan, run.marker_covariance()),
      run.filter().update_marker(t, T_inf, run.marker_covariance()),
      run.filter().update_marker(t, T_WC, C_nan),
      run.filter().update_velocity(t, Vector3d(0, nan, 0), run.velocity_covariance()),
      run.filter().update_velocity(t, Vector3d::Zero(), V_inf),
  };
  for (const UpdateResult& r : results) {
    EXPECT_EQ(r.status, UpdateStatus::kRejected) << r.reason;
    EXPECT_TRUE(std::string(r.reason).find("non-finite") != std::string::npos ||
                std::string(r.reason).find("not positive definite") != std::string::npos)
        << r.reason;
  }
  EXPECT_THAT(results[0].reason, HasSubstr("non-finite IMU"));
  EXPECT_THAT(results[2].reason, HasSubstr("non-finite marker"));
  EXPECT_THAT(results[5].reason, HasSubstr("non-finite velocity"));
  EXPECT_EQ(run.filter().health().inputs_rejected, 7);
  EXPECT_EQ(run.filter().state().p_W_m, before.p_W_m);
  EXPECT_EQ(run.filter().state().v_W_mps, before.v_W_mps);
  EXPECT_EQ(run.filter().state().q_W_B.coeffs(), before.q_W_B.coeffs());
  EXPECT_EQ(run.filter().covariance(), P_before);
  EXPECT_EQ(run.filter().t_ns(), t);
  // And it keeps working on good data.
  run.run_to(6.0);
  EXPECT_TRUE(run.filter().covariance().allFinite());
  EXPECT_LT(run.position_error_m(), 3.0 * run.options().marker_sigma_m);
}

TEST(NavigationFilter, StaleAndUninitialisedInputsAreRejected) {
  NavigationFilter filter(NavigationConfig{}, T_B_C());
  EXPECT_THAT(filter.predict(0, Vector3d::Zero(), Vector3d(0, 0, -kGravity)).reason,
              HasSubstr("not initialised"));
  filter.initialize(1'000'000'000, NominalState{});
  EXPECT_THAT(filter.update_velocity(0, Vector3d::Zero(), Matrix3d::Identity()).reason,
              HasSubstr("stamp"));
  estimator::VelocityEstimate unavailable;
  EXPECT_THAT(filter.update_velocity(unavailable).reason, HasSubstr("unavailable"));
}

TEST(NavigationFilter, AnchoringOnFirstMarkerKeepsVelocityInHorizontalFrame) {
  // GIVEN velocity-only flight with a wrong yaw, WHEN the first marker anchors position and
  // yaw, THEN the velocity the tracker reads (in H) does not jump.
  Scenario run;
  run.run_to(0.098);
  ASSERT_FALSE(run.filter().health().anchored);
  const Vector3d v_H_before = run.filter().v_H_mps();
  const Truth x = run.truth();
  const UpdateResult result =
      run.filter().anchor_to_marker(run.t_ns(), run.marker_truth(x), run.marker_covariance());
  ASSERT_TRUE(result.accepted());
  EXPECT_TRUE(run.filter().health().anchored);
  EXPECT_LT((run.filter().v_H_mps() - v_H_before).norm(), 1e-12);
  EXPECT_LT((run.filter().state().p_W_m - x.p_W).norm(), 1e-9);
  EXPECT_NEAR(yaw_rad(run.filter().state().q_W_B.toRotationMatrix()), yaw_rad(x.R_WB), 1e-9);
}

TEST(NavigationFilter, NeesAveragedOverTheRunIsConsistent) {
  double nees_total = 0.0;
  long samples = 0;
  constexpr int kRuns = 4;
  for (int r = 0; r < kRuns; ++r) {
    ScenarioOptions options;
    options.seed = 100 + static_cast<std::uint64_t>(r);
    Scenario run(options);
    run.run_to(30.0);
    fmt::print("seed {}: mean NEES (p, v, theta; 9 dof) {:.2f} over {} samples\n", 100 + r,
               run.mean_nees(), run.samples());
    nees_total += run.mean_nees() * static_cast<double>(run.samples());
    samples += run.samples();
  }
  // About 1000 samples, correlated in time: a loose band around the 9-dof mean.
  const double mean = nees_total / static_cast<double>(samples);
  fmt::print("mean NEES over {} runs {:.2f} (9 expected; accepted band [4.5, 18])\n", kRuns, mean);
  EXPECT_GT(mean, 4.5);
  EXPECT_LT(mean, 18.0);
}

TEST(NavigationFilter, PredictAndUpdatesAllocateNothing) {
  Scenario run;
  run.run_to(1.0);
  const long before = hq::testing::allocation_count();
  run.run_to(3.0);
  const long allocations = hq::testing::allocation_count() - before;
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(run.filter().health().markers_accepted, 20);
}

std::string write_yaml(const std::string& name, const std::string& text) {
  const std::filesystem::path path = std::filesystem::temp_directory_path() / name;
  std::ofstream(path) << text;
  return path.string();
}

TEST(NavigationConfig, ReadsNavigationSectionWithDegreesConverted) {
  const std::string path = write_yaml("hq_navigation_ok.yaml",
                                      "odometry: {anything: 1}\n"
                                      "navigation:\n"
                                      "  gyro_noise_density_radps_rthz: 3.0e-4\n"
                                      "  initial_attitude_sigma_deg: 10\n"
                                      "  degraded_after_s: 4\n"
                                      "  reanchor_after_gated_markers: 0\n"
                                      "  position_max_age_s: 2.5\n"
                                      "  position_max_sigma_m: 0.4\n"
                                      "  position_inconsistent_after_frames: 5\n"
                                      "  position_inconsistent_after_velocities: 7\n");
  const NavigationConfig config = load_navigation_config(path);
  EXPECT_DOUBLE_EQ(config.gyro_noise_density_radps_rthz, 3.0e-4);
  EXPECT_NEAR(config.initial_attitude_sigma_rad, 10.0 * kPi / 180.0, 1e-12);
  EXPECT_DOUBLE_EQ(config.degraded_after_s, 4.0);
  EXPECT_EQ(config.reanchor_after_gated_markers, 0);
  EXPECT_DOUBLE_EQ(config.position_max_age_s, 2.5);
  EXPECT_DOUBLE_EQ(config.position_max_sigma_m, 0.4);
  EXPECT_EQ(config.position_inconsistent_after_frames, 5);
  EXPECT_EQ(config.position_inconsistent_after_velocities, 7);
}

TEST(NavigationConfig, ErrorsNameTheKey) {
  const std::string negative =
      write_yaml("hq_navigation_neg.yaml", "navigation: {accel_noise_density_mps2_rthz: -1}\n");
  EXPECT_THAT(hq::testing::input_error_message([&] { load_navigation_config(negative); }),
              HasSubstr("navigation.accel_noise_density_mps2_rthz"));
  const std::string unknown =
      write_yaml("hq_navigation_unknown.yaml", "navigation: {marker_gate: 3}\n");
  EXPECT_THAT(hq::testing::input_error_message([&] { load_navigation_config(unknown); }),
              HasSubstr("navigation.marker_gate"));
  const std::string gate =
      write_yaml("hq_navigation_gate.yaml", "navigation: {velocity_gate_chi2: 0}\n");
  EXPECT_THAT(hq::testing::input_error_message([&] { load_navigation_config(gate); }),
              HasSubstr("navigation.velocity_gate_chi2"));
  const std::string age =
      write_yaml("hq_navigation_age.yaml", "navigation: {position_max_age_s: 0}\n");
  EXPECT_THAT(hq::testing::input_error_message([&] { load_navigation_config(age); }),
              HasSubstr("navigation.position_max_age_s = 0"));
  const std::string gated = write_yaml("hq_navigation_gated.yaml",
                                       "navigation: {position_inconsistent_after_frames: 0}\n");
  EXPECT_THAT(hq::testing::input_error_message([&] { load_navigation_config(gated); }),
              HasSubstr("navigation.position_inconsistent_after_frames"));
  const std::string missing = write_yaml("hq_navigation_missing.yaml", "estimator: {}\n");
  const std::string message =
      hq::testing::input_error_message([&] { load_navigation_config(missing); });
  EXPECT_THAT(message, HasSubstr("navigation"));
  EXPECT_THAT(message, HasSubstr("hq_navigation_missing.yaml"));
}

}  // namespace
}  // namespace hq::navigation
