#include "hq/base/monotonic_clock.hpp"
#include "hq/haptics/haptic_loop.hpp"
#include "hq/testing/allocation_counter.hpp"

#include "test_support.hpp"
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fmt/format.h>
#include <limits>
#include <numbers>
#include <thread>

namespace hq::haptics {
namespace {

using ::testing::HasSubstr;

HapticsConfig pushing_config() {
  HapticsConfig config;
  config.loop.realtime = false;  // unit tests never ask for real-time priority
  config.loop.lock_memory = false;
  HandKeyframe rest;
  HandKeyframe pushed;
  pushed.t_s = 0.05;
  pushed.p_D_m = Eigen::Vector3d(0.04, 0.0, 0.0);
  config.sim.script = {rest, pushed};
  return config;
}

TEST(HapticLoop, ThreadRunsAndProducesForwardCommands) {
  const HapticsConfig config = pushing_config();
  SimulatedDevice device(config.sim);
  HapticLoop loop(device, config, test::core_paper_R_B_C());
  const RealtimeGrant grant = loop.start();
  EXPECT_FALSE(grant.fifo);
  EXPECT_THAT(grant.summary, HasSubstr("SCHED_OTHER"));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const LoopOutput out = loop.latest();
  loop.stop();
  EXPECT_GT(out.tick, 10u);
  EXPECT_TRUE(out.device_connected);
  EXPECT_TRUE(out.command_valid);
  // The hand pushed forward: the command points along alpha.
  EXPECT_GT(out.command.v_H_mps.head<2>().dot(Eigen::Vector2d(
                std::cos(loop.mapping().alpha_rad()), std::sin(loop.mapping().alpha_rad()))),
            0.1);
  EXPECT_GT(loop.timing().period.count(), 0);
}

TEST(HapticLoop, TickAllocatesNothing) {
  const HapticsConfig config = pushing_config();
  SimulatedDevice device(config.sim);
  HapticLoop loop(device, config, test::core_paper_R_B_C());
  VehicleEstimate estimate;
  estimate.valid = true;
  loop.tick(0);
  const long before = testing::allocation_count();
  for (int k = 1; k <= 1000; ++k) {
    estimate.t_ns = k * test::kMsNs;
    loop.set_vehicle_estimate(estimate);
    loop.tick(k * test::kMsNs);
    const LoopOutput out = loop.latest();
    ASSERT_TRUE(out.command_valid);
  }
  EXPECT_EQ(testing::allocation_count() - before, 0);
}

TEST(HapticLoop, DeviceLossZeroesCommandAndForceAndSaysSo) {
  HapticsConfig config = pushing_config();
  HandKeyframe lost;
  lost.t_s = 0.3;
  lost.p_D_m = Eigen::Vector3d(0.04, 0.0, 0.0);
  lost.connected = false;
  config.sim.script.push_back(lost);
  SimulatedDevice device(config.sim);
  HapticLoop loop(device, config, test::core_paper_R_B_C());
  for (int k = 0; k < 250; ++k) loop.tick(k * test::kMsNs);
  ASSERT_GT(loop.latest().command.v_H_mps.norm(), 0.1);
  for (int k = 250; k < 350; ++k) loop.tick(k * test::kMsNs);
  const LoopOutput out = loop.latest();
  EXPECT_FALSE(out.device_connected);
  EXPECT_EQ(out.command.v_H_mps, Eigen::Vector3d::Zero());
  EXPECT_EQ(out.command.yaw_rate_radps, 0.0);
  EXPECT_EQ(out.F_D_n, Eigen::Vector3d::Zero());
  EXPECT_THAT(out.status.data(), HasSubstr("command zero"));
}

/// A device whose encoder reads NaN.
class NanDevice final : public HapticDevice {
 public:
  bool read(std::int64_t, DeviceSample& out) override {
    out.p_D_m = Eigen::Vector3d(std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0);
    return true;
  }
  void write_force(std::int64_t, const Eigen::Vector3d& F_D_n) override { last_F_D_n = F_D_n; }
  [[nodiscard]] const char* name() const override { return "nan"; }
  [[nodiscard]] bool connected() const override { return true; }
  Eigen::Vector3d last_F_D_n = Eigen::Vector3d::Constant(1.0);
};

TEST(HapticLoop, NanPositionGivesZeroCommandZeroForceAndStatus) {
  NanDevice device;
  HapticLoop loop(device, pushing_config(), test::core_paper_R_B_C());
  loop.tick(0);
  loop.tick(test::kMsNs);
  const LoopOutput out = loop.latest();
  EXPECT_FALSE(out.command_valid);
  EXPECT_EQ(out.command.v_H_mps, Eigen::Vector3d::Zero());
  EXPECT_EQ(device.last_F_D_n, Eigen::Vector3d::Zero());
  EXPECT_THAT(out.status.data(), HasSubstr("not finite"));
}

/// An effector swung by the hand along x, 3 cm at 3 Hz (up to 0.57 m/s): fast enough that the
/// passivity damper, at its cap, asks for more than the law's saturated force.
class SwingingDevice final : public HapticDevice {
 public:
  bool read(std::int64_t t_ns, DeviceSample& out) override {
    out.p_D_m =
        Eigen::Vector3d(kAmplitudeM * std::sin(kOmegaRadps * hq::to_seconds(t_ns)), 0.0, 0.0);
    return true;
  }
  void write_force(std::int64_t, const Eigen::Vector3d& F_D_n) override {
    peak_force_n = std::max(peak_force_n, F_D_n.norm());
    all_finite = all_finite && F_D_n.allFinite();
  }
  [[nodiscard]] const char* name() const override { return "swinging"; }
  [[nodiscard]] bool connected() const override { return true; }
  [[nodiscard]] static double v_x_mps(std::int64_t t_ns) {
    return kAmplitudeM * kOmegaRadps * std::cos(kOmegaRadps * hq::to_seconds(t_ns));
  }

  static constexpr double kAmplitudeM = 0.03;
  static constexpr double kOmegaRadps = 2.0 * std::numbers::pi * 3.0;
  double peak_force_n = 0.0;
  bool all_finite = true;
};

// GIVEN a forger's states (insecure link, copied session) claiming the vehicle flies at 20 m/s
// (plausible, so admitted) along whichever way the hand moves, so the cue saturates and pushes
// the hand along its own motion and the port turns active, WHEN the passivity damper adds its
// term on top of the saturated cue, THEN the device is never commanded beyond max_force_n.
TEST(HapticLoop, ForceOnTheHandNeverExceedsTheCapWhateverIsAddedBeforeIt) {
  HapticsConfig config = pushing_config();
  SwingingDevice device;
  HapticLoop loop(device, config, test::core_paper_R_B_C());
  const double alpha_rad = loop.mapping().alpha_rad();
  VehicleEstimate forged;
  forged.valid = true;
  double peak_damping_ns_per_m = 0.0;
  for (int k = 0; k < 3000; ++k) {
    const std::int64_t t_ns = k * test::kMsNs;
    const double along = SwingingDevice::v_x_mps(t_ns) >= 0.0 ? 20.0 : -20.0;
    forged.t_ns = t_ns;
    forged.v_H_mps = Eigen::Vector3d(along * std::cos(alpha_rad), along * std::sin(alpha_rad), 0);
    loop.set_vehicle_estimate(forged);
    loop.tick(t_ns);
    peak_damping_ns_per_m =
        std::max(peak_damping_ns_per_m, loop.latest().passivity_damping_ns_per_m);
  }
  fmt::print("force peak {:.3f} N (cap {:.1f} N), damper peak {:.1f} N s/m\n", device.peak_force_n,
             config.feedback.max_force_n, peak_damping_ns_per_m);
  EXPECT_GT(peak_damping_ns_per_m, 0.0);  // the damper did act: the case is the issue's
  EXPECT_LE(device.peak_force_n, config.feedback.max_force_n + 1e-9);
  EXPECT_GT(device.peak_force_n, 0.99 * config.feedback.max_force_n);  // the cap was reached
  EXPECT_TRUE(device.all_finite);
  EXPECT_GT(loop.latest().force_saturated_ticks, 0U);
}

// GIVEN a term of the force that turns NaN (here the law's damping, as a corrupted
// configuration would make it), WHEN the loop runs with the effector moving, THEN the device is
// commanded zero, never NaN, and the loop counts the ticks and says why in its status.
TEST(HapticLoop, NonFiniteForceTermGivesZeroForceAndSaysSo) {
  HapticsConfig config = pushing_config();
  config.feedback.damping_ns_per_m = std::numeric_limits<double>::quiet_NaN();
  SwingingDevice device;
  HapticLoop loop(device, config, test::core_paper_R_B_C());
  for (int k = 0; k < 100; ++k) loop.tick(k * test::kMsNs);
  const LoopOutput out = loop.latest();
  EXPECT_TRUE(device.all_finite);
  EXPECT_EQ(device.peak_force_n, 0.0);
  EXPECT_EQ(out.F_D_n, Eigen::Vector3d::Zero());
  EXPECT_EQ(out.force_nonfinite_ticks, 100U);  // NaN times a zero p_dot is NaN too
  EXPECT_THAT(out.status.data(), HasSubstr("force not finite"));
  EXPECT_TRUE(out.command_valid);  // the command does not depend on the force
}

TEST(HapticLoop, CueWeightFadesWhenEstimatesStop) {
  const HapticsConfig config = pushing_config();
  SimulatedDevice device(config.sim);
  HapticLoop loop(device, config, test::core_paper_R_B_C());
  VehicleEstimate estimate;
  estimate.valid = true;
  estimate.t_ns = 100 * test::kMsNs;
  loop.set_vehicle_estimate(estimate);
  loop.tick(100 * test::kMsNs);
  EXPECT_EQ(loop.latest().cue_weight, 1.0);
  const auto fade_end_ms =
      static_cast<int>(1e3 * (config.feedback.stale_after_s + config.feedback.fade_s)) + 100;
  double previous = 1.0;
  for (int ms = 101; ms <= fade_end_ms + 1; ++ms) {
    loop.tick(ms * test::kMsNs);
    EXPECT_LE(loop.latest().cue_weight, previous);
    previous = loop.latest().cue_weight;
  }
  EXPECT_EQ(loop.latest().cue_weight, 0.0);
}

TEST(JitterStats, QuantilesComeFromTheHistogram) {
  JitterStats stats;
  for (int i = 1; i <= 100; ++i) stats.add(i * 1000);  // 1..100 us
  stats.add(-50'000'000);                              // beyond the range, sign dropped
  EXPECT_EQ(stats.count(), 101);
  EXPECT_NEAR(stats.quantile_us(0.5), 51.0, 0.51);
  EXPECT_NEAR(stats.quantile_us(0.99), 100.0, 0.51);
  EXPECT_DOUBLE_EQ(stats.max_us(), 50'000.0);
  EXPECT_DOUBLE_EQ(stats.quantile_us(1.0), 50'000.0);
}

}  // namespace
}  // namespace hq::haptics
