#include "hq/estimator/one_euro_filter.hpp"

#include "hq/config/strict_yaml.hpp"
#include "hq/geometry/lie.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <random>

namespace hq::estimator {
namespace {

using testing::HasSubstr;

constexpr std::int64_t kFrameNs = 33'333'333;  // 30 Hz

TEST(OneEuroFilter, FirstSamplePassesThrough) {
  OneEuroFilter<3> filter;
  const Eigen::Vector3d x(1.5, -2.0, 0.25);
  EXPECT_EQ(filter.update(1000, x), FilterStatus::kFirstSample);
  EXPECT_EQ(filter.value(), x);
}

TEST(OneEuroFilter, SmoothsNoiseOnAConstantSignal) {
  // GIVEN a constant 1.0 with N(0, 0.05) noise at 30 Hz, beta small as Casiez recommends to tune.
  OneEuroFilter<1> filter(OneEuroConfig{1.0, 0.007, 1.0});
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.05);
  double raw_sq = 0.0;
  double filtered_sq = 0.0;
  int n = 0;
  for (int k = 0; k < 3000; ++k) {
    const double x = 1.0 + noise(rng);
    filter.update(k * kFrameNs, x);
    if (k < 100) continue;  // settle
    raw_sq += (x - 1.0) * (x - 1.0);
    filtered_sq += (filter.value()[0] - 1.0) * (filter.value()[0] - 1.0);
    ++n;
  }
  const double ratio = filtered_sq / raw_sq;
  // A 1 Hz first-order low-pass at 30 Hz passes alpha / (2 - alpha) = 0.095 of white-noise
  // variance; measured 0.086 here. Bound with margin:
  EXPECT_LT(ratio, 0.15) << "variance ratio " << ratio << " over " << n << " samples";
}

double ramp_lag(double beta) {
  OneEuroFilter<1> filter(OneEuroConfig{1.0, beta, 1.0});
  double lag = 0.0;
  for (int k = 0; k < 300; ++k) {
    const double t_s = k * 1e-9 * kFrameNs;
    filter.update(k * kFrameNs, 1.0 * t_s);  // 1 m/s ramp
    lag = t_s - filter.value()[0];
  }
  return lag;
}

TEST(OneEuroFilter, FollowsARampWithBoundedLagAtHighBeta) {
  const double lag_low_beta = ramp_lag(0.0);
  const double lag_high_beta = ramp_lag(5.0);
  // beta = 0 is a 1 Hz low-pass: steady lag (1 - alpha) v dt / alpha = 0.16 m (measured 0.159).
  EXPECT_NEAR(lag_low_beta, 0.159, 0.005);
  // beta = 5 raises the cutoff with speed; measured lag 0.018 m.
  EXPECT_GT(lag_high_beta, 0.0);
  EXPECT_LT(lag_high_beta, 0.04) << lag_high_beta;
}

TEST(OneEuroFilter, HandlesIrregularDtAndDroppedFrames) {
  OneEuroFilter<1> regular(OneEuroConfig{1.0, 0.0, 1.0});
  OneEuroFilter<1> dropped(OneEuroConfig{1.0, 0.0, 1.0});
  regular.update(0, 0.0);
  dropped.update(0, 0.0);
  // A step to 1: one frame later vs three frames later (two dropped). The longer dt must move
  // the estimate further, as a continuous-time low-pass would (alpha = 1 / (1 + tau / dt)).
  regular.update(kFrameNs, 1.0);
  dropped.update(3 * kFrameNs, 1.0);
  EXPECT_NEAR(regular.value()[0], smoothing_factor(1.0, 1e-9 * kFrameNs), 1e-12);
  EXPECT_NEAR(dropped.value()[0], smoothing_factor(1.0, 3e-9 * kFrameNs), 1e-12);
  EXPECT_GT(dropped.value()[0], regular.value()[0]);

  // Jittered stamps on a constant stay exactly constant.
  OneEuroFilter<2> jitter;
  std::int64_t t_ns = 0;
  std::mt19937 rng(3);
  std::uniform_int_distribution<std::int64_t> step(1'000'000, 90'000'000);
  for (int k = 0; k < 200; ++k) {
    t_ns += step(rng);
    ASSERT_TRUE(accepted(jitter.update(t_ns, Eigen::Vector2d(0.3, -0.7))));
  }
  EXPECT_NEAR(jitter.value()[0], 0.3, 1e-12);
  EXPECT_NEAR(jitter.value()[1], -0.7, 1e-12);
}

TEST(OneEuroFilter, RejectsNonPositiveDtAndNonFiniteInputAndKeepsState) {
  OneEuroFilter<1> filter;
  filter.update(100, 2.0);
  filter.update(200, 3.0);
  const double before = filter.value()[0];
  EXPECT_EQ(filter.update(200, 10.0), FilterStatus::kRejectedTime);
  EXPECT_EQ(filter.update(150, 10.0), FilterStatus::kRejectedTime);
  EXPECT_EQ(filter.update(300, std::nan("")), FilterStatus::kRejectedNonFinite);
  EXPECT_EQ(filter.value()[0], before);
  EXPECT_STREQ(to_string(FilterStatus::kRejectedTime),
               "rejected: stamp not after the previous sample");
}

double orthonormality_error(const Eigen::Matrix3d& R) {
  return (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
}

TEST(PoseOneEuroFilter, StaysOrthonormalAndConvergesToAConstantRotation) {
  PoseOneEuroFilter filter(OneEuroConfig{1.0, 1.0, 1.0}, OneEuroConfig{1.0, 1.0, 1.0});
  const Eigen::Matrix3d R_true = geometry::exp_so3(Eigen::Vector3d(0.4, -1.1, 2.0));
  const Eigen::Vector3d p_true(1.0, 2.0, -0.5);
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.05);
  // Starts far away (identity), then noisy samples, then exact samples.
  filter.update(0, Eigen::Isometry3d::Identity());
  for (int k = 1; k < 600; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    const Eigen::Vector3d n(noise(rng), noise(rng), noise(rng));
    T.linear() = R_true * (k < 300 ? geometry::exp_so3(n) : Eigen::Matrix3d::Identity());
    T.translation() = p_true + (k < 300 ? n : Eigen::Vector3d::Zero());
    ASSERT_EQ(filter.update(k * kFrameNs, T), FilterStatus::kOk);
    ASSERT_LT(orthonormality_error(filter.pose().linear()), 1e-12) << k;
  }
  EXPECT_LT(geometry::log_so3(R_true.transpose() * filter.pose().linear()).norm(), 1e-6);
  EXPECT_LT((filter.pose().translation() - p_true).norm(), 1e-6);
}

TEST(PoseOneEuroFilter, SmoothsRotationNoise) {
  PoseOneEuroFilter filter(OneEuroConfig{1.0, 0.0, 1.0}, OneEuroConfig{1.0, 0.0, 1.0});
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.02);
  double raw_sq = 0.0;
  double filtered_sq = 0.0;
  for (int k = 0; k < 2000; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    const Eigen::Vector3d n(noise(rng), noise(rng), noise(rng));
    T.linear() = geometry::exp_so3(n);
    filter.update(k * kFrameNs, T);
    if (k < 100) continue;
    raw_sq += n.squaredNorm();
    filtered_sq += geometry::log_so3(filter.pose().linear()).squaredNorm();
  }
  EXPECT_LT(filtered_sq / raw_sq, 0.15);  // measured 0.094, as the scalar low-pass predicts
}

TEST(PoseOneEuroFilter, RejectsANonRotation) {
  PoseOneEuroFilter filter(OneEuroConfig{}, OneEuroConfig{});
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() *= 2.0;
  EXPECT_EQ(filter.update(0, T), FilterStatus::kRejectedNonFinite);
  EXPECT_FALSE(filter.initialized());
}

TEST(OneEuroConfig, BadValueIsRejectedNamingTheKey) {
  const YAML::Node node = YAML::Load("{min_cutoff_hz: -1.0}");
  config::StrictMap section(node, "config/onboard.yaml", "estimator.one_euro_position");
  OneEuroConfig config;
  try {
    read_config(section, config);
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("estimator.one_euro_position.min_cutoff_hz = -1.0"));
  }
}

}  // namespace
}  // namespace hq::estimator
