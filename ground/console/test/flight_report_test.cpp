#include "hq/console/flight_report.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace hq::console {
namespace {

constexpr std::int64_t kMs = 1'000'000;

// 30 states/s; modes hover (0-2 s), teleop (2-5 s), hover (5-8 s); the link goes silent for
// 20.9 s after 8 s; then the vehicle restarts (session 2, sequence from 1) in land mode for 1 s.
// Two states of session 1 are lost on the way. The vehicle's clearance dips to 0.347 m while
// the cloud's nearest point from the body origin is 0.72 m.
Recording synthetic() {
  Recording r;
  std::int64_t t_ns = 1'000'000'000;
  std::uint64_t sequence = 1;
  std::int64_t vehicle_ns = 0;
  const auto add = [&](const char* mode, std::uint64_t session, double clearance_m) {
    RecordedState s;
    s.receipt_ns = t_ns;
    s.sequence = sequence++;
    s.vehicle_t_ns = vehicle_ns;
    s.mode = intern(mode);
    s.latency_ms = 3.0;
    s.session_id = session;
    s.flight_fields = true;
    s.clearance_m = clearance_m;
    s.closest_obstacle_m = 0.72 + (clearance_m - 0.347);
    s.height_m = 1.0;
    r.states.push_back(s);
    t_ns += 33 * kMs;
    vehicle_ns += 33 * kMs;
  };
  for (int i = 0; i < 60; ++i) add("hover", 11, 2.0);
  for (int i = 0; i < 90; ++i) add("teleop", 11, i == 45 ? 0.347 : 1.0);
  sequence += 2;  // two lost
  for (int i = 0; i < 90; ++i) add("hover", 11, 1.5);
  t_ns += 20'900 * kMs - 33 * kMs;  // 20.9 s silent
  sequence = 1;
  vehicle_ns = 0;
  for (int i = 0; i < 30; ++i) add("land", 12, 3.0);
  r.events.push_back({t_ns - 500 * kMs, 2, 7, "no ground heartbeat for 1.0 s: landing"});
  r.events.push_back({t_ns - 400 * kMs, 0, 1, "mode land"});
  return r;
}

TEST(FlightReport, GapRestartModeChangesAndClearanceAreTheVehiclesOwn) {
  const ReportFigures f = compute_report(synthetic());
  EXPECT_EQ(f.states, 270U);
  EXPECT_NEAR(f.largest_gap_s, 20.9, 1e-6);
  EXPECT_NEAR(f.largest_gap_at_s, 239 * 0.033, 1e-6);
  ASSERT_EQ(f.sessions.size(), 2U);
  EXPECT_EQ(f.sessions[0].session_id, 11U);
  EXPECT_EQ(f.sessions[1].session_id, 12U);
  EXPECT_STREQ(f.sessions[1].why, "new session_id");
  EXPECT_EQ(f.sessions[0].states, 240U);
  EXPECT_NEAR(f.sessions[0].vehicle_duration_s, 239 * 0.033, 1e-6);
  EXPECT_EQ(f.states_lost, 2U);  // the restart's sequence drop is no loss
  EXPECT_STREQ(f.initial_mode, "hover");
  ASSERT_EQ(f.mode_changes.size(), 3U);  // hover->teleop, teleop->hover, hover->land
  EXPECT_STREQ(f.mode_changes[0].to, "teleop");
  EXPECT_STREQ(f.mode_changes[2].from, "hover");
  EXPECT_STREQ(f.mode_changes[2].to, "land");
  EXPECT_NEAR(f.closest_clearance_m, 0.347, 1e-9);
  EXPECT_NEAR(f.closest_cloud_point_m, 0.72, 1e-9);
  EXPECT_NEAR(f.max_height_m, 1.0, 1e-9);
  ASSERT_EQ(f.link_lost_events_s.size(), 1U);
  EXPECT_EQ(f.warnings, 1U);
  EXPECT_NEAR(f.latency_p50_ms, 3.0, 1e-9);
}

TEST(FlightReport, WithoutSessionIdsARestartIsFoundBySequenceAndClock) {
  Recording r = synthetic();
  for (RecordedState& s : r.states) {
    s.session_id = 0;
    s.flight_fields = false;
    s.clearance_m = std::nan("");
  }
  const ReportFigures f = compute_report(r);
  ASSERT_EQ(f.sessions.size(), 2U);
  EXPECT_STREQ(f.sessions[1].why, "sequence restarted");
  EXPECT_EQ(f.states_lost, 2U);
  EXPECT_TRUE(std::isnan(f.closest_clearance_m));  // unknown, not the cloud's figure
  EXPECT_NEAR(f.closest_cloud_point_m, 0.72, 1e-9);
}

TEST(FlightReport, EmptyRecordingGivesZeros) {
  const ReportFigures f = compute_report(Recording{});
  EXPECT_EQ(f.states, 0U);
  EXPECT_TRUE(f.mode_changes.empty());
  EXPECT_TRUE(f.sessions.empty());
}

}  // namespace
}  // namespace hq::console
