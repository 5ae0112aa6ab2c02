// SimFrameSource: lock-step frames at the camera rate, the IMU samples between them, the
// controller ticks, end of stream and no allocation per frame.
#include "hq/sim/sim_frame_source.hpp"

#include "hq/base/error.hpp"
#include "hq/sim/scripted_flight.hpp"
#include "hq/testing/allocation_counter.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <limits>

namespace {

using hq::sources::FrameStatus;
using hq::sources::RgbdFrame;
using ::testing::HasSubstr;

constexpr std::int64_t kStepNs = 1'000'000;       // default_sim_config: 1 kHz physics
constexpr std::int64_t kImuPeriodNs = 2'000'000;  // 500 Hz IMU

hq::sim::World room() { return hq::sim::load_world("onboard/sim/worlds/room.yaml"); }

/// The stamp the simulator gives frame k: the first physics step at or after k / rate.
std::int64_t expected_stamp_ns(int k, double rate_hz) {
  const std::int64_t period_ns = std::llround(1e9 / rate_hz);
  const std::int64_t nominal_ns = k * period_ns;
  return (nominal_ns + kStepNs - 1) / kStepNs * kStepNs;
}

TEST(SimFrameSource, DeliversFramesAt30HzStampsWithTheImuSamplesBetweenThem) {
  const hq::sim::SimConfig config = hq::sim::default_sim_config(160, 120);
  ASSERT_DOUBLE_EQ(config.camera.rate_hz, 30.0);
  hq::sim::Simulator sim(config, room());
  hq::sim::SimFrameSource source(sim);
  EXPECT_EQ(source.camera().width, 160);
  EXPECT_EQ(source.camera().fx, config.camera.pinhole.fx);
  EXPECT_THAT(source.describe(), HasSubstr("room"));

  RgbdFrame frame;
  std::int64_t previous_ns = -1;
  std::size_t total_imu = 0;
  for (int k = 0; k < 45; ++k) {
    ASSERT_EQ(source.next(frame), FrameStatus::kFrame) << k;
    EXPECT_EQ(frame.t_ns, expected_stamp_ns(k, 30.0)) << k;
    EXPECT_EQ(frame.t_ns, sim.t_ns()) << "rendered at its own physics step";
    EXPECT_TRUE(source.T_N_C().isApprox(sim.truth().T_N_B * config.camera.T_B_C));
    ASSERT_EQ(frame.bgr.type(), CV_8UC3);
    ASSERT_EQ(frame.gray.type(), CV_8UC1);
    ASSERT_EQ(frame.depth_m.type(), CV_32FC1);
    EXPECT_EQ(frame.gray.cols, 160);
    EXPECT_EQ(frame.depth_m.rows, 120);

    // Samples at every 2 ms in (previous frame, this frame].
    const std::int64_t first_tick = previous_ns < 0 ? 0 : previous_ns / kImuPeriodNs;
    const auto expected_count = static_cast<std::size_t>(frame.t_ns / kImuPeriodNs - first_tick);
    ASSERT_EQ(source.imu().size(), expected_count) << "frame " << k << " at " << frame.t_ns;
    for (const hq::sim::ImuSample& s : source.imu()) {
      EXPECT_GT(s.t_ns, previous_ns);
      EXPECT_LE(s.t_ns, frame.t_ns);
    }
    total_imu += source.imu().size();
    previous_ns = frame.t_ns;
  }
  EXPECT_EQ(total_imu, static_cast<std::size_t>(previous_ns / kImuPeriodNs));
  EXPECT_EQ(sim.dropped_frames(), 0);
}

TEST(SimFrameSource, TicksTheControllerAt200HzInLockStep) {
  hq::sim::Simulator sim(hq::sim::default_sim_config(160, 120), room());
  const hq::sim::FlightScript script =
      hq::sim::script_for_world(sim.world(), hq::sim::FlightScript::Kind::kHover);
  int ticks = 0;
  std::int64_t last_tick_ns = -1;
  hq::sim::SimFrameSource source(sim, 3'000'000'000, [&](hq::sim::Simulator& s, std::int64_t t) {
    EXPECT_EQ(t, s.t_ns());
    EXPECT_EQ(t % hq::sim::kScriptControlPeriodNs, 0);
    EXPECT_GT(t, last_tick_ns);
    last_tick_ns = t;
    ++ticks;
    s.set_command(hq::sim::scripted_command(s, script, static_cast<double>(t) * 1e-9));
  });
  RgbdFrame frame;
  int frames = 0;
  while (source.next(frame) == FrameStatus::kFrame) ++frames;
  // Frames up to and including t = 3 s; the controller ran at every 5 ms tick before the last.
  EXPECT_EQ(frames, 91);
  EXPECT_EQ(frame.t_ns, 3'000'000'000);
  EXPECT_EQ(ticks, 600);
  // The script took off at 1 s: the commands reached the vehicle.
  EXPECT_GT(sim.truth().T_N_B.translation().z(), 0.8);
  EXPECT_EQ(source.next(frame), FrameStatus::kEndOfStream) << "stays ended";
}

TEST(SimFrameSource, EndsAtEndTimeWithoutPassingIt) {
  hq::sim::Simulator sim(hq::sim::default_sim_config(160, 120), room());
  hq::sim::SimFrameSource source(sim, 500'000'000);
  RgbdFrame frame;
  int frames = 0;
  while (source.next(frame) == FrameStatus::kFrame) ++frames;
  EXPECT_EQ(frames, 16);  // t = 0, 34, 67, ..., 467, 500 ms
  EXPECT_LE(sim.t_ns(), 500'000'000);
}

TEST(SimFrameSource, RendersGrayCamerasIntoBothImages) {
  hq::sim::SimConfig config = hq::sim::default_sim_config(160, 120);
  config.camera.gray = true;
  hq::sim::Simulator sim(config, room());
  hq::sim::SimFrameSource source(sim);
  RgbdFrame frame;
  ASSERT_EQ(source.next(frame), FrameStatus::kFrame);
  ASSERT_EQ(frame.bgr.type(), CV_8UC3);
  ASSERT_EQ(frame.gray.type(), CV_8UC1);
  const cv::Vec3b bgr = frame.bgr.at<cv::Vec3b>(60, 80);
  EXPECT_EQ(bgr[0], frame.gray.at<std::uint8_t>(60, 80));
  EXPECT_EQ(bgr[2], frame.gray.at<std::uint8_t>(60, 80));
}

TEST(SimFrameSource, RejectsANonPositiveControlPeriod) {
  hq::sim::Simulator sim(hq::sim::default_sim_config(160, 120), room());
  try {
    hq::sim::SimFrameSource source(sim, 1'000'000'000, {}, 0);
    FAIL() << "expected hq::InputError";
  } catch (const hq::InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("control_period_ns = 0, expected > 0"));
  }
}

TEST(SimFrameSource, AllocatesNothingPerFrameAfterTheFirst) {
  hq::sim::Simulator sim(hq::sim::default_sim_config(160, 120), room());
  const hq::sim::FlightScript script =
      hq::sim::script_for_world(sim.world(), hq::sim::FlightScript::Kind::kCircle);
  hq::sim::SimFrameSource source(
      sim, std::numeric_limits<std::int64_t>::max(),
      [&script](hq::sim::Simulator& s, std::int64_t t) {
        s.set_command(hq::sim::scripted_command(s, script, static_cast<double>(t) * 1e-9));
      });
  RgbdFrame frame;
  ASSERT_EQ(source.next(frame), FrameStatus::kFrame);
  const long before = hq::testing::allocation_count();
  for (int k = 0; k < 30; ++k) ASSERT_EQ(source.next(frame), FrameStatus::kFrame);
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
}

}  // namespace
