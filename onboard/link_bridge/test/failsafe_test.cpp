#include "hq/link_bridge/failsafe.hpp"

#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"
#include "hq/testing/wire_enum.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>

namespace hq::link_bridge {
namespace {

using ::testing::HasSubstr;

constexpr std::int64_t kMs = 1'000'000;

link::VelocityCommand command(float v_x_mps) {
  link::VelocityCommand c{};
  c.vehicle_id = 1;
  c.station_id = 1;
  c.v_H_mps = {v_x_mps, 0.0F, -0.2F};
  c.yaw_rate_radps = 0.1F;
  return c;
}

link::Heartbeat ground_heartbeat(std::uint32_t station_id = 1) {
  link::Heartbeat h{};
  h.vehicle_id = 1;
  h.role = hq_msgs_ROLE_GROUND;
  h.sender_id = station_id;
  return h;
}

constexpr std::uint64_t kSession = 0x1234'5678'9abc'def0ULL;

link::ModeRequest mode_request(std::uint32_t station_id, hq_msgs_Mode mode,
                               std::uint64_t session = kSession) {
  link::ModeRequest r{};
  r.vehicle_id = 1;
  r.station_id = station_id;
  r.requested_mode = mode;
  r.vehicle_session_id = session;
  return r;
}

FailsafeConfig session_config() {
  FailsafeConfig config;
  config.session_id = kSession;
  return config;
}

link::VelocityCommand command_from(std::uint32_t station_id, float v_x_mps) {
  link::VelocityCommand c = command(v_x_mps);
  c.station_id = station_id;
  return c;
}

TEST(Failsafe, HoldsZeroVelocityUntilTheFirstCommand) {
  Failsafe failsafe(FailsafeConfig{});
  const FailsafeState& s = failsafe.update(10 * kMs);
  EXPECT_TRUE(s.hold);
  EXPECT_FALSE(s.have_command);
  EXPECT_EQ(s.command_age_ns, -1);
  EXPECT_EQ(s.command.v_H_mps.norm(), 0.0);
  EXPECT_FALSE(s.heartbeat_lost);  // nobody seen yet: nobody to lose
}

TEST(Failsafe, FreshCommandPassesThenHoldsZeroAfterTheTimeout) {
  FailsafeConfig config;
  config.command_timeout_ns = 200 * kMs;
  Failsafe failsafe(config);
  ASSERT_TRUE(failsafe.on_command(1000 * kMs, command(0.5F)).accepted);
  const FailsafeState& fresh = failsafe.update(1150 * kMs);
  EXPECT_FALSE(fresh.hold);
  EXPECT_EQ(fresh.command_age_ns, 150 * kMs);
  EXPECT_FLOAT_EQ(static_cast<float>(fresh.command.v_H_mps.x()), 0.5F);
  EXPECT_EQ(fresh.command.t_ns, 1000 * kMs);

  EXPECT_FALSE(failsafe.update(1200 * kMs).hold);  // exactly at the timeout: still fresh
  const FailsafeState& held = failsafe.update(1201 * kMs);
  EXPECT_TRUE(held.hold);
  EXPECT_TRUE(held.hold_started);
  EXPECT_EQ(held.command.v_H_mps.norm(), 0.0);
  EXPECT_EQ(held.command.yaw_rate_radps, 0.0);
  EXPECT_EQ(held.command.t_ns, 1201 * kMs);  // stamped now: flown as a fresh zero command
  EXPECT_FALSE(failsafe.update(1300 * kMs).hold_started);  // the edge is reported once
  EXPECT_EQ(failsafe.counters().holds, 1U);

  ASSERT_TRUE(failsafe.on_command(1400 * kMs, command(0.3F)).accepted);
  EXPECT_FALSE(failsafe.update(1405 * kMs).hold);
}

TEST(Failsafe, CommandTimeoutIsConfigurable) {
  FailsafeConfig config;
  config.command_timeout_ns = 50 * kMs;
  Failsafe failsafe(config);
  failsafe.on_command(0, command(0.5F));
  EXPECT_FALSE(failsafe.update(50 * kMs).hold);
  EXPECT_TRUE(failsafe.update(51 * kMs).hold);
}

TEST(Failsafe, RequestsLandOnceAfterTwoSecondsWithoutHeartbeat) {
  Failsafe failsafe(FailsafeConfig{});
  ASSERT_TRUE(failsafe.on_heartbeat(1000 * kMs, ground_heartbeat()).accepted);
  EXPECT_FALSE(failsafe.update(2900 * kMs).heartbeat_lost);
  // Commands keep arriving but do not stand in for the heartbeat.
  failsafe.on_command(2950 * kMs, command(0.1F));
  EXPECT_FALSE(failsafe.update(3000 * kMs).heartbeat_lost);
  const FailsafeState& lost = failsafe.update(3001 * kMs);
  EXPECT_TRUE(lost.heartbeat_lost);
  EXPECT_TRUE(lost.request_land);
  EXPECT_EQ(lost.heartbeat_age_ns, 2001 * kMs);
  EXPECT_FALSE(failsafe.update(3100 * kMs).request_land);
  EXPECT_EQ(failsafe.counters().land_requests, 1U);

  // A station coming back re-arms it: a second loss lands again.
  failsafe.on_heartbeat(4000 * kMs, ground_heartbeat());
  EXPECT_FALSE(failsafe.update(4000 * kMs).heartbeat_lost);
  EXPECT_TRUE(failsafe.update(6001 * kMs).request_land);
  EXPECT_EQ(failsafe.counters().land_requests, 2U);
}

TEST(Failsafe, CommandsWithoutAnyHeartbeatLandAfterTheTimeout) {
  Failsafe failsafe(FailsafeConfig{});
  failsafe.on_command(0, command(0.2F));
  EXPECT_FALSE(failsafe.update(2000 * kMs).heartbeat_lost);
  EXPECT_TRUE(failsafe.update(2001 * kMs).request_land);
}

TEST(Failsafe, VehicleHeartbeatsAndOtherVehiclesDoNotKeepTheLinkAlive) {
  Failsafe failsafe(FailsafeConfig{});
  failsafe.on_heartbeat(0, ground_heartbeat());
  link::Heartbeat own = ground_heartbeat();
  own.role = hq_msgs_ROLE_VEHICLE;
  EXPECT_THAT(failsafe.on_heartbeat(1500 * kMs, own).reason, HasSubstr("not from a ground"));
  link::Heartbeat other = ground_heartbeat();
  other.vehicle_id = 7;
  EXPECT_THAT(failsafe.on_heartbeat(1500 * kMs, other).reason, HasSubstr("another vehicle"));
  link::Heartbeat bad_role = ground_heartbeat();
  bad_role.role = hq::testing::wire_enum<hq_msgs_Role>(77);
  EXPECT_FALSE(failsafe.on_heartbeat(1500 * kMs, bad_role).accepted);
  EXPECT_EQ(failsafe.counters().heartbeats_rejected, 2U);  // a vehicle's is ignored, not counted
  EXPECT_TRUE(failsafe.update(2001 * kMs).request_land);
}

TEST(Failsafe, NonFiniteOrOutOfEnvelopeCommandsAreRejectedCountedAndNotFlown) {
  Failsafe failsafe(FailsafeConfig{});
  ASSERT_TRUE(failsafe.on_command(0, command(0.4F)).accepted);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const float values[] = {nan, inf, -inf, 1e30F, -3.0F, std::numeric_limits<float>::max()};
  for (const float v : values) {
    const Verdict verdict = failsafe.on_command(10 * kMs, command(v));
    EXPECT_FALSE(verdict.accepted) << v;
    EXPECT_THAT(verdict.reason, HasSubstr("v_H_mps.x")) << v;
  }
  link::VelocityCommand yaw = command(0.1F);
  yaw.yaw_rate_radps = nan;
  EXPECT_FALSE(failsafe.on_command(10 * kMs, yaw).accepted);
  link::VelocityCommand other = command(0.1F);
  other.vehicle_id = 2;
  EXPECT_THAT(failsafe.on_command(10 * kMs, other).reason, HasSubstr("another vehicle"));
  EXPECT_EQ(failsafe.counters().commands_rejected, 8U);
  EXPECT_EQ(failsafe.counters().commands_accepted, 1U);
  EXPECT_THAT(failsafe.last_command_rejection(), HasSubstr("another vehicle"));

  // The last good command is still what flies, and its age is not refreshed by bad samples.
  const FailsafeState& s = failsafe.update(100 * kMs);
  EXPECT_FLOAT_EQ(static_cast<float>(s.command.v_H_mps.x()), 0.4F);
  EXPECT_EQ(s.command_age_ns, 100 * kMs);
  EXPECT_TRUE(s.command.v_H_mps.allFinite());
  EXPECT_TRUE(failsafe.update(201 * kMs).hold);
}

TEST(Failsafe, HugeSequenceNumbersDoNotLockOutTheStation) {
  Failsafe failsafe(FailsafeConfig{});
  link::VelocityCommand hostile = command(0.0F);
  hostile.sequence_number = std::numeric_limits<std::uint64_t>::max();
  failsafe.on_command(0, hostile);
  link::VelocityCommand real = command(0.3F);
  real.sequence_number = 5;
  EXPECT_TRUE(failsafe.on_command(10 * kMs, real).accepted);
  EXPECT_FLOAT_EQ(static_cast<float>(failsafe.update(20 * kMs).command.v_H_mps.x()), 0.3F);
}

TEST(Failsafe, MalformedModeRequestsAreRejectedAndValidOnesMapped) {
  Failsafe failsafe(FailsafeConfig{});
  link::ModeRequest request{};
  request.vehicle_id = 1;
  request.station_id = 1;
  modes::Mode mode = modes::Mode::kHover;
  request.requested_mode = hq_msgs_MODE_TELEOP;
  EXPECT_TRUE(failsafe.on_mode_request(0, request, mode).accepted);
  EXPECT_EQ(mode, modes::Mode::kTeleop);
  request.requested_mode = hq_msgs_MODE_LAND;
  EXPECT_TRUE(failsafe.on_mode_request(0, request, mode).accepted);
  EXPECT_EQ(mode, modes::Mode::kLand);

  for (const int bad : {-1, 5, 1000, std::numeric_limits<int>::max()}) {
    request.requested_mode = static_cast<hq_msgs_Mode>(bad);
    mode = modes::Mode::kHover;
    EXPECT_FALSE(failsafe.on_mode_request(0, request, mode).accepted) << bad;
    EXPECT_EQ(mode, modes::Mode::kHover);
  }
  request.requested_mode = hq_msgs_MODE_TELEOP;
  request.vehicle_id = 9;
  EXPECT_THAT(failsafe.on_mode_request(0, request, mode).reason, HasSubstr("another vehicle"));
  EXPECT_EQ(failsafe.counters().mode_requests_rejected, 5U);
  EXPECT_EQ(failsafe.counters().mode_requests_accepted, 2U);
}

// Ownership: requests and heartbeats count only from the commanding station.
TEST(FailsafeOwnership, WeakerStationsRequestsAreIgnoredWhileTheStrongerCommands) {
  // GIVEN station 2's commands are delivered (DDS gave it the command instance)
  Failsafe failsafe(session_config());
  ASSERT_TRUE(failsafe.on_command(0, command_from(2, 0.3F)).accepted);
  EXPECT_EQ(failsafe.update(0).commanding_station_id, 2U);
  // WHEN station 1 (weaker: its commands never arrive) asks for hover
  modes::Mode mode = modes::Mode::kTeleop;
  const Verdict weak =
      failsafe.on_mode_request(10 * kMs, mode_request(1, hq_msgs_MODE_HOVER), mode);
  // THEN it is rejected and counted; the commander's request is accepted
  EXPECT_FALSE(weak.accepted);
  EXPECT_THAT(weak.reason, HasSubstr("does not command"));
  EXPECT_EQ(mode, modes::Mode::kTeleop);
  EXPECT_EQ(failsafe.counters().mode_requests_not_commander, 1U);
  EXPECT_TRUE(
      failsafe.on_mode_request(20 * kMs, mode_request(2, hq_msgs_MODE_LAND), mode).accepted);
  EXPECT_EQ(mode, modes::Mode::kLand);
}

TEST(FailsafeOwnership, FirstStationHeardCommandsUntilAStrongerOnesCommandsArrive) {
  Failsafe failsafe(session_config());
  modes::Mode mode = modes::Mode::kHover;
  // Before any command: the first station's heartbeat makes it the commander ...
  EXPECT_TRUE(failsafe.on_heartbeat(0, ground_heartbeat(5)).accepted);
  EXPECT_EQ(failsafe.update(0).commanding_station_id, 5U);
  EXPECT_TRUE(failsafe.update(1).commander_changed == false);
  EXPECT_TRUE(
      failsafe.on_mode_request(5 * kMs, mode_request(5, hq_msgs_MODE_TELEOP), mode).accepted);
  EXPECT_FALSE(failsafe.on_heartbeat(6 * kMs, ground_heartbeat(6)).accepted);
  EXPECT_EQ(failsafe.counters().heartbeats_not_commander, 1U);
  // ... until station 6's commands arrive (it is stronger): it commands from then on.
  ASSERT_TRUE(failsafe.on_command(10 * kMs, command_from(6, 0.2F)).accepted);
  const FailsafeState& s = failsafe.update(10 * kMs);
  EXPECT_EQ(s.commanding_station_id, 6U);
  EXPECT_TRUE(s.commander_changed);
  EXPECT_FALSE(
      failsafe.on_mode_request(20 * kMs, mode_request(5, hq_msgs_MODE_HOVER), mode).accepted);
  EXPECT_EQ(failsafe.counters().commander_changes, 2U);
}

TEST(FailsafeOwnership, ForeignHeartbeatsDoNotKeepAVehicleWhoseCommanderDiedFromLanding) {
  // GIVEN station 1 commands and sends heartbeats
  Failsafe failsafe(session_config());
  for (std::int64_t t = 0; t <= 1000 * kMs; t += 10 * kMs) {
    failsafe.on_command(t, command_from(1, 0.3F));
    failsafe.on_heartbeat(t, ground_heartbeat(1));
    failsafe.update(t);
  }
  // WHEN it dies at 1 s while station 666 keeps sending heartbeats
  bool landed = false;
  std::int64_t land_t = -1;
  for (std::int64_t t = 1010 * kMs; t <= 4000 * kMs && !landed; t += 10 * kMs) {
    EXPECT_FALSE(failsafe.on_heartbeat(t, ground_heartbeat(666)).accepted);
    const FailsafeState& s = failsafe.update(t);
    if (s.request_land) {
      landed = true;
      land_t = t;
      EXPECT_TRUE(s.land_for_heartbeat);
    }
  }
  // THEN it lands once the commander's heartbeat is 2 s old
  EXPECT_TRUE(landed);
  EXPECT_EQ(land_t, 3010 * kMs);
  EXPECT_GT(failsafe.counters().heartbeats_not_commander, 100U);
}

TEST(FailsafeOwnership, RequestsForAnotherSessionAreRejected) {
  // A TRANSIENT_LOCAL request made to the previous instance of this vehicle, or a replay
  Failsafe failsafe(session_config());
  modes::Mode mode = modes::Mode::kHover;
  const Verdict old =
      failsafe.on_mode_request(0, mode_request(1, hq_msgs_MODE_TELEOP, kSession + 1), mode);
  EXPECT_FALSE(old.accepted);
  EXPECT_THAT(old.reason, HasSubstr("another vehicle session"));
  EXPECT_EQ(mode, modes::Mode::kHover);
  EXPECT_FALSE(failsafe.on_mode_request(0, mode_request(1, hq_msgs_MODE_TELEOP, 0), mode).accepted);
  EXPECT_EQ(failsafe.counters().mode_requests_wrong_session, 2U);
  // ... and does not make its station the commander
  EXPECT_EQ(failsafe.update(0).commanding_station_id, 0U);
  EXPECT_TRUE(failsafe.on_mode_request(0, mode_request(1, hq_msgs_MODE_TELEOP), mode).accepted);
}

TEST(FailsafeOwnership, StationsNotListedCannotCommandRequestOrKeepTheLink) {
  FailsafeConfig config = session_config();
  config.stations = {1, 2};
  Failsafe failsafe(config);
  modes::Mode mode = modes::Mode::kHover;
  EXPECT_FALSE(failsafe.on_command(0, command_from(9, 0.5F)).accepted);
  EXPECT_THAT(failsafe.last_command_rejection(), HasSubstr("not allowed"));
  EXPECT_FALSE(failsafe.on_mode_request(0, mode_request(9, hq_msgs_MODE_TELEOP), mode).accepted);
  EXPECT_FALSE(failsafe.on_heartbeat(0, ground_heartbeat(9)).accepted);
  const FailsafeState& s = failsafe.update(0);
  EXPECT_EQ(s.commanding_station_id, 0U);
  EXPECT_EQ(operator_input(s, modes::Mode::kTeleop, false), hq_msgs_INPUT_IGNORED_NOT_OWNER);
  EXPECT_EQ(failsafe.counters().commands_not_allowed, 1U);
  EXPECT_TRUE(failsafe.on_command(10 * kMs, command_from(2, 0.5F)).accepted);
  EXPECT_EQ(failsafe.update(10 * kMs).commanding_station_id, 2U);
}

// GIVEN stations 1 and 3 both allowed, WHEN station 3's certificate writes samples claiming
// station 1 (the shipped hq-ground could be told --station-id 1), THEN none of them counts: the
// command is not flown, the request not obeyed, the heartbeat keeps nothing alive, and each is
// an intrusion naming both stations. Station 1's own samples, and unbound ones (plain DDS),
// pass as before.
TEST(FailsafeIdentity, SamplesClaimingAnotherStationThanTheirCertificateAreIntrusions) {
  FailsafeConfig config = session_config();
  config.stations = {1, 3};
  Failsafe failsafe(config);
  modes::Mode mode = modes::Mode::kHover;
  const link::WriterStation station_3{true, 3};
  EXPECT_FALSE(failsafe.on_command(0, command_from(1, 0.5F), station_3).accepted);
  EXPECT_THAT(failsafe.last_command_rejection(), HasSubstr("certificate"));
  EXPECT_FALSE(
      failsafe.on_mode_request(0, mode_request(1, hq_msgs_MODE_LAND), mode, station_3).accepted);
  EXPECT_FALSE(failsafe.on_heartbeat(0, ground_heartbeat(1), station_3).accepted);
  EXPECT_EQ(failsafe.counters().intrusions, 3U);
  EXPECT_EQ(failsafe.counters().commands_rejected, 1U);
  EXPECT_EQ(failsafe.counters().mode_requests_rejected, 1U);
  EXPECT_EQ(failsafe.counters().heartbeats_rejected, 1U);
  EXPECT_EQ(failsafe.last_intrusion().claimed_station_id, 1U);
  EXPECT_EQ(failsafe.last_intrusion().writer_station_id, 3U);
  EXPECT_STREQ(failsafe.last_intrusion().kind, "heartbeat");
  EXPECT_EQ(failsafe.update(0).commanding_station_id, 0U);  // nobody took command

  // A writer bound to no station (its partitions name none) cannot claim one either.
  EXPECT_FALSE(failsafe.on_command(kMs, command_from(1, 0.5F), {true, 0}).accepted);
  EXPECT_EQ(failsafe.counters().intrusions, 4U);

  EXPECT_TRUE(failsafe.on_command(2 * kMs, command_from(1, 0.5F), {true, 1}).accepted);
  EXPECT_TRUE(failsafe.on_command(3 * kMs, command_from(1, 0.5F)).accepted);  // unbound
  EXPECT_EQ(failsafe.update(3 * kMs).commanding_station_id, 1U);
  EXPECT_EQ(failsafe.counters().intrusions, 4U);
  // A sample whose writer left before it was checked (a station restarting) proves nothing
  // either way: rejected and counted apart, never called an intrusion.
  EXPECT_FALSE(failsafe.on_command(4 * kMs, command_from(1, 0.5F), {true, 0, false}).accepted);
  EXPECT_EQ(failsafe.counters().unverified, 1U);
  EXPECT_EQ(failsafe.counters().intrusions, 4U);
  // The vehicle's own heartbeat claims no station: ignored as before, not an intrusion.
  link::Heartbeat own = ground_heartbeat(1);
  own.role = hq_msgs_ROLE_VEHICLE;
  EXPECT_FALSE(failsafe.on_heartbeat(4 * kMs, own, {true, 0}).accepted);
  EXPECT_EQ(failsafe.counters().intrusions, 4U);
}

TEST(FailsafeEscalation, HoldThenLandAfterHoldToLand) {
  FailsafeConfig config = session_config();
  config.hold_to_land_ns = 1000 * kMs;
  Failsafe failsafe(config);
  // Commands stop at 0 while heartbeats go on (a hand that froze, a broken device loop)
  failsafe.on_command(0, command_from(1, 0.3F));
  std::int64_t land_t = -1;
  int lands = 0;
  for (std::int64_t t = 0; t <= 5000 * kMs; t += 5 * kMs) {
    failsafe.on_heartbeat(t, ground_heartbeat(1));
    const FailsafeState& s = failsafe.update(t);
    if (t == 205 * kMs) {
      EXPECT_TRUE(s.hold);
    }
    if (s.request_land) {
      ++lands;
      if (land_t < 0) land_t = t;
      EXPECT_TRUE(s.land_for_hold);
      EXPECT_FALSE(s.heartbeat_lost);
    }
  }
  // hold at 200 ms, land 1 s later, once
  EXPECT_EQ(land_t, 1205 * kMs);
  EXPECT_EQ(lands, 1);
  EXPECT_EQ(failsafe.counters().land_requests_hold, 1U);
  // A fresh command ends the episode: the next silence lands again.
  failsafe.on_command(6000 * kMs, command_from(1, 0.1F));
  failsafe.on_heartbeat(6000 * kMs, ground_heartbeat(1));
  EXPECT_FALSE(failsafe.update(6000 * kMs).hold_expired);
  failsafe.on_heartbeat(7000 * kMs, ground_heartbeat(1));
  EXPECT_TRUE(failsafe.update(7201 * kMs).land_for_hold);
}

TEST(FailsafeEscalation, HeartbeatLossAndHoldExpiryLandOnce) {
  Failsafe failsafe(session_config());  // heartbeat 2 s, hold_to_land 5 s
  failsafe.on_command(0, command_from(1, 0.3F));
  failsafe.on_heartbeat(0, ground_heartbeat(1));
  int lands = 0;
  for (std::int64_t t = 0; t <= 8000 * kMs; t += 5 * kMs) lands += failsafe.update(t).request_land;
  EXPECT_EQ(lands, 1);
  EXPECT_EQ(failsafe.counters().land_requests_hold, 0U);
}

TEST(FailsafeOwnership, OperatorInputSaysWhatTheVehicleDoesWithTheHand) {
  Failsafe failsafe(session_config());
  EXPECT_EQ(operator_input(failsafe.update(0), modes::Mode::kTeleop, true), hq_msgs_INPUT_NONE);
  failsafe.on_command(10 * kMs, command_from(1, 0.3F));
  const FailsafeState& s = failsafe.update(10 * kMs);
  EXPECT_EQ(operator_input(s, modes::Mode::kTeleop, false), hq_msgs_INPUT_FLOWN);
  EXPECT_EQ(operator_input(s, modes::Mode::kTeleop, true), hq_msgs_INPUT_IGNORED_LANDED);
  EXPECT_EQ(operator_input(s, modes::Mode::kHover, false), hq_msgs_INPUT_IGNORED_MODE);
  EXPECT_EQ(operator_input(failsafe.update(300 * kMs), modes::Mode::kTeleop, false),
            hq_msgs_INPUT_IGNORED_FAILSAFE);
}

TEST(Failsafe, ModeEnumRoundTrips) {
  for (const modes::Mode mode : {modes::Mode::kTeleop, modes::Mode::kHover, modes::Mode::kLand,
                                 modes::Mode::kMarker, modes::Mode::kExplore}) {
    modes::Mode back = modes::Mode::kHover;
    ASSERT_TRUE(to_mode(to_link_mode(mode), back));
    EXPECT_EQ(back, mode);
  }
}

TEST(Failsafe, BadConfigNamesTheField) {
  FailsafeConfig config;
  config.command_timeout_ns = 0;
  EXPECT_THAT(hq::testing::input_error_message([&] { Failsafe f(config); }),
              HasSubstr("command_timeout_ms = 0"));
  config = {};
  config.heartbeat_timeout_ns = 100 * kMs;
  EXPECT_THAT(hq::testing::input_error_message([&] { Failsafe f(config); }),
              HasSubstr("heartbeat_timeout_ms = 100"));
  config = {};
  config.hold_to_land_ns = 50 * kMs;
  EXPECT_THAT(hq::testing::input_error_message([&] { Failsafe f(config); }),
              HasSubstr("hold_to_land_s = 0.05"));
  config = {};
  config.stations = {1, 0};
  EXPECT_THAT(hq::testing::input_error_message([&] { Failsafe f(config); }),
              HasSubstr("station id 0"));
  config = {};
  config.envelope.max_v_z_mps = std::nan("");
  EXPECT_THAT(hq::testing::input_error_message([&] { Failsafe f(config); }),
              HasSubstr("envelope.max_v_z_mps"));
}

TEST(Failsafe, PerMessagePathAllocatesNothing) {
  Failsafe failsafe(FailsafeConfig{});
  failsafe.on_command(0, command(0.1F));
  failsafe.update(0);
  const auto before = hq::testing::allocation_count();
  for (int i = 1; i < 1000; ++i) {
    const std::int64_t t_ns = i * kMs;
    failsafe.on_command(t_ns, command(i % 3 == 0 ? std::nanf("") : 0.2F));
    failsafe.on_heartbeat(t_ns, ground_heartbeat());
    failsafe.update(t_ns);
  }
  EXPECT_EQ(hq::testing::allocation_count(), before);
}

link::VelocityCommand stamped(float v_x_mps, std::int64_t stamp_ns) {
  link::VelocityCommand c = command(v_x_mps);
  c.t_ns = stamp_ns;
  return c;
}

// The station's clock runs 7 s ahead of the vehicle's: only differences of delay matter.
constexpr std::int64_t kStationAheadNs = 7'000'000'000;

TEST(FailsafeStamps, BurstOfStaleCommandsAfterAStallMovesNothing) {
  // GIVEN a station 50 ms away sending every 10 ms
  Failsafe failsafe(FailsafeConfig{});
  // Fresh commands for 1 s: accepted, flown.
  for (std::int64_t t = 0; t < 1000 * kMs; t += 10 * kMs) {
    ASSERT_TRUE(failsafe.on_command(t + 50 * kMs, stamped(0.3F, t + kStationAheadNs)).accepted);
    failsafe.update(t + 50 * kMs);
  }
  EXPECT_FALSE(failsafe.update(1050 * kMs).hold);
  // WHEN the link stalls while the station sends 1.0 m/s from 1.0 to 1.7 s, and those commands
  // arrive in one burst at 2.05 s
  EXPECT_TRUE(failsafe.update(1300 * kMs).hold);  // no command for 250 ms: hold
  int accepted = 0;
  for (std::int64_t t = 1000 * kMs; t < 1700 * kMs; t += 10 * kMs) {
    accepted += failsafe.on_command(2050 * kMs, stamped(1.0F, t + kStationAheadNs)).accepted;
  }
  const FailsafeState& during = failsafe.update(2050 * kMs);
  // THEN every burst command is rejected as stale and the vehicle keeps holding zero velocity
  EXPECT_EQ(accepted, 0);
  EXPECT_EQ(failsafe.counters().commands_stale, 70u);
  EXPECT_THAT(failsafe.last_command_rejection(), HasSubstr("older than its deadline"));
  EXPECT_TRUE(during.hold);
  EXPECT_EQ(during.command.v_H_mps.norm(), 0.0);
  // ... and it resumes on the first fresh command
  ASSERT_TRUE(
      failsafe.on_command(2100 * kMs, stamped(0.2F, 2050 * kMs + kStationAheadNs)).accepted);
  const FailsafeState& resumed = failsafe.update(2100 * kMs);
  EXPECT_FALSE(resumed.hold);
  EXPECT_FLOAT_EQ(static_cast<float>(resumed.command.v_H_mps.x()), 0.2F);
}

TEST(FailsafeStamps, ReorderedOlderCommandIsRejected) {
  Failsafe failsafe(FailsafeConfig{});
  ASSERT_TRUE(failsafe.on_command(100 * kMs, stamped(0.3F, 60 * kMs)).accepted);
  EXPECT_FALSE(failsafe.on_command(105 * kMs, stamped(0.9F, 50 * kMs)).accepted);
  EXPECT_THAT(failsafe.last_command_rejection(), HasSubstr("reordered"));
  EXPECT_FALSE(failsafe.on_command(106 * kMs, stamped(0.9F, 60 * kMs)).accepted);
  EXPECT_TRUE(failsafe.on_command(110 * kMs, stamped(0.3F, 70 * kMs)).accepted);
}

TEST(FailsafeStamps, AnotherClockIsReanchoredAfterOneSecondOfStaleCommands) {
  // GIVEN a station whose stamps jump 5 s back (restarted, another clock), or a sample stamped
  // far in the future: fresh commands look stale, but only for command_reanchor
  for (const std::int64_t jump_ns : {-5'000'000'000LL, 3'600'000'000'000LL}) {
    Failsafe failsafe(FailsafeConfig{});
    for (std::int64_t t = 0; t < 500 * kMs; t += 10 * kMs) {
      ASSERT_TRUE(failsafe.on_command(t, stamped(0.3F, t + kStationAheadNs)).accepted);
    }
    std::int64_t t = 500 * kMs;
    if (jump_ns > 0) {
      // one hostile sample from the future: accepted once (nothing tells it apart)
      failsafe.on_command(t, stamped(0.0F, t + kStationAheadNs + jump_ns));
      t += 10 * kMs;
    }
    std::int64_t first_accepted_ns = -1;
    for (; t < 3000 * kMs && first_accepted_ns < 0; t += 10 * kMs) {
      const std::int64_t stamp = t + kStationAheadNs + (jump_ns < 0 ? jump_ns : 0);
      if (failsafe.on_command(t, stamped(0.3F, stamp)).accepted) first_accepted_ns = t;
    }
    // THEN the vehicle holds for 1 s, then accepts the station's commands again
    EXPECT_NEAR(static_cast<double>(first_accepted_ns), 1510.0 * kMs, 20.0 * kMs) << jump_ns;
  }
}

TEST(FailsafeStamps, UnstampedCommandsSkipTheDeadline) {
  // t_ns = 0 (a sender that does not stamp): only the receipt timeout applies
  Failsafe failsafe(FailsafeConfig{});
  for (std::int64_t t = 0; t < 3000 * kMs; t += 10 * kMs) {
    ASSERT_TRUE(failsafe.on_command(t, command(0.3F)).accepted);
  }
  EXPECT_EQ(failsafe.counters().commands_stale, 0u);
}

}  // namespace
}  // namespace hq::link_bridge
