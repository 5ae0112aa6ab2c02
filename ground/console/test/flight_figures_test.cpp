// The console's flight figures: the flight timer from take-off, the touchdown event, the
// autonomous modes' target and phase carried to the snapshot.
#include "hq/console/console_model.hpp"

#include <gtest/gtest.h>

#include <string>

namespace hq::console {
namespace {

void add_state(ConsoleModel& m, double t_s, const char* flight_state) {
  StateExtras extras;
  extras.flight_state = flight_state;
  m.on_state(static_cast<std::int64_t>(t_s * 1e9), 1.0, {0, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0},
             "teleop", "ok", "ok", nullptr, 0, extras);
}

TEST(FlightFigures, TimerRunsFromTakeOffAndTouchdownIsSaidWithTheFlightsLength) {
  ConsoleModel m;
  Snapshot s = m.make_snapshot();
  // GIVEN 5 s on the ground
  for (int i = 0; i <= 5; ++i) add_state(m, i, "landed");
  m.snapshot(s);
  EXPECT_LT(s.flight_time_s, 0) << "no flight yet";
  EXPECT_FALSE(s.airborne);
  // WHEN it takes off at 6 s and flies to 70 s
  add_state(m, 6, "taking off");
  for (int i = 7; i <= 70; ++i) add_state(m, i, i < 68 ? "airborne" : "landing");
  m.snapshot(s);
  // THEN the timer says 64 s from the take-off
  EXPECT_TRUE(s.airborne);
  EXPECT_NEAR(s.flight_time_s, 64.0, 1e-6);
  const std::size_t events_before = s.event_count;
  // WHEN it touches down at 71 s
  add_state(m, 71, "landed");
  add_state(m, 80, "landed");
  m.snapshot(s);
  // THEN the timer holds the flight's length and one event says the touchdown
  EXPECT_FALSE(s.airborne);
  EXPECT_NEAR(s.flight_time_s, 65.0, 1e-6);
  ASSERT_EQ(s.event_count, events_before + 1);
  EXPECT_EQ(std::string(s.events[s.event_count - 1].text.data()),
            "touchdown: landed after 01:05 of flight");
  // and a second flight starts the timer afresh
  add_state(m, 90, "taking off");
  add_state(m, 92, "airborne");
  m.snapshot(s);
  EXPECT_NEAR(s.flight_time_s, 2.0, 1e-6);
}

TEST(FlightFigures, StatesThatSayNoFlightStateStartNoTimer) {
  ConsoleModel m;
  Snapshot s = m.make_snapshot();
  for (int i = 0; i < 10; ++i) add_state(m, i, "-");
  m.snapshot(s);
  EXPECT_LT(s.flight_time_s, 0);
  EXPECT_EQ(s.event_count, 0U);
}

TEST(FlightFigures, MarkerTargetAndExplorePhaseReachTheSnapshot) {
  ConsoleModel m;
  Snapshot s = m.make_snapshot();
  StateExtras extras;
  extras.marker_target_id = 12;
  extras.explore_phase = "search";
  m.on_state(1'000'000'000, 1.0, {0, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0}, "explore", "ok", "ok",
             nullptr, 0, extras);
  m.snapshot(s);
  EXPECT_EQ(s.marker_target_id, 12);
  EXPECT_EQ(std::string(s.explore_phase), "search");
  m.on_state(2'000'000'000, 1.0, {0, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0}, "teleop", "ok", "ok",
             nullptr, 0, StateExtras{});
  m.snapshot(s);
  EXPECT_EQ(s.marker_target_id, -1);
  EXPECT_EQ(std::string(s.explore_phase), "");
}

}  // namespace
}  // namespace hq::console
