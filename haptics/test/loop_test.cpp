#include "hq/haptics/haptic_loop.hpp"
#include "hq/testing/allocation_counter.hpp"

#include "test_support.hpp"
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <limits>
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
  HapticLoop loop(device, config, test::core_paper_R_body_camera());
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
  HapticLoop loop(device, config, test::core_paper_R_body_camera());
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
  HapticLoop loop(device, config, test::core_paper_R_body_camera());
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
  HapticLoop loop(device, pushing_config(), test::core_paper_R_body_camera());
  loop.tick(0);
  loop.tick(test::kMsNs);
  const LoopOutput out = loop.latest();
  EXPECT_FALSE(out.command_valid);
  EXPECT_EQ(out.command.v_H_mps, Eigen::Vector3d::Zero());
  EXPECT_EQ(device.last_F_D_n, Eigen::Vector3d::Zero());
  EXPECT_THAT(out.status.data(), HasSubstr("not finite"));
}

TEST(HapticLoop, CueWeightFadesWhenEstimatesStop) {
  const HapticsConfig config = pushing_config();
  SimulatedDevice device(config.sim);
  HapticLoop loop(device, config, test::core_paper_R_body_camera());
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
