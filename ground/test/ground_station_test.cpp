#include "hq/ground/ground_station.hpp"

#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace hq::ground {
namespace {

using ::testing::HasSubstr;

TEST(ModeToggle, Button0TogglesTeleopAndHoverOnRisingEdgesOnly) {
  ModeToggle toggle;
  EXPECT_FALSE(toggle.on_buttons(0, hq_msgs_MODE_HOVER));
  EXPECT_EQ(toggle.on_buttons(1, hq_msgs_MODE_HOVER), hq_msgs_MODE_TELEOP);
  EXPECT_FALSE(toggle.on_buttons(1, hq_msgs_MODE_HOVER));  // held: asks once
  EXPECT_FALSE(toggle.on_buttons(0, hq_msgs_MODE_TELEOP));
  EXPECT_EQ(toggle.on_buttons(1, hq_msgs_MODE_TELEOP), hq_msgs_MODE_HOVER);
  EXPECT_FALSE(toggle.on_buttons(0, hq_msgs_MODE_HOVER));
  EXPECT_EQ(toggle.on_buttons(1, hq_msgs_MODE_LAND), hq_msgs_MODE_TELEOP);  // out of land too
}

TEST(ModeToggle, Button1LandsAndWinsOverAToggle) {
  ModeToggle toggle;
  EXPECT_EQ(toggle.on_buttons(2, hq_msgs_MODE_TELEOP), hq_msgs_MODE_LAND);
  EXPECT_FALSE(toggle.on_buttons(2, hq_msgs_MODE_LAND));
  EXPECT_EQ(toggle.on_buttons(3, hq_msgs_MODE_LAND), hq_msgs_MODE_TELEOP);  // 0 rises, 1 held
  EXPECT_FALSE(toggle.on_buttons(0, hq_msgs_MODE_TELEOP));
  EXPECT_EQ(toggle.on_buttons(3, hq_msgs_MODE_TELEOP), hq_msgs_MODE_LAND);
}

TEST(GroundStation, ModeNamesCoverOutOfRangeValues) {
  EXPECT_STREQ(to_string(hq_msgs_MODE_LAND), "land");
  EXPECT_STREQ(to_string(static_cast<hq_msgs_Mode>(42)), "invalid");
  EXPECT_STREQ(to_string(static_cast<hq_msgs_Health>(-3)), "invalid");
}

TEST(LatencyStats, QuantilesFollowTheSamples) {
  LatencyStats stats;
  EXPECT_EQ(stats.quantile_ms(0.5), 0.0);
  for (int i = 1; i <= 100; ++i) stats.add(i * 100'000LL);  // 0.1 .. 10 ms
  EXPECT_NEAR(stats.quantile_ms(0.5), 5.0, 0.02);
  EXPECT_NEAR(stats.quantile_ms(0.99), 9.9, 0.02);
  stats.add(-5);  // clock step: clamped into the first bin, not out of the array
  stats.add(1'000'000'000'000LL);
  EXPECT_EQ(stats.count(), 102);
}

TEST(LatencyStats, CoarseBinsReachSeconds) {
  // Round trips and state ages over a slow link: 1 ms bins up to 10 s.
  LatencyStats stats(1'000'000, 10'000);
  for (int i = 1; i <= 100; ++i) stats.add(i * 12'000'000LL);  // 12 .. 1200 ms
  EXPECT_NEAR(stats.quantile_ms(0.5), 601.0, 1.0);
  EXPECT_NEAR(stats.quantile_ms(0.99), 1189.0, 1.0);
}

TEST(TelemetryRecorder, UnwritableDirectoryIsNamed) {
  EXPECT_THAT(hq::testing::input_error_message(
                  [] { TelemetryRecorder r("/proc/no/such/dir"); }),
              HasSubstr("--record /proc/no/such/dir"));
}

TEST(MarkerTaskOf, NamesTheCommandLineTasksAndRejectsOthers) {
  EXPECT_EQ(marker_task_of("hold"), hq_msgs_MARKER_TASK_HOLD);
  EXPECT_EQ(marker_task_of("goto"), hq_msgs_MARKER_TASK_GO_TO);
  EXPECT_EQ(marker_task_of("land"), hq_msgs_MARKER_TASK_LAND);
  EXPECT_FALSE(marker_task_of("none").has_value());
  EXPECT_FALSE(marker_task_of("Land").has_value());
}

}  // namespace
}  // namespace hq::ground
