// hq-ground's flight loop (OperatorStation) driven without DDS or threads: a fake link whose
// poll_until() moves a fake clock and ticks the real haptic loop (a simulated hand) every
// millisecond, and delivers scripted vehicle states. Checks what the station commands, asks
// and reports.
#include "hq/ground/operator_station.hpp"

#include "hq/console/console_model.hpp"
#include "hq/haptics/haptic_device.hpp"
#include "hq/haptics/haptic_loop.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <limits>
#include <string>
#include <vector>

namespace hq::ground {
namespace {

using ::testing::HasSubstr;

constexpr std::int64_t kMsNs = 1'000'000;

class FakeClock final : public StationClock {
 public:
  std::int64_t monotonic_ns() override { return now_ns; }
  std::int64_t wall_ns() override { return 1'700'000'000'000'000'000 + now_ns; }
  std::int64_t now_ns = 1'000 * kMsNs;
};

struct ModeRequestSent {
  std::int64_t t_ns;
  hq_msgs_Mode mode;
  MarkerChoice marker;
  bool take_off;
};

// The vehicle side as the station sees it: states arrive at scripted times; everything sent
// is kept. Time passes only in poll_until(), which ticks the haptic loop at 1 kHz meanwhile.
class FakeLink final : public VehicleLink {
 public:
  FakeLink(FakeClock& clock, haptics::HapticLoop& hand) : clock_(clock), hand_(hand) {}

  /// A state (this template) arrives `at_ns` with one-way age `age_ns`.
  void schedule_state(std::int64_t at_ns, std::int64_t age_ns = 0) {
    arrivals_.push_back({at_ns, age_ns});
  }

  bool poll_until(std::int64_t deadline_ns) override {
    std::int64_t until_ns = deadline_ns;
    const bool arrives =
        next_arrival_ < arrivals_.size() && arrivals_[next_arrival_].at_ns <= deadline_ns;
    if (arrives) until_ns = std::max(clock_.now_ns, arrivals_[next_arrival_].at_ns);
    while (clock_.now_ns < until_ns) {
      clock_.now_ns = std::min(clock_.now_ns + kMsNs, until_ns);
      hand_.tick(clock_.now_ns);
    }
    if (!arrives) return false;
    status_.have_state = true;
    status_.state = state;
    status_.last_state_age_ns = arrivals_[next_arrival_].age_ns;
    ++status_.states;
    last_state_ns_ = clock_.now_ns;
    ++next_arrival_;
    return true;
  }
  [[nodiscard]] const LinkStatus& status() const override { return status_; }
  [[nodiscard]] double state_age_s() const override {
    return status_.have_state ? 1e-9 * static_cast<double>(clock_.now_ns - last_state_ns_)
                              : std::numeric_limits<double>::infinity();
  }
  [[nodiscard]] std::uint32_t vehicle_id() const override { return vehicle_id_; }
  void select_vehicle(std::uint32_t vehicle_id) override { vehicle_id_ = vehicle_id; }
  void send_command(std::int64_t t_ns, const haptics::VelocityCommand& command,
                    bool valid) override {
    commands.push_back({t_ns, valid ? command.v_H_mps : Eigen::Vector3d::Zero(), valid});
    ++status_.commands_sent;
  }
  bool request_mode(std::int64_t t_ns, hq_msgs_Mode mode, const MarkerChoice& marker,
                    bool take_off) override {
    mode_requests.push_back({t_ns, mode, marker, take_off});
    return status_.have_state;
  }
  void send_heartbeat(std::int64_t t_ns) override { heartbeats.push_back(t_ns); }
  [[nodiscard]] const LatencyStats& latency() const override { return stats_; }
  [[nodiscard]] const LatencyStats& round_trip() const override { return stats_; }
  [[nodiscard]] const LatencyStats& state_age() const override { return stats_; }
  [[nodiscard]] double state_loss() const override { return 0.0; }

  LinkStatus& mutable_status() { return status_; }

  struct CommandSent {
    std::int64_t t_ns;
    Eigen::Vector3d v_H_mps;
    bool valid;
  };
  link::VehicleState state{};  ///< What every scheduled state carries.
  std::vector<CommandSent> commands;
  std::vector<ModeRequestSent> mode_requests;
  std::vector<std::int64_t> heartbeats;

 private:
  struct Arrival {
    std::int64_t at_ns;
    std::int64_t age_ns;
  };
  FakeClock& clock_;
  haptics::HapticLoop& hand_;
  std::vector<Arrival> arrivals_;
  std::size_t next_arrival_ = 0;
  LinkStatus status_;
  LatencyStats stats_{1'000'000, 100};
  std::int64_t last_state_ns_ = 0;
  std::uint32_t vehicle_id_ = 1;
};

// A hand that pushes the effector forward from 50 ms on; `script` adds keyframes after that.
haptics::HapticsConfig hand_config(std::vector<haptics::HandKeyframe> script = {}) {
  haptics::HapticsConfig config;
  config.loop.realtime = false;
  config.loop.lock_memory = false;
  haptics::HandKeyframe rest;
  haptics::HandKeyframe pushed;
  pushed.t_s = 0.05;
  pushed.p_D_m = Eigen::Vector3d(0.04, 0.0, 0.0);
  config.sim.script = {rest, pushed};
  for (const haptics::HandKeyframe& k : script) config.sim.script.push_back(k);
  return config;
}

// A forward-looking camera: optical z along body x (FRD), x right, y down.
Eigen::Matrix3d forward_camera() {
  Eigen::Matrix3d R_B_C;
  R_B_C << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  return R_B_C;
}

// Everything one station needs, wired as hq-ground wires it; output captured in memory.
struct Rig {
  explicit Rig(const haptics::HapticsConfig& config = hand_config(),
               OperatorStationOptions options = {})
      : device(config.sim),
        hand(device, config, forward_camera()),
        link(clock, hand),
        out(open_memstream(&out_text, &out_size)),
        log(open_memstream(&log_text, &log_size)),
        station(options, link, hand, model, clock, {nullptr, nullptr, out, log}) {
    link.state.vehicle_id = 1;
    link.state.mode = hq_msgs_MODE_TELEOP;
    link.state.estimator_health = hq_msgs_HEALTH_OK;
  }
  ~Rig() {
    std::fclose(out);
    std::fclose(log);
    std::free(out_text);
    std::free(log_text);
  }
  Rig(const Rig&) = delete;
  Rig& operator=(const Rig&) = delete;
  std::string out_lines() {
    std::fflush(out);
    return {out_text, out_size};
  }
  std::string log_lines() {
    std::fflush(log);
    return {log_text, log_size};
  }
  std::int64_t at_ms(int ms) const { return start_ns + ms * kMsNs; }
  void run_to_ms(int ms) {
    while (clock.now_ns < at_ms(ms)) ASSERT_TRUE(station.step());
  }

  FakeClock clock;
  std::int64_t start_ns = clock.now_ns;
  haptics::SimulatedDevice device;
  haptics::HapticLoop hand;
  FakeLink link;
  console::ConsoleModel model;
  char* out_text = nullptr;
  std::size_t out_size = 0;
  char* log_text = nullptr;
  std::size_t log_size = 0;
  std::FILE* out;
  std::FILE* log;
  OperatorStation station;
};

TEST(OperatorStation, SendsTheHandsCommandAtTheCommandRate) {
  Rig rig;
  rig.run_to_ms(1000);
  // 50 Hz over the first second, the first a period after the start.
  ASSERT_EQ(rig.link.commands.size(), 50U);
  EXPECT_EQ(rig.link.commands.front().t_ns, rig.at_ms(20));
  EXPECT_EQ(rig.link.commands.back().t_ns, rig.at_ms(1000));
  // The hand pushed forward: the last command is forward (eq. 6-10, x of D is forward).
  EXPECT_TRUE(rig.link.commands.back().valid);
  EXPECT_GT(rig.link.commands.back().v_H_mps.x(), 0.1);
  // Heartbeats at 10 Hz from the start.
  EXPECT_EQ(rig.link.heartbeats.size(), 11U);  // at 20 ms, then every 100 ms
  EXPECT_EQ(rig.station.stats().ticks, 50U);
}

TEST(OperatorStation, StopsAtTheDurationWithoutSending) {
  OperatorStationOptions options;
  options.duration_s = 0.1;
  Rig rig(hand_config(), options);
  int steps = 0;
  while (rig.station.step()) ++steps;
  EXPECT_EQ(steps, 4);  // 20, 40, 60, 80 ms; the 100 ms tick ends the flight
  EXPECT_EQ(rig.link.commands.size(), 4U);
}

TEST(OperatorStation, LostDeviceSendsZeroCommandsAndIsCountedOnce) {
  haptics::HandKeyframe lost;
  lost.t_s = 0.3;
  lost.p_D_m = Eigen::Vector3d(0.04, 0.0, 0.0);
  lost.connected = false;
  Rig rig(hand_config({lost}));
  rig.run_to_ms(600);
  EXPECT_EQ(rig.station.stats().device_losses, 1U);
  EXPECT_FALSE(rig.link.commands.back().valid);
  EXPECT_EQ(rig.link.commands.back().v_H_mps, Eigen::Vector3d::Zero());
  EXPECT_THAT(rig.log_lines(), HasSubstr("device lost"));
}

// The hand under the same push with vehicle states of speed `v_x_mps` arriving at 30 Hz, each
// measured `age_ns` before it arrives (as stamped through the heartbeat clock offset).
haptics::LoopOutput hand_after_1s(bool with_states, float v_x_mps, std::int64_t age_ns) {
  Rig rig;
  rig.link.state.v_H_mps = {v_x_mps, 0.0F, 0.0F};
  for (int ms = 100; with_states && ms <= 1000; ms += 33) {
    rig.link.schedule_state(rig.at_ms(ms), age_ns);
  }
  rig.run_to_ms(1000);
  return rig.hand.latest();
}

TEST(OperatorStation, FreshStateCuesTheHandStaleStateCuesNothing) {
  const haptics::LoopOutput none = hand_after_1s(false, 0.0F, 0);
  EXPECT_EQ(none.cue_weight, 0.0);
  const haptics::LoopOutput fresh = hand_after_1s(true, 0.5F, 0);
  EXPECT_EQ(fresh.cue_weight, 1.0);
  EXPECT_GT((fresh.F_D_n - none.F_D_n).norm(), 0.1);
  // Measured 2 s before arrival: past the force law's fade, the vehicle's motion adds no force;
  // the hand feels what it feels without any vehicle state.
  const haptics::LoopOutput stale = hand_after_1s(true, 0.5F, 2'000 * kMsNs);
  EXPECT_EQ(stale.cue_weight, 0.0);
  EXPECT_EQ(stale.F_D_n, none.F_D_n);
}

TEST(OperatorStation, KeepsTheLargestGapBetweenStates) {
  Rig rig;
  rig.link.schedule_state(rig.at_ms(100));
  rig.link.schedule_state(rig.at_ms(130));
  rig.link.schedule_state(rig.at_ms(380));
  rig.run_to_ms(500);
  EXPECT_NEAR(rig.station.stats().max_state_gap_s, 0.25, 1e-9);
}

TEST(OperatorStation, ButtonTogglesTeleopAndHover) {
  haptics::HandKeyframe press;
  press.t_s = 0.2;
  press.buttons = 1;
  haptics::HandKeyframe release;
  release.t_s = 0.4;
  Rig rig(hand_config({press, release}));
  rig.link.schedule_state(rig.at_ms(100));
  rig.run_to_ms(1000);
  // One rising edge of button 0 while the vehicle flies teleop: one hover request.
  ASSERT_EQ(rig.link.mode_requests.size(), 1U);
  EXPECT_EQ(rig.link.mode_requests[0].mode, hq_msgs_MODE_HOVER);
  EXPECT_FALSE(rig.link.mode_requests[0].take_off);
  EXPECT_THAT(rig.log_lines(), HasSubstr("requesting mode hover"));
}

TEST(OperatorStation, WindowRequestsBecomeModeRequestsOnce) {
  Rig rig;
  rig.run_to_ms(100);
  rig.station.requests().mode = hq_msgs_MODE_LAND;
  rig.run_to_ms(200);
  ASSERT_EQ(rig.link.mode_requests.size(), 1U);
  EXPECT_EQ(rig.link.mode_requests[0].mode, hq_msgs_MODE_LAND);
  // Nothing heard yet: the request waits for the vehicle, and says so.
  EXPECT_THAT(rig.log_lines(), HasSubstr("requesting mode land (waiting for vehicle)"));

  rig.station.requests().take_off = true;
  rig.run_to_ms(300);
  ASSERT_EQ(rig.link.mode_requests.size(), 2U);
  EXPECT_EQ(rig.link.mode_requests[1].mode, hq_msgs_MODE_TELEOP);
  EXPECT_TRUE(rig.link.mode_requests[1].take_off);

  rig.station.requests().marker_task = hq_msgs_MARKER_TASK_GO_TO;
  rig.station.requests().marker_id = 7;
  rig.station.requests().mode = hq_msgs_MODE_MARKER;
  rig.station.requests().vehicle = 3;
  rig.run_to_ms(400);
  ASSERT_EQ(rig.link.mode_requests.size(), 3U);
  EXPECT_EQ(rig.link.mode_requests[2].marker.task, hq_msgs_MARKER_TASK_GO_TO);
  EXPECT_EQ(rig.link.mode_requests[2].marker.target_id, 7);
  EXPECT_EQ(rig.link.vehicle_id(), 3U);
}

TEST(OperatorStation, CommandLineTakeOffAndMarkerTaskWaitForTheVehicle) {
  OperatorStationOptions options;
  options.take_off = true;
  options.marker = {hq_msgs_MARKER_TASK_HOLD, 4};
  Rig rig(hand_config(), options);
  rig.run_to_ms(500);
  EXPECT_TRUE(rig.link.mode_requests.empty());  // nothing heard: nothing asked
  rig.link.schedule_state(rig.at_ms(510));
  rig.run_to_ms(1000);
  // First tick after the vehicle is heard: take-off; the next: the marker task.
  ASSERT_EQ(rig.link.mode_requests.size(), 2U);
  EXPECT_EQ(rig.link.mode_requests[0].mode, hq_msgs_MODE_TELEOP);
  EXPECT_TRUE(rig.link.mode_requests[0].take_off);
  EXPECT_EQ(rig.link.mode_requests[1].mode, hq_msgs_MODE_MARKER);
  EXPECT_EQ(rig.link.mode_requests[1].marker.task, hq_msgs_MARKER_TASK_HOLD);
  EXPECT_EQ(rig.link.mode_requests[1].marker.target_id, 4);
  EXPECT_THAT(rig.log_lines(), HasSubstr("marker task hold on marker 4"));
}

TEST(OperatorStation, LinkLossIsToldOnceAndRegainedIsToo) {
  Rig rig;
  for (int ms = 100; ms <= 400; ms += 33) rig.link.schedule_state(rig.at_ms(ms));
  for (int ms = 1500; ms <= 2000; ms += 33) rig.link.schedule_state(rig.at_ms(ms));
  rig.run_to_ms(2000);
  const std::string out = rig.out_lines();
  EXPECT_THAT(out, HasSubstr("VEHICLE LINK LOST: no vehicle state for 0.5 s (ground)"));
  EXPECT_THAT(out, HasSubstr("vehicle link regained after"));
  EXPECT_EQ(rig.station.link_loss().losses(), 1U);
  hq::console::Snapshot snap = rig.model.make_snapshot();
  rig.model.snapshot(snap);
  EXPECT_EQ(snap.link.link_losses, 1U);
  EXPECT_FALSE(snap.link.link_lost);
  EXPECT_GE(snap.event_count, 2U);
}

TEST(OperatorStation, ControlLostReachesTheConsole) {
  OperatorStationOptions options;
  options.station_id = 2;
  Rig rig(hand_config(), options);
  rig.link.schedule_state(rig.at_ms(100));
  rig.run_to_ms(300);
  rig.link.mutable_status().control_lost = true;
  rig.link.mutable_status().commanding_station_id = 5;
  rig.run_to_ms(600);
  hq::console::Snapshot snap = rig.model.make_snapshot();
  rig.model.snapshot(snap);
  EXPECT_TRUE(snap.link.control_lost);
  EXPECT_EQ(snap.link.commanding_station, 5U);
  EXPECT_EQ(snap.link.own_station, 2U);
}

TEST(OperatorStation, HeadlessPrintsOneStatusLinePerSecond) {
  OperatorStationOptions options;
  options.headless = true;
  Rig rig(hand_config(), options);
  rig.link.schedule_state(rig.at_ms(100));
  rig.run_to_ms(2000);
  const std::string log = rig.log_lines();
  EXPECT_THAT(log, HasSubstr("link waiting"));  // the first line, before any state
  EXPECT_THAT(log, HasSubstr("vehicle teleop"));
  std::size_t lines = 0;
  for (std::size_t at = log.find("t "); at != std::string::npos; at = log.find("\nt ", at + 1)) {
    ++lines;
  }
  EXPECT_EQ(lines, 3U);  // at 20 ms, 1 s and 2 s
}

}  // namespace
}  // namespace hq::ground
