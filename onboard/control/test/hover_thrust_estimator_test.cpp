#include "hq/control/hover_thrust_estimator.hpp"

#include "hq/base/error.hpp"
#include "hq/control/velocity_controller.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fmt/format.h>
#include <limits>
#include <numbers>
#include <random>

namespace hq::control {
namespace {

using testing::HasSubstr;

constexpr double kMassKg = 1.5;
constexpr std::int64_t kImuPeriodNs = 5'000'000;        // 200 Hz, as the FC is asked for
constexpr std::int64_t kSetpointPeriodNs = 33'333'333;  // a setpoint per 30 Hz camera frame

/// A vertical-only vehicle whose rotors give `true_gain` times the thrust the chain believes it
/// asks for, with the motors' first-order lag, frame vibration and accelerometer noise: what the
/// estimator would see on a vehicle whose mass or maximum thrust is off.
struct VerticalFlight {
  double true_gain = 1.0;
  double motor_lag_s = 0.03;
  double vibration_mps2 = 2.0;  // at 83 Hz, a propeller's blade-pass seen by a soft mount
  double noise_mps2 = 0.3;
  std::mt19937 rng{7};

  /// Flies `seconds` of hover with a 0.5 Hz climb-and-sink manoeuvre, sending the estimator's
  /// corrected thrust; returns the first time (s) from which the gain stayed within `tolerance`
  /// of true_gain, or a negative number if it never settled.
  double fly(HoverThrustEstimator& estimator, double seconds, double tolerance,
             bool airborne = true) {
    std::normal_distribution<double> noise(0.0, noise_mps2);
    double thrust_n = 0.0;  // what the rotors give (after the lag)
    double sent_n = 0.0;
    double settled_since_s = -1.0;
    const auto steps = static_cast<std::int64_t>(seconds * 1e9 / kImuPeriodNs);
    for (std::int64_t i = 0; i < steps; ++i) {
      const std::int64_t t_ns = start_ns + i * kImuPeriodNs;
      const double t_s = static_cast<double>(t_ns) * 1e-9;
      if (t_ns % kSetpointPeriodNs < kImuPeriodNs) {
        const double wanted_n =
            kMassKg * kGravityMps2 * (1.0 + 0.15 * std::sin(2.0 * std::numbers::pi * 0.5 * t_s));
        sent_n = estimator.corrected_thrust_n(wanted_n);
        estimator.on_command(t_ns, sent_n);
      }
      const double dt_s = static_cast<double>(kImuPeriodNs) * 1e-9;
      thrust_n += (true_gain * sent_n - thrust_n) * (1.0 - std::exp(-dt_s / motor_lag_s));
      const double vibration = vibration_mps2 * std::sin(2.0 * std::numbers::pi * 83.0 * t_s);
      const double f_z = airborne ? -thrust_n / kMassKg + vibration + noise(rng) : -kGravityMps2;
      estimator.on_specific_force(t_ns, f_z, airborne);
      const bool within = std::abs(estimator.estimate().gain - true_gain) <= tolerance * true_gain;
      if (!within) {
        settled_since_s = -1.0;
      } else if (settled_since_s < 0.0) {
        settled_since_s = static_cast<double>(i * kImuPeriodNs) * 1e-9;
      }
    }
    start_ns += steps * kImuPeriodNs;
    return settled_since_s;
  }
  std::int64_t start_ns = 1'000'000'000;
};

TEST(HoverThrustEstimator, LearnsAMaximumThrustSetThirtyPercentTooHighWithinSeconds) {
  // --fc-max-thrust-n 30 % above the truth: the rotors give 1/1.3 of what is asked.
  HoverThrustEstimator estimator({}, kMassKg);
  VerticalFlight flight;
  flight.true_gain = 1.0 / 1.3;
  const double settled_s = flight.fly(estimator, 20.0, 0.10);
  fmt::print(
      "[ figures ] 30 % too high a maximum thrust: gain {:.3f} (true {:.3f}, sigma {:.3f}), within "
      "10 % after {:.2f} s, {} fused, {} gated\n",
      estimator.estimate().gain, flight.true_gain, estimator.estimate().sigma, settled_s,
      static_cast<unsigned long long>(estimator.estimate().updates),
      static_cast<unsigned long long>(estimator.estimate().rejected));
  ASSERT_GE(settled_s, 0.0);
  EXPECT_LT(settled_s, 5.0);
  EXPECT_NEAR(estimator.estimate().gain, flight.true_gain, 0.03 * flight.true_gain);
  EXPECT_TRUE(estimator.estimate().converged);
  EXPECT_NEAR(estimator.hover_thrust_n(), kMassKg * kGravityMps2 / flight.true_gain, 0.5);
}

TEST(HoverThrustEstimator, LearnsAMaximumThrustSetThirtyPercentTooLowWithinSeconds) {
  HoverThrustEstimator estimator({}, kMassKg);
  VerticalFlight flight;
  flight.true_gain = 1.0 / 0.7;
  const double settled_s = flight.fly(estimator, 20.0, 0.10);
  fmt::print(
      "[ figures ] 30 % too low a maximum thrust: gain {:.3f} (true {:.3f}), within 10 % after "
      "{:.2f} s\n",
      estimator.estimate().gain, flight.true_gain, settled_s);
  ASSERT_GE(settled_s, 0.0);
  EXPECT_LT(settled_s, 5.0);
  EXPECT_NEAR(estimator.estimate().gain, flight.true_gain, 0.03 * flight.true_gain);
}

TEST(HoverThrustEstimator, CorrectedThrustMakesTheRotorsGiveWhatTheChainAsked) {
  HoverThrustEstimator estimator({}, kMassKg);
  VerticalFlight flight;
  flight.true_gain = 1.25;
  flight.fly(estimator, 10.0, 0.1);
  const double wanted_n = kMassKg * kGravityMps2;
  EXPECT_NEAR(flight.true_gain * estimator.corrected_thrust_n(wanted_n), wanted_n, 0.03 * wanted_n);
}

TEST(HoverThrustEstimator, OnTheFloorNothingIsLearnt) {
  // On the floor the ground carries the weight: f_z = -g whatever the rotors give, which
  // would read as a gain of g m / u. Not airborne: not fused.
  HoverThrustEstimator estimator({}, kMassKg);
  VerticalFlight flight;
  flight.true_gain = 1.0;
  flight.fly(estimator, 5.0, 0.1, /*airborne=*/false);
  EXPECT_EQ(estimator.estimate().updates, 0U);
  EXPECT_DOUBLE_EQ(estimator.estimate().gain, 1.0);
  EXPECT_DOUBLE_EQ(estimator.corrected_thrust_n(10.0), 10.0);
}

TEST(HoverThrustEstimator, NonFiniteSamplesAreIgnored) {
  HoverThrustEstimator estimator({}, kMassKg);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  estimator.on_command(0, nan);
  estimator.on_specific_force(0, -kGravityMps2, true);
  estimator.on_command(0, kMassKg * kGravityMps2);
  for (int i = 1; i < 400; ++i) {
    estimator.on_specific_force(i * kImuPeriodNs, i % 2 == 0 ? nan : -kGravityMps2, true);
  }
  EXPECT_TRUE(std::isfinite(estimator.estimate().gain));
  EXPECT_TRUE(std::isfinite(estimator.estimate().sigma));
}

TEST(HoverThrustEstimator, AGainChangeInFlightIsLearntAgain) {
  // A payload dropped: once converged the innovations jump beyond the gate; after a second of
  // them the variance is reset and the new gain is learnt.
  HoverThrustEstimator estimator({}, kMassKg);
  VerticalFlight flight;
  flight.true_gain = 1.0;
  flight.fly(estimator, 10.0, 0.1);
  ASSERT_TRUE(estimator.estimate().converged);
  flight.true_gain = 1.35;
  const double settled_s = flight.fly(estimator, 15.0, 0.10);
  fmt::print("[ figures ] gain 1.00 -> 1.35 in flight: within 10 % after {:.2f} s, relearned {}\n",
             settled_s, static_cast<unsigned long long>(estimator.estimate().relearned));
  ASSERT_GE(settled_s, 0.0);
  EXPECT_LT(settled_s, 6.0);
  EXPECT_GE(estimator.estimate().relearned, 1U);
}

TEST(HoverThrustEstimator, TheGainStaysWithinItsBounds) {
  // A vehicle whose rotors give 3x what is asked is not what its config says: clamped, counted.
  HoverThrustEstimator estimator({}, kMassKg);
  VerticalFlight flight;
  flight.true_gain = 3.0;
  flight.fly(estimator, 10.0, 0.1);
  EXPECT_LE(estimator.estimate().gain, 2.0);
  EXPECT_GT(estimator.estimate().clamped, 0U);
}

TEST(HoverThrustEstimator, DisabledLeavesTheThrustAlone) {
  HoverThrustConfig config;
  config.enabled = false;
  HoverThrustEstimator estimator(config, kMassKg);
  VerticalFlight flight;
  flight.true_gain = 1.3;
  flight.fly(estimator, 5.0, 0.1);
  EXPECT_EQ(estimator.estimate().updates, 0U);
  EXPECT_DOUBLE_EQ(estimator.corrected_thrust_n(12.0), 12.0);
}

TEST(HoverThrustEstimator, ABadConfigNamesTheKey) {
  HoverThrustConfig config;
  config.initial_sigma = -1.0;
  try {
    HoverThrustEstimator estimator(config, kMassKg);
    FAIL() << "accepted initial_sigma -1";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("hover_thrust.initial_sigma = -1"));
  }
  EXPECT_THROW(HoverThrustEstimator({}, 0.0), InputError);
  config = {};
  config.converged_sigma = 0.5;  // not below initial_sigma: could never converge
  EXPECT_THROW(config.validate(), InputError);
}

}  // namespace
}  // namespace hq::control
