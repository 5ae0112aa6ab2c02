#include "hq/console/replay_player.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <string>

namespace hq::console {
namespace {

constexpr std::int64_t kT0 = 5'000'000'000LL;
constexpr std::int64_t kPeriod = 33'333'333LL;  // 30 states/s

// 10 s of states at 30 Hz: hover for 3 s, then teleop; events at 1 s and 6 s. With
// `restart_at_s` >= 0 the vehicle restarts there: a new session_id (with_sessions) or, in a
// recording without sessions, its sequence numbers and clock start again.
Recording synthetic(double restart_at_s = -1, bool with_sessions = true) {
  Recording r;
  std::uint64_t sequence = 1;
  std::int64_t vehicle_t_ns = 1'000'000'000;
  std::uint64_t session = 77;
  for (int i = 0; i <= 300; ++i) {
    const double t_s = i / 30.0;
    if (restart_at_s >= 0 && i == static_cast<int>(restart_at_s * 30)) {
      sequence = 1;
      vehicle_t_ns = 500'000'000;
      session = 91;
    }
    RecordedState s;
    s.receipt_ns = kT0 + i * kPeriod;
    s.sequence = sequence++;
    s.vehicle_t_ns = vehicle_t_ns;
    vehicle_t_ns += kPeriod;
    s.latency_ms = 2.0;
    s.mode = intern(t_s < 3.0 ? "hover" : "teleop");
    s.session_id = with_sessions ? session : 0;
    r.states.push_back(s);
    RecordedCommand c;
    c.t_ns = s.receipt_ns - 1000;
    c.v_H_mps = {0.5F, 0, 0};
    c.valid = true;
    r.commands.push_back(c);
  }
  r.events.push_back({kT0 + 1'000'000'000LL, 0, -1, "teleop requested"});
  r.events.push_back({kT0 + 6'000'000'000LL, 1, -1, "obstacle close"});
  return r;
}

TEST(ReplayTimeline, SpansTheRecordingWithModeBandsAndEventMarks) {
  const Recording r = synthetic();
  const Timeline t = make_timeline(r);
  EXPECT_EQ(t.t0_ns, kT0 - 1000);  // the first command, just before the first state
  EXPECT_NEAR(t.duration_s, 10.0, 1e-3);
  ASSERT_EQ(t.bands.size(), 2U);
  EXPECT_STREQ(t.bands[0].mode, "hover");
  EXPECT_STREQ(t.bands[1].mode, "teleop");
  EXPECT_NEAR(t.bands[1].start_s, 3.0, 0.05);
  EXPECT_NEAR(t.bands[1].end_s, t.duration_s, 1e-6);  // the last state is the last stamp
  ASSERT_EQ(t.marks.size(), 2U);
  EXPECT_NEAR(t.marks[1].t_s, 6.0, 1e-3);
  EXPECT_EQ(t.marks[1].severity, 1);
  EXPECT_EQ(t.sessions.size(), 1U);
}

TEST(ReplayTimeline, ASilenceOfMoreThanASecondLeavesTheBarEmpty) {
  Recording r = synthetic();
  for (std::size_t i = 150; i < r.states.size(); ++i) r.states[i].receipt_ns += 3'000'000'000LL;
  const Timeline t = make_timeline(r);
  ASSERT_EQ(t.bands.size(), 3U);  // hover, teleop until the silence, teleop after it
  EXPECT_NEAR(t.bands[1].end_s, 149 / 30.0, 0.01);
  EXPECT_NEAR(t.bands[2].start_s, 150 / 30.0 + 3.0, 0.01);
  EXPECT_STREQ(t.bands[2].mode, "teleop");
}

TEST(ReplayPlayer, PlaysPausesChangesSpeedAndStopsAtTheEnd) {
  const Recording r = synthetic();
  ReplayPlayer p(r);
  EXPECT_FALSE(p.playing());
  p.advance(1.0);
  EXPECT_EQ(p.position_s(), 0.0);  // paused: wall time does not move it
  p.play();
  p.advance(1.0);
  EXPECT_NEAR(p.position_s(), 1.0, 1e-9);
  p.set_speed(2.0);
  p.advance(1.0);
  EXPECT_NEAR(p.position_s(), 3.0, 1e-9);
  p.toggle_play();
  EXPECT_FALSE(p.playing());
  p.advance(5.0);
  EXPECT_NEAR(p.position_s(), 3.0, 1e-9);
  p.play();
  p.advance(100.0);
  EXPECT_TRUE(p.at_end());
  EXPECT_FALSE(p.playing());
  EXPECT_NEAR(p.position_s(), p.duration_s(), 1e-9);
  p.play();  // from the end: again from the start
  EXPECT_EQ(p.position_s(), 0.0);
  EXPECT_TRUE(p.playing());
}

TEST(ReplayPlayer, SpeedStepsStayWithinAQuarterAndEightTimes) {
  const Recording r = synthetic();
  ReplayPlayer p(r);
  for (int i = 0; i < 10; ++i) p.faster();
  EXPECT_EQ(p.speed(), ReplayPlayer::kMaxSpeed);
  p.slower();
  EXPECT_EQ(p.speed(), 4.0);
  for (int i = 0; i < 10; ++i) p.slower();
  EXPECT_EQ(p.speed(), ReplayPlayer::kMinSpeed);
  p.set_speed(100);
  EXPECT_EQ(p.speed(), 8.0);
  p.set_speed(0.01);
  EXPECT_EQ(p.speed(), 0.25);
}

TEST(ReplayPlayer, SeekBackwardsShowsOnlyTheDataBeforeTheNewPosition) {
  const Recording r = synthetic();
  ReplayPlayer p(r);
  ConsoleModel model;
  Snapshot snap = model.make_snapshot();
  std::uint64_t missing = 0;
  p.seek(8.0);
  p.feed(model, missing);
  model.snapshot(snap);
  EXPECT_EQ(snap.plot_total, 240U);  // states before 8 s (t0 is the first command)
  EXPECT_EQ(snap.event_count, 2U);
  EXPECT_EQ(snap.mode, "teleop");
  p.seek(2.0);
  p.feed(model, missing);
  model.snapshot(snap);
  EXPECT_EQ(snap.plot_total, 60U);
  EXPECT_EQ(snap.event_count, 1U);
  EXPECT_EQ(snap.link.events, 1U);  // the count shown is the events shown
  EXPECT_EQ(snap.link.states, 60U);
  EXPECT_EQ(snap.mode, "hover");
  EXPECT_NEAR(snap.replay.position_s, 2.0, 1e-9);
  EXPECT_TRUE(snap.replay.active);
  EXPECT_FALSE(snap.replay.at_end);
  // Seeks clamp to the recording.
  p.seek(-4);
  EXPECT_EQ(p.position_s(), 0.0);
  p.step(1e6);
  EXPECT_TRUE(p.at_end());
  p.feed(model, missing);
  model.snapshot(snap);
  EXPECT_TRUE(snap.replay.at_end);
  EXPECT_EQ(snap.plot_total, 301U);
}

TEST(ReplayPlayer, RatesAreThoseOfTheReplayedData) {
  const Recording r = synthetic();
  ReplayPlayer p(r);
  p.seek(5.0);
  const ReplayCounts c = p.counts();
  EXPECT_NEAR(c.state_rate_hz, 30.0, 1.5);
  EXPECT_EQ(c.camera_rate_hz, 0.0);  // no frames in this recording
  EXPECT_NEAR(c.latency_p50_ms, 2.0, 1e-9);
  EXPECT_EQ(c.sequence_gaps, 0U);
}

TEST(ReplayPlayer, ARestartedVehicleIsANewSessionNotALoss) {
  for (const bool with_sessions : {true, false}) {
    SCOPED_TRACE(with_sessions ? "session_id" : "sequence and clock restart");
    const Recording r = synthetic(4.0, with_sessions);
    ReplayPlayer p(r);
    ASSERT_EQ(p.timeline().sessions.size(), 2U);
    EXPECT_EQ(p.timeline().sessions[1].first_state, 120U);
    EXPECT_NEAR(p.timeline().sessions[1].t_s, 4.0, 1e-3);
    ConsoleModel model;
    Snapshot snap = model.make_snapshot();
    std::uint64_t missing = 0;
    p.seek(5.0);
    p.feed(model, missing);
    model.snapshot(snap);
    EXPECT_EQ(p.counts().sessions, 2U);
    EXPECT_EQ(snap.link.sequence_gaps, 0U);
    ASSERT_EQ(snap.event_count, 2U);  // "teleop requested", then the restart
    EXPECT_NE(std::strstr(snap.events[1].text.data(), "vehicle restarted at 4.0 s"), nullptr)
        << snap.events[1].text.data();
    EXPECT_EQ(snap.link.events, 2U);
    // The restarted vehicle's track is its own: only the states since the restart.
    EXPECT_EQ(snap.track_count, p.counts().states - 120U);
  }
}

TEST(ReplayPlayer, ALostStateInsideASessionCountsAsAGap) {
  Recording r = synthetic();
  for (std::size_t i = 150; i < r.states.size(); ++i) r.states[i].sequence += 3;
  ReplayPlayer p(r);
  p.seek(10);
  EXPECT_EQ(p.counts().sequence_gaps, 3U);
  EXPECT_EQ(p.timeline().sessions.size(), 1U);
}

TEST(ReplayControl, AppliesTheUiRequestsOnce) {
  const Recording r = synthetic();
  ReplayPlayer p(r);
  ReplayControl control;
  control.toggles = 1;
  control.speed_steps = 2;
  control.seek_to_s = 4.0;
  control.seek_by_s = 5.0;
  control.apply(p);
  EXPECT_TRUE(p.playing());
  EXPECT_EQ(p.speed(), 4.0);
  EXPECT_NEAR(p.position_s(), 9.0, 1e-9);
  control.apply(p);  // nothing pending: nothing changes
  EXPECT_TRUE(p.playing());
  EXPECT_NEAR(p.position_s(), 9.0, 1e-9);
}

}  // namespace
}  // namespace hq::console
