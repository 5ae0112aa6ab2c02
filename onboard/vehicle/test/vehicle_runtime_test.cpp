// VehicleRuntime: frames at their stamps with the IMU first, the setpoint stream gated on the
// first estimate, the flight controller's loss, disarm and offboard exit said once and answered
// by the chain, arming only on an operator's request, and no allocation per step.
#include "hq/vehicle/vehicle_runtime.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/odometry/rendered_plane.hpp"
#include "hq/testing/allocation_counter.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace hq::vehicle {
namespace {

using ::testing::HasSubstr;

const geometry::PinholeCamera kCamera{260.0, 260.0, 159.5, 119.5, 320, 240};
constexpr std::int64_t kFramePeriodNs = 33'333'333;
constexpr std::int64_t kStepNs = 5'000'000;

/// Frames of a textured plane 2 m ahead, the camera moving slowly along its x axis.
class PlaneSource final : public sources::FrameSource {
 public:
  explicit PlaneSource(int frames) : frames_(frames) {}
  sources::FrameStatus next(sources::RgbdFrame& frame) override {
    if (index_ == frames_) return sources::FrameStatus::kEndOfStream;
    if (hold_) return sources::FrameStatus::kNoFrame;
    const std::int64_t t_ns = (index_ + 1) * kFramePeriodNs + out_of_order_shift_;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation().x() = 0.2 * hq::to_seconds(t_ns);
    odometry::test::render_textured_plane(kCamera, T, 2.0, frame.gray, frame.depth_m);
    frame.t_ns = t_ns;
    ++index_;
    return sources::FrameStatus::kFrame;
  }
  [[nodiscard]] geometry::PinholeCamera camera() const override { return kCamera; }
  [[nodiscard]] std::string describe() const override { return "plane"; }
  bool hold_ = false;
  std::int64_t out_of_order_shift_ = 0;

 private:
  int frames_;
  int index_ = 0;
};

/// A flight controller the test scripts: IMU at 200 Hz (level, at rest), a status it sets.
class FakeFc final : public FlightController {
 public:
  void poll(std::int64_t t_ns, FcSink& sink) override {
    for (; next_imu_ns_ <= t_ns; next_imu_ns_ += kStepNs) {
      sink.on_imu({next_imu_ns_, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 0.0, -9.80665)});
    }
  }
  void send_setpoint(std::int64_t /*t_ns*/, const control::AttitudeSetpoint& s) override {
    ++setpoints;
    last = s;
  }
  void send_velocity(const VelocityReport& report) override {
    ++velocity_estimates;
    last_velocity = report;
  }
  void request_arm_offboard(std::int64_t /*t_ns*/) override { ++arm_requests; }
  [[nodiscard]] FcStatus status(std::int64_t /*t_ns*/) const override { return fc_status; }
  [[nodiscard]] std::string describe() const override { return "fake"; }

  FcStatus fc_status;
  VelocityReport last_velocity;
  int setpoints = 0;
  int velocity_estimates = 0;
  int arm_requests = 0;
  control::AttitudeSetpoint last;

 private:
  std::int64_t next_imu_ns_ = kStepNs;
};

/// Records events and hands out queued mode requests.
class RecordingPort final : public OperatorPort {
 public:
  modes::OperatorCommand poll(std::int64_t, std::vector<pipeline::ModeRequest>& requests) override {
    for (const pipeline::ModeRequest& r : queued) requests.push_back(r);
    queued.clear();
    return {};
  }
  void on_output(const pipeline::ChainOutput& out, const VehicleStatus& status) override {
    ++outputs;
    last_degraded = status.degraded();
    estimate_ok += out.estimate.ok() ? 1 : 0;
  }
  void on_event(std::int64_t, FcSeverity severity, std::string_view text) override {
    events.emplace_back(text);
    errors += severity == FcSeverity::kError ? 1 : 0;
  }
  std::vector<pipeline::ModeRequest> queued;
  std::vector<std::string> events;
  int outputs = 0;
  int estimate_ok = 0;
  int errors = 0;
  bool last_degraded = false;
};

pipeline::OnboardConfig airborne_config() {
  pipeline::OnboardConfig config;
  config.modes.start_landed = false;
  return config;
}

struct Rig {
  explicit Rig(int frames, const pipeline::OnboardConfig& config = airborne_config())
      : chain(config, VehicleConfig{}, kCamera), source(frames) {
    runtime = std::make_unique<VehicleRuntime>(chain, source, fc, &port);
  }
  void run_until(std::int64_t end_ns) {
    for (; t_ns <= end_ns; t_ns += kStepNs) runtime->step(t_ns);
  }
  pipeline::OnboardChain chain;
  PlaneSource source;
  FakeFc fc;
  RecordingPort port;
  std::unique_ptr<VehicleRuntime> runtime;
  std::int64_t t_ns = kStepNs;
};

bool contains(const std::vector<std::string>& texts, const char* needle) {
  for (const std::string& t : texts) {
    if (t.find(needle) != std::string::npos) return true;
  }
  return false;
}

// GIVEN a source of 20 frames WHEN stepped past them THEN each is processed once at its stamp,
// the source's end ends the run, and the velocity estimate goes to the FC with each frame.
TEST(VehicleRuntime, ProcessesEveryFrameOnceAndEndsWithTheSource) {
  Rig rig(20);
  rig.run_until(30 * kFramePeriodNs);
  EXPECT_EQ(rig.runtime->counters().frames, 20U);
  EXPECT_TRUE(rig.runtime->ended());
  EXPECT_FALSE(rig.runtime->step(rig.t_ns));
  EXPECT_GT(rig.port.estimate_ok, 10);
  EXPECT_GT(rig.fc.velocity_estimates, 10);
  EXPECT_GT(rig.runtime->counters().imu_samples, 100U);
}

// GIVEN a frame stamped no later than the previous one WHEN it arrives THEN it is dropped and
// counted, never handed to the chain.
TEST(VehicleRuntime, DropsAFrameThatIsNotNewer) {
  Rig rig(6);
  rig.run_until(3 * kFramePeriodNs);
  const std::uint64_t before = rig.runtime->counters().frames;
  rig.source.out_of_order_shift_ = -10 * kFramePeriodNs;  // every later frame is older
  rig.run_until(8 * kFramePeriodNs);
  EXPECT_EQ(rig.runtime->counters().frames_out_of_order, 3U);
  // The frame already read ahead (stamped 3 periods) is newer and still flown.
  EXPECT_EQ(rig.runtime->counters().frames, before + 1);
}

// GIVEN no frame yet (so no estimate) WHEN the chain ticks on the camera timeout THEN nothing
// is streamed to the FC; after the first estimate the stream starts and an event says so.
TEST(VehicleRuntime, StreamsSetpointsOnlyAfterTheFirstEstimate) {
  Rig rig(40);
  rig.source.hold_ = true;
  rig.run_until(500'000'000);
  EXPECT_EQ(rig.fc.setpoints, 0);
  EXPECT_GT(rig.runtime->counters().setpoints_withheld, 0U);
  EXPECT_FALSE(rig.runtime->status().streaming);
  rig.source.hold_ = false;
  rig.run_until(rig.t_ns + 20 * kFramePeriodNs);
  EXPECT_TRUE(rig.runtime->status().streaming);
  EXPECT_GT(rig.fc.setpoints, 0);
  EXPECT_TRUE(contains(rig.port.events, "first estimate: setpoint stream to the FC started"));
}

// GIVEN a vehicle that starts landed WHEN no frame has come yet THEN it streams its idle
// setpoints at once (the FC needs the stream before offboard), with zero thrust.
TEST(VehicleRuntime, StreamsIdleSetpointsWhileLanded) {
  pipeline::OnboardConfig config;
  config.modes.start_landed = true;
  Rig rig(40, config);
  rig.source.hold_ = true;
  rig.run_until(500'000'000);
  EXPECT_TRUE(rig.runtime->status().streaming);
  EXPECT_GT(rig.fc.setpoints, 0);
  EXPECT_LT(rig.fc.last.thrust_n, 0.5);
  EXPECT_TRUE(contains(rig.port.events, "landed and at rest"));
}

// GIVEN a connected, armed FC in offboard WHEN its heartbeat stops THEN one error event, the
// chain holds (hover) and the vehicle reports degraded; heard again, it says so once.
TEST(VehicleRuntime, SaysFlightControllerLostOnceAndHolds) {
  Rig rig(200);
  rig.fc.fc_status = {true, true, true, 0, -1.0, -1};
  rig.chain.request_mode(modes::Mode::kTeleop, modes::RequestOrigin::kOperator);
  rig.run_until(10 * kFramePeriodNs);
  rig.fc.fc_status.connected = false;
  rig.fc.fc_status.heartbeat_age_ns = 1'200'000'000;
  rig.run_until(rig.t_ns + 10 * kFramePeriodNs);
  EXPECT_EQ(rig.port.errors, 1) << ::testing::PrintToString(rig.port.events);
  EXPECT_TRUE(contains(rig.port.events, "flight controller lost: nothing heard for 1200 ms"));
  EXPECT_EQ(rig.chain.mode(), modes::Mode::kHover);
  EXPECT_TRUE(rig.runtime->status().fc_lost);
  EXPECT_TRUE(rig.port.last_degraded);
  rig.fc.fc_status.connected = true;
  rig.run_until(rig.t_ns + 2 * kFramePeriodNs);
  EXPECT_TRUE(contains(rig.port.events, "flight controller heard again"));
  EXPECT_FALSE(rig.runtime->status().fc_lost);
}

// GIVEN flying in offboard WHEN the FC leaves offboard (its failsafe, the pilot) THEN the
// runtime says so, the chain holds, and it never asks to re-enter offboard by itself; WHEN the
// FC then disarms THEN the chain lands. Only the operator's teleop request asks to arm again.
TEST(VehicleRuntime, NeverReArmsByItselfAfterTheFlightControllerTakesOver) {
  Rig rig(300);
  rig.fc.fc_status = {true, true, true, 0, -1.0, -1};
  rig.chain.request_mode(modes::Mode::kTeleop, modes::RequestOrigin::kOperator);
  rig.run_until(10 * kFramePeriodNs);
  rig.fc.fc_status.offboard = false;
  rig.run_until(rig.t_ns + 10 * kFramePeriodNs);
  EXPECT_TRUE(contains(rig.port.events, "left offboard"));
  EXPECT_EQ(rig.chain.mode(), modes::Mode::kHover);
  EXPECT_TRUE(rig.runtime->status().fc_override);
  rig.fc.fc_status.armed = false;
  rig.run_until(rig.t_ns + 10 * kFramePeriodNs);
  EXPECT_EQ(rig.fc.arm_requests, 0);
  EXPECT_GT(rig.fc.setpoints, 0);  // the stream stays alive: PX4 accepts offboard only with it

  rig.port.queued.push_back({modes::Mode::kTeleop, std::nullopt});
  rig.run_until(rig.t_ns + kStepNs);
  EXPECT_EQ(rig.fc.arm_requests, 1);
  EXPECT_TRUE(contains(rig.port.events, "requesting the FC to arm"));
  rig.run_until(rig.t_ns + 10 * kFramePeriodNs);
  EXPECT_EQ(rig.fc.arm_requests, 1);
  // Refused (the FC stays disarmed): asked again once a second, five times, then given up.
  rig.run_until(rig.t_ns + 6'000'000'000);
  EXPECT_EQ(rig.fc.arm_requests, 5);
  EXPECT_TRUE(contains(rig.port.events, "did not arm and enter offboard after 5 requests"));
}

// GIVEN an operator who asks to fly before the FC is heard WHEN the FC is heard THEN the
// runtime asks it to arm then, once.
TEST(VehicleRuntime, ArmsWhenTheFlightControllerIsHeardAfterTheOperatorsRequest) {
  pipeline::OnboardConfig config;
  config.modes.start_landed = true;
  Rig rig(300, config);
  rig.port.queued.push_back({modes::Mode::kTeleop, std::nullopt});
  rig.run_until(10 * kFramePeriodNs);
  EXPECT_EQ(rig.fc.arm_requests, 0);
  rig.fc.fc_status = {true, false, false, 0, -1.0, -1};
  rig.run_until(rig.t_ns + kStepNs);
  EXPECT_EQ(rig.fc.arm_requests, 1);
  rig.fc.fc_status.armed = rig.fc.fc_status.offboard = true;
  rig.run_until(rig.t_ns + 3'000'000'000);
  EXPECT_EQ(rig.fc.arm_requests, 1);
  EXPECT_FALSE(rig.runtime->status().fc_override);
}

// GIVEN an FC that was armed and offboard WHEN it disarms on its own THEN the chain lands.
TEST(VehicleRuntime, LandsWhenTheFlightControllerDisarms) {
  Rig rig(100);
  rig.fc.fc_status = {true, true, true, 0, -1.0, -1};
  rig.chain.request_mode(modes::Mode::kTeleop, modes::RequestOrigin::kOperator);
  rig.run_until(5 * kFramePeriodNs);
  rig.fc.fc_status.armed = false;
  rig.run_until(rig.t_ns + 2 * kFramePeriodNs);
  EXPECT_TRUE(contains(rig.port.events, "disarmed"));
  EXPECT_EQ(rig.chain.mode(), modes::Mode::kLand);
}

// GIVEN flying in teleop WHEN the run ends with StopAction::kLand THEN the chain lands on the
// vehicle's own request, the operator's later requests to fly are not taken, and the stop is
// complete only once the chain believes it is on the ground.
TEST(VehicleRuntime, StopLandsAndNoLongerTakesTheOperator) {
  // The plane ahead reads as 2 m of height: the floor is allowed that far for the touchdown.
  pipeline::OnboardConfig config = airborne_config();
  config.modes.touchdown_max_height_m = 5.0;
  Rig rig(2000, config);
  rig.fc.fc_status = {true, true, true, 0, -1.0, -1};
  rig.chain.request_mode(modes::Mode::kTeleop, modes::RequestOrigin::kOperator);
  rig.run_until(10 * kFramePeriodNs);
  ASSERT_FALSE(rig.runtime->stop_complete());
  rig.runtime->begin_stop(rig.t_ns, StopAction::kLand);
  EXPECT_TRUE(rig.runtime->stopping());
  EXPECT_TRUE(contains(rig.port.events, "vehicle stopping: landing"));
  EXPECT_EQ(rig.chain.mode(), modes::Mode::kLand);
  rig.port.queued.push_back({modes::Mode::kTeleop, std::nullopt});
  rig.run_until(rig.t_ns + 2 * kFramePeriodNs);
  EXPECT_EQ(rig.chain.mode(), modes::Mode::kLand);
  EXPECT_TRUE(rig.port.queued.empty());  // polled: the link stays served
  EXPECT_FALSE(rig.runtime->stop_complete());
  for (int i = 0; i < 3000 && !rig.runtime->stop_complete(); ++i) rig.run_until(rig.t_ns);
  EXPECT_TRUE(rig.runtime->stop_complete());
  ASSERT_TRUE(rig.runtime->last_output().has_value());
  EXPECT_TRUE(rig.runtime->last_output()->mode.landed);
  EXPECT_LT(rig.fc.last.thrust_n, 0.5);  // motors idle
  EXPECT_EQ(rig.fc.arm_requests, 0);
}

// GIVEN flying in teleop WHEN the run ends with StopAction::kHold THEN the chain hovers and the
// stop completes without landing; a second begin_stop changes nothing.
TEST(VehicleRuntime, StopHoldsWhenAskedTo) {
  Rig rig(200);
  rig.fc.fc_status = {true, true, true, 0, -1.0, -1};
  rig.chain.request_mode(modes::Mode::kTeleop, modes::RequestOrigin::kOperator);
  rig.run_until(10 * kFramePeriodNs);
  rig.runtime->begin_stop(rig.t_ns, StopAction::kHold);
  rig.runtime->begin_stop(rig.t_ns, StopAction::kLand);
  rig.run_until(rig.t_ns + 2 * kFramePeriodNs);
  EXPECT_EQ(rig.chain.mode(), modes::Mode::kHover);
  EXPECT_TRUE(rig.runtime->stop_complete());
  EXPECT_FALSE(rig.runtime->last_output()->mode.landed);
  EXPECT_TRUE(contains(rig.port.events, "vehicle stopping: holding"));
}

// After the first frames have sized every buffer, a step allocates nothing.
TEST(VehicleRuntime, StepAllocatesNothingAfterTheFirstFrames) {
  pipeline::OnboardChain chain(airborne_config(), VehicleConfig{}, kCamera);
  PlaneSource source(100);
  FakeFc fc;
  NoFlightController none;
  VehicleRuntime runtime(chain, source, fc, nullptr);
  std::int64_t t_ns = kStepNs;
  for (; t_ns < 10 * kFramePeriodNs; t_ns += kStepNs) runtime.step(t_ns);
  // The plane is rendered by the test's source, which allocates; count only the runtime.
  long allocations = 0;
  for (; t_ns < 40 * kFramePeriodNs; t_ns += kStepNs) {
    sources::RgbdFrame dummy;
    (void)dummy;
    const long before = hq::testing::allocation_count();
    runtime.step(t_ns);
    allocations += hq::testing::allocation_count() - before;
  }
  EXPECT_GT(runtime.counters().frames, 30U);
  // The source renders inside step(); its cv::Mat buffers are reused after the first frame.
  EXPECT_EQ(allocations, 0);
}

TEST(VehicleRuntime, RejectsAConfigOutOfRange) {
  pipeline::OnboardChain chain(airborne_config(), VehicleConfig{}, kCamera);
  PlaneSource source(1);
  NoFlightController none;
  RuntimeConfig config;
  config.control_period_ns = 0;
  try {
    VehicleRuntime runtime(chain, source, none, nullptr, nullptr, config);
    ADD_FAILURE() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("control_period_ns = 0"));
  }
}

// --fc none replays recorded IMU by stamp, or makes a level one at its rate.
TEST(NoFlightController, ReplaysRecordedImuOrMakesALevelOne) {
  struct Count final : FcSink {
    void on_imu(const FcImuSample& s) override {
      ++n;
      last = s;
    }
    int n = 0;
    FcImuSample last;
  } sink;
  NoFlightController recorded({{10, Eigen::Vector3d(0.1, 0, 0), Eigen::Vector3d::Zero()},
                               {20, Eigen::Vector3d(0.2, 0, 0), Eigen::Vector3d::Zero()}});
  recorded.poll(15, sink);
  EXPECT_EQ(sink.n, 1);
  recorded.poll(25, sink);
  EXPECT_EQ(sink.n, 2);
  EXPECT_DOUBLE_EQ(sink.last.omega_B_radps.x(), 0.2);
  EXPECT_FALSE(recorded.status(0).connected);

  NoFlightController level;
  level.set_tilt_source(nullptr, Eigen::Matrix3d::Identity(), 200.0);
  sink.n = 0;
  level.poll(0, sink);
  level.poll(100'000'000, sink);
  EXPECT_EQ(sink.n, 21);
  EXPECT_NEAR(sink.last.f_B_mps2.z(), -9.80665, 1e-9);
}

}  // namespace
}  // namespace hq::vehicle
