// The ground station and the vehicle bridge in one process over loopback DDS, each impairing
// what it receives by 100 +- 10 ms: the heartbeat echo gives the round trip and the clock
// offset, the state's vehicle stamp its one-way age, and the vehicle accepts the delayed but
// fresh commands. The vehicle's clock runs 5 s ahead of the ground's.
#include "hq/ground/ground_station.hpp"
#include "hq/link/impairment.hpp"
#include "hq/link_bridge/link_bridge.hpp"
#include "hq/testing/loopback_dds.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fmt/format.h>
#include <unistd.h>
#include <vector>

namespace hq {
namespace {

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

TEST(LinkDelay, RoundTripStateAgeAndCommandsOverAnImpairedLink) {
  hq::testing::use_loopback_dds();
  link::LinkConfig config;
  config.domain_id = hq::testing::private_domain_id(0);
  config.security.enabled = false;  // ground and vehicle in one process: plain DDS
  config.impairment = link::parse_impairment("delay_ms=100,jitter_ms=10,seed=3");
  ground::GroundStation ground(config);
  link_bridge::LinkBridge bridge(config, link_bridge::FailsafeConfig{});
  constexpr std::int64_t kVehicleAheadNs = 5'000'000'000;
  std::vector<pipeline::ModeRequest> requests;
  haptics::VelocityCommand command;
  command.v_H_mps = {0.3, 0.0, 0.0};
  const std::int64_t start_ns = monotonic_ns();
  std::int64_t next_heartbeat_ns = start_ns;
  std::int64_t next_state_ns = start_ns;
  link_bridge::FailsafeState vehicle;
  // WHEN both sides run their loops for 2.5 s (ground paced by its waitset, 10 ms steps)
  for (std::int64_t step_ns = start_ns; step_ns < start_ns + 2'500'000'000; step_ns += 10'000'000) {
    ground.poll_until(step_ns);
    const std::int64_t t_ns = monotonic_ns();
    if (t_ns >= next_heartbeat_ns) {
      ground.send_heartbeat(t_ns);
      next_heartbeat_ns += 100'000'000;
    }
    ground.send_command(t_ns, command, true);
    const std::int64_t vehicle_t_ns = t_ns + kVehicleAheadNs;
    vehicle = bridge.poll(vehicle_t_ns, requests);
    if (t_ns >= next_state_ns) {
      pipeline::ChainOutput out;
      out.t_ns = vehicle_t_ns;
      bridge.publish_state(out);
      next_state_ns += 33'000'000;
    }
  }
  const ground::LinkStatus& s = ground.status();
  fmt::print(
      "round trip {:.1f} ms (p50 {:.1f}), offset {:.1f} ms, state age {:.1f} ms (p50 {:.1f}), loss "
      "{:.3f}, vehicle hold {:d}, stale {}\n",
      1e-6 * static_cast<double>(s.round_trip_ns), ground.round_trip().quantile_ms(0.5),
      1e-6 * static_cast<double>(s.clock_offset_ns - kVehicleAheadNs),
      1e-6 * static_cast<double>(s.last_state_age_ns), ground.state_age().quantile_ms(0.5),
      ground.state_loss(), vehicle.hold,
      static_cast<unsigned long long>(bridge.failsafe().counters().commands_stale));
  // THEN the round trip is the two 100 ms delays (+ up to a 10 ms step each side and jitter),
  ASSERT_TRUE(s.have_clock_offset);
  EXPECT_NEAR(ground.round_trip().quantile_ms(0.5), 210.0, 40.0);
  // the clock offset is found to within half the asymmetry of the steps,
  EXPECT_NEAR(1e-6 * static_cast<double>(s.clock_offset_ns - kVehicleAheadNs), 0.0, 25.0);
  // a state is one 100 ms delay old on arrival,
  EXPECT_NEAR(ground.state_age().quantile_ms(0.5), 105.0, 30.0);
  EXPECT_EQ(ground.state_loss(), 0.0);
  // and the vehicle flies the delayed but fresh commands; only those the jitter reordered
  // behind a newer one are dropped (measured 21 of 250)
  EXPECT_FALSE(vehicle.hold);
  EXPECT_GT(bridge.failsafe().counters().commands_accepted, 150u);
  EXPECT_LT(bridge.failsafe().counters().commands_stale, 60u);
  EXPECT_STREQ(bridge.failsafe().last_command_rejection(),
               "command older than one already accepted (reordered)");
}

// Runs the ground and one vehicle's bridge for duration_ns, the vehicle's clock `ahead_ns`
// ahead of the ground's (another process's clock: a simulator's from 0, another boot's).
void fly(ground::GroundStation& ground, link_bridge::LinkBridge& bridge, std::int64_t ahead_ns,
         std::int64_t duration_ns) {
  std::vector<pipeline::ModeRequest> requests;
  const std::int64_t start_ns = monotonic_ns();
  std::int64_t next_heartbeat_ns = start_ns;
  std::int64_t next_state_ns = start_ns;
  for (std::int64_t step_ns = start_ns; step_ns < start_ns + duration_ns; step_ns += 10'000'000) {
    ground.poll_until(step_ns);
    const std::int64_t t_ns = monotonic_ns();
    if (t_ns >= next_heartbeat_ns) {
      ground.send_heartbeat(t_ns);
      next_heartbeat_ns += 100'000'000;
    }
    bridge.poll(t_ns + ahead_ns, requests);
    if (t_ns >= next_state_ns) {
      pipeline::ChainOutput out;
      out.t_ns = t_ns + ahead_ns;
      bridge.publish_state(out);
      next_state_ns += 33'000'000;
    }
  }
}

// GIVEN a vehicle whose clock is 150 s ahead of the ground's, on a fast link WHEN it says
// goodbye THEN the ground marks it ended (no link loss for its silence); WHEN a new vehicle
// process (clock 7 s behind, a slower link) follows THEN it is a new session at once, and its
// clock offset and state age are its own: the old session's echoes, with their shorter round
// trips, would otherwise win the least-delay choice and age its states by ~157 s.
TEST(LinkDelay, ARestartedVehicleGetsItsOwnClockOffset) {
  hq::testing::use_loopback_dds();
  link::LinkConfig config;
  config.domain_id = hq::testing::private_domain_id(1);
  config.security.enabled = false;
  ground::GroundStation ground(config);
  constexpr std::int64_t kFirstAheadNs = 150'000'000'000;
  constexpr std::int64_t kSecondAheadNs = -7'000'000'000;
  {
    link_bridge::LinkBridge first(config, link_bridge::FailsafeConfig{});
    fly(ground, first, kFirstAheadNs, 1'500'000'000);
    ASSERT_TRUE(ground.status().have_clock_offset);
    EXPECT_NEAR(1e-9 * static_cast<double>(ground.status().clock_offset_ns - kFirstAheadNs), 0.0,
                0.05);
    EXPECT_TRUE(first.say_goodbye(monotonic_ns() + kFirstAheadNs, "stopped by SIGTERM; landed"));
    fly(ground, first, kFirstAheadNs, 0);  // nothing more: the goodbye is taken on a poll
    ground.poll_until(monotonic_ns() + 50'000'000);
  }
  EXPECT_TRUE(ground.status().vehicle_ended);
  EXPECT_STREQ(ground.status().vehicle_ended_text.data(),
               "vehicle ended: stopped by SIGTERM; landed");
  link::LinkConfig slower = config;
  slower.impairment = link::parse_impairment("delay_ms=40,seed=5");  // the vehicle's receipts
  link_bridge::LinkBridge second(slower, link_bridge::FailsafeConfig{});
  fly(ground, second, kSecondAheadNs, 1'000'000'000);  // fewer echoes than the ring holds
  const ground::LinkStatus& s = ground.status();
  fmt::print("after the restart: offset {:.3f} s from the new vehicle's, state age {:.1f} ms\n",
             1e-9 * static_cast<double>(s.clock_offset_ns - kSecondAheadNs),
             1e-6 * static_cast<double>(s.last_state_age_ns));
  EXPECT_EQ(s.vehicle_restarts, 1U);
  EXPECT_EQ(s.vehicle_session, second.session_id());
  EXPECT_FALSE(s.vehicle_ended);
  ASSERT_TRUE(s.have_clock_offset);
  EXPECT_NEAR(1e-9 * static_cast<double>(s.clock_offset_ns - kSecondAheadNs), 0.0, 0.05);
  EXPECT_GE(s.last_state_age_ns, -50'000'000);
  EXPECT_LT(s.last_state_age_ns, 200'000'000);
}

}  // namespace
}  // namespace hq
