// hq-sim --sitl as a real process, with this test as the companion computer: MAVLink over
// loopback UDP with the codec, frames from the shared-memory channel. GIVEN a SITL process, WHEN
// the companion streams heartbeats and setpoints, asks for OFFBOARD and arms, THEN it flies the
// setpoints; WHEN the setpoints stop, THEN it lands and disarms; SIGTERM ends it with the summary
// and the channel unlinked. Each test uses its own port and channel name.
#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/frame_channel/frame_channel.hpp"
#include "hq/mavlink/codec.hpp"
#include "hq/mavlink/transport.hpp"
#include "hq/testing/process.hpp"
#include "hq/vehicle/mavlink_flight_controller.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <memory>
#include <optional>
#include <random>
#include <regex>
#include <signal.h>
#include <span>
#include <sstream>
#include <string>
#include <string_view>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
namespace mav = hq::mavlink;
using hq::testing::Process;
using ::testing::HasSubstr;

std::string slurp(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// A port and channel name per test process and test.
int test_port(int offset) { return 30000 + static_cast<int>(getpid() % 15000) * 2 + offset; }
std::string test_channel(const std::string& what) {
  return "sitl-test-" + what + "-" + std::to_string(getpid());
}

double number_after(const std::string& text, const std::string& pattern) {
  std::smatch m;
  if (!std::regex_search(text, m, std::regex(pattern + " ([0-9.]+)"))) return -1.0;
  return std::stod(m[1]);
}

/// The companion computer: the codec on a UDP transport to hq-sim, and the frame channel.
class Companion {
 public:
  explicit Companion(int port)
      : transport_(mav::open_transport("udp:127.0.0.1:" + std::to_string(port))),
        encoder_(1, mav::kMavCompIdOnboardComputer) {}

  void send(const mav::Message& message) {
    std::array<std::uint8_t, mav::kMaxFrameSize> buffer{};
    const std::size_t n = encoder_.encode(message, buffer);
    transport_->send(std::span<const std::uint8_t>(buffer.data(), n));
  }
  void heartbeat() {
    mav::Heartbeat h;
    h.type = mav::kMavTypeOnboardController;
    h.autopilot = mav::kMavAutopilotInvalid;
    send(h);
  }
  void setpoint(float thrust) {
    mav::SetAttitudeTarget s;
    s.target_system = 1;
    s.target_component = 1;
    s.thrust = thrust;
    s.type_mask = mav::kAttitudeTargetIgnoreBodyRollRate | mav::kAttitudeTargetIgnoreBodyPitchRate;
    send(s);
  }
  void command(std::uint16_t id, float p1, float p2 = 0.0f) {
    mav::CommandLong c;
    c.target_system = 1;
    c.target_component = 1;
    c.command = id;
    c.param[0] = p1;
    c.param[1] = p2;
    send(c);
  }

  /// Takes everything pending (messages and the newest frame).
  void poll() {
    std::array<std::uint8_t, 2048> rx{};
    for (std::size_t n = transport_->receive(rx); n > 0; n = transport_->receive(rx)) {
      parser_.feed(std::span<const std::uint8_t>(rx.data(), n),
                   [&](const mav::FrameHeader& header, const mav::Message& m) {
                     EXPECT_EQ(header.system_id, 1);
                     EXPECT_EQ(header.component_id, 1);
                     on_message(m);
                   });
      parser_.end_of_datagram();
    }
    if (!frames_) {
      try {
        frames_ = std::make_unique<hq::frame_channel::FrameChannelReader>(channel_);
      } catch (const hq::InputError&) {
        return;  // hq-sim not up yet
      }
    }
    hq::frame_channel::FrameInfo info;
    if (frames_->take_latest(image_, depth_, info)) {
      const std::int64_t now_ns = hq::monotonic_now_ns();
      if (frame_count_ > 0 && info.t_ns <= last_frame_.t_ns) frame_stamps_increasing_ = false;
      // A host-clock stamp of the exposure: in the past, by less than a render and a poll.
      if (info.t_ns > now_ns || now_ns - info.t_ns > 300'000'000) frame_stamps_recent_ = false;
      last_frame_ = info;
      ++frame_count_;
    }
  }

  /// Polls for `seconds`, calling tick() every 20 ms (the companion's 50 Hz loop).
  template <typename Tick>
  void run_for(double seconds, Tick tick) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    auto next_heartbeat = std::chrono::steady_clock::now();
    while (std::chrono::steady_clock::now() < end) {
      if (std::chrono::steady_clock::now() >= next_heartbeat) {
        heartbeat();
        next_heartbeat += std::chrono::milliseconds(500);
      }
      poll();
      tick();
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  void run_for(double seconds) {
    run_for(seconds, [] {});
  }

  void on_message(const mav::Message& m) {
    if (const auto* imu = std::get_if<mav::HighresImu>(&m)) {
      if (imu_count_ > 0 && imu->time_usec <= last_imu_usec_) imu_increasing_ = false;
      if (imu->fields_updated != 0x3F) imu_fields_ok_ = false;
      if (imu_count_ == 0) first_imu_usec_ = imu->time_usec;
      last_imu_usec_ = imu->time_usec;
      ++imu_count_;
    } else if (const auto* h = std::get_if<mav::Heartbeat>(&m)) {
      last_heartbeat_ = *h;
      ++heartbeats_;
    } else if (const auto* a = std::get_if<mav::CommandAck>(&m)) {
      acks_.push_back(*a);
    } else if (const auto* s = std::get_if<mav::Statustext>(&m)) {
      texts_.append(s->text.data(), strnlen(s->text.data(), s->text.size())).append("\n");
    } else if (const auto* att = std::get_if<mav::Attitude>(&m)) {
      last_attitude_ = *att;
      ++attitudes_;
    }
  }

  [[nodiscard]] bool armed() const {
    return last_heartbeat_ && (last_heartbeat_->base_mode & mav::kMavModeFlagSafetyArmed) != 0;
  }
  [[nodiscard]] std::uint32_t custom_mode() const {
    return last_heartbeat_ ? last_heartbeat_->custom_mode : 0;
  }
  /// The ack of the latest COMMAND_LONG `id`, if any.
  [[nodiscard]] std::optional<mav::CommandAck> ack(std::uint16_t id) const {
    for (auto it = acks_.rbegin(); it != acks_.rend(); ++it) {
      if (it->command == id) return *it;
    }
    return std::nullopt;
  }

  std::string channel_;
  std::unique_ptr<mav::Transport> transport_;
  mav::Encoder encoder_;
  mav::Parser parser_;
  std::unique_ptr<hq::frame_channel::FrameChannelReader> frames_;
  cv::Mat image_, depth_;
  hq::frame_channel::FrameInfo last_frame_;
  long frame_count_ = 0;
  bool frame_stamps_increasing_ = true;
  bool frame_stamps_recent_ = true;
  long imu_count_ = 0;
  std::uint64_t first_imu_usec_ = 0, last_imu_usec_ = 0;
  bool imu_increasing_ = true;
  bool imu_fields_ok_ = true;
  std::optional<mav::Heartbeat> last_heartbeat_;
  long heartbeats_ = 0;
  std::optional<mav::Attitude> last_attitude_;
  long attitudes_ = 0;
  std::vector<mav::CommandAck> acks_;
  std::string texts_;
};

class SitlProcess : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(HQ_SITL_ARTEFACT_DIR) /
           ("sitl_test_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  std::vector<std::string> sim_args(int port, const std::string& channel) const {
    return {HQ_SIM_EXE,     "--sitl",
            "--world",      "onboard/sim/worlds/arena.yaml",
            "--mavlink",    "udp-listen:" + std::to_string(port),
            "--channel",    channel,
            "--duration-s", "90"};
  }
  fs::path dir_;
};

/// THEN IMU at 500 Hz with increasing stamps, frames with increasing recent host stamps, and
/// IMU time_usec on the frames' time origin; the vehicle on the ground, disarmed.
void expect_sensor_streams(Companion& companion) {
  const long imu_before = companion.imu_count_;
  const std::uint64_t usec_before = companion.last_imu_usec_;
  companion.run_for(1.0);
  const double imu_span_s = static_cast<double>(companion.last_imu_usec_ - usec_before) * 1e-6;
  EXPECT_NEAR(static_cast<double>(companion.imu_count_ - imu_before) / imu_span_s, 500.0, 10.0);
  EXPECT_TRUE(companion.imu_increasing_);
  EXPECT_TRUE(companion.imu_fields_ok_);
  EXPECT_GT(companion.frame_count_, 20) << "30 Hz frames, polled at 50 Hz";
  EXPECT_TRUE(companion.frame_stamps_increasing_);
  EXPECT_TRUE(companion.frame_stamps_recent_);
  // Frame stamps and IMU time_usec share the origin the channel publishes: the newest IMU
  // sample, mapped onto the host clock, is in the past and recent.
  ASSERT_TRUE(companion.frames_);
  const std::int64_t origin_ns = companion.frames_->time_origin_ns();
  ASSERT_GT(origin_ns, 0);
  const std::int64_t imu_host_ns =
      origin_ns + 1000 * static_cast<std::int64_t>(companion.last_imu_usec_);
  const std::int64_t now_ns = hq::monotonic_now_ns();
  EXPECT_LT(imu_host_ns, now_ns);
  EXPECT_GT(imu_host_ns, now_ns - 200'000'000);
  ASSERT_TRUE(companion.last_frame_.has_truth);
  EXPECT_TRUE(companion.last_frame_.truth.on_ground);
  EXPECT_GE(companion.heartbeats_, 2);
  EXPECT_GE(companion.attitudes_, 80);
  EXPECT_FALSE(companion.armed());
}

/// The companion's velocity report: the channel's true v_H rotated by the FC's yaw into NED.
mav::VisionSpeedEstimate true_velocity_ned(const Companion& companion) {
  const auto& truth = companion.last_frame_.truth;
  const double yaw =
      companion.last_attitude_ ? static_cast<double>(companion.last_attitude_->yaw_rad) : 0.0;
  mav::VisionSpeedEstimate v;
  v.x_mps = static_cast<float>(std::cos(yaw) * truth.v_H_mps[0] - std::sin(yaw) * truth.v_H_mps[1]);
  v.y_mps = static_cast<float>(std::sin(yaw) * truth.v_H_mps[0] + std::cos(yaw) * truth.v_H_mps[1]);
  v.z_mps = static_cast<float>(truth.v_H_mps[2]);
  return v;
}

/// WHEN the setpoints stop (heartbeats go on), THEN LAND, touchdown and disarm.
void expect_lands_on_setpoint_loss(Companion& companion) {
  companion.run_for(1.0);
  EXPECT_THAT(companion.texts_, HasSubstr("offboard setpoints lost: landing"));
  EXPECT_EQ(companion.custom_mode(), 4u << 16 | 6u << 24) << "AUTO.LAND";
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (companion.armed() && std::chrono::steady_clock::now() < deadline) companion.run_for(0.2);
  EXPECT_FALSE(companion.armed());
  EXPECT_TRUE(companion.last_frame_.truth.on_ground);
  EXPECT_THAT(companion.texts_, HasSubstr("landed: disarmed"));
}

TEST_F(SitlProcess, CompanionArmsFliesOffboardThenLosesSetpointsAndTheSimLandsAndDisarms) {
  const int port = test_port(0);
  const std::string channel = test_channel("flight");
  const fs::path out = dir_ / "sim.out";
  Process sim(sim_args(port, channel), out.string());
  ASSERT_TRUE(sim.started());
  Companion companion(port);
  companion.channel_ = channel;

  // GIVEN hq-sim up (it answers once it learns our address from a heartbeat).
  companion.run_for(1.5);
  const std::string banner = slurp(out);
  const double max_thrust_n = number_after(banner, "max thrust");
  const double hover_n = number_after(banner, "hover");
  ASSERT_GT(max_thrust_n, 0.0) << banner;
  ASSERT_GT(hover_n, 0.0) << banner;
  const float hover = static_cast<float>(hover_n / max_thrust_n);
  expect_sensor_streams(companion);
  ASSERT_FALSE(HasFatalFailure());

  // WHEN setpoints stream, OFFBOARD is requested and the vehicle armed.
  // Altitude hold on the channel's truth: climb to 1.5 m, then hover there.
  auto fly = [&] {
    const auto& truth = companion.last_frame_.truth;
    const double v_up_mps = -truth.v_H_mps[2];  // H is NED
    const double a_up_mps2 = 2.0 * (1.5 - truth.p_W_m[2]) - 2.5 * v_up_mps;
    companion.setpoint(hover * static_cast<float>(1.0 + std::clamp(a_up_mps2, -3.0, 3.0) / 9.81));
  };
  companion.run_for(0.3, fly);
  companion.command(mav::kMavCmdDoSetMode, mav::kMavModeFlagCustomModeEnabled, 6.0f);
  companion.run_for(0.2, fly);
  companion.command(mav::kMavCmdComponentArmDisarm, 1.0f);
  companion.run_for(1.5, fly);
  ASSERT_TRUE(companion.ack(mav::kMavCmdDoSetMode).has_value()) << slurp(out);
  EXPECT_EQ(companion.ack(mav::kMavCmdDoSetMode)->result, mav::kMavResultAccepted);
  ASSERT_TRUE(companion.ack(mav::kMavCmdComponentArmDisarm).has_value());
  EXPECT_EQ(companion.ack(mav::kMavCmdComponentArmDisarm)->result, mav::kMavResultAccepted);
  EXPECT_TRUE(companion.armed());
  EXPECT_EQ(companion.custom_mode(), 6u << 16) << "OFFBOARD";
  EXPECT_THAT(companion.texts_, HasSubstr("armed"));

  // THEN it climbs and keeps flying on hover setpoints; the companion reports its velocity.
  companion.run_for(3.0, [&] {
    fly();
    companion.send(true_velocity_ned(companion));
  });
  EXPECT_FALSE(companion.last_frame_.truth.on_ground);
  EXPECT_NEAR(companion.last_frame_.truth.p_W_m[2], 1.5, 0.5) << slurp(out);
  EXPECT_TRUE(companion.armed());
  expect_lands_on_setpoint_loss(companion);

  // SIGTERM: a clean end with the summary, the channel unlinked.
  sim.signal(SIGTERM);
  ASSERT_EQ(sim.wait_exit(10.0), 0) << slurp(out);
  const std::string summary = slurp(out);
  fmt::print("{}", summary);
  EXPECT_THAT(summary, HasSubstr("real-time factor"));
  EXPECT_GT(number_after(summary, "real-time factor"), 0.9);
  EXPECT_THAT(summary, HasSubstr("collision ticks airborne 0"));
  EXPECT_GT(number_after(summary, "setpoints received"), 100.0);
  // PX4 does not fuse VISION_SPEED_ESTIMATE, and neither does the SITL: counted, said once.
  EXPECT_GT(number_after(summary, "VISION_SPEED_ESTIMATE ignored"), 50.0);
  EXPECT_THAT(companion.texts_, HasSubstr("VISION_SPEED_ESTIMATE ignored"));
  EXPECT_EQ(number_after(summary, "fused"), 0.0);
  EXPECT_THAT(summary, HasSubstr("dropped 0"));
  EXPECT_FALSE(fs::exists("/dev/shm/hq-" + channel)) << "the channel is unlinked";
}

/// What the vehicle's FC client hands its runtime.
class CountingSink final : public hq::vehicle::FcSink {
 public:
  void on_imu(const hq::vehicle::FcImuSample& sample) override {
    if (imu > 0 && sample.t_ns <= last_imu_ns) imu_increasing = false;
    last_imu_ns = sample.t_ns;
    ++imu;
  }
  void on_fc_event(hq::vehicle::FcSeverity /*severity*/, std::string_view text) override {
    events.append(text).append("\n");
  }
  long imu = 0;
  std::int64_t last_imu_ns = 0;
  bool imu_increasing = true;
  std::string events;
};

/// The vehicle's 50 Hz loop around its MAVLink FC client: poll, newest frame, and with
/// The velocity noise the companion loop adds to the truth it reports (m/s per axis).
constexpr double kVelocityNoiseMps = 0.1;

/// setpoints on, a setpoint (altitude hold at 1.5 m on the frames' truth) and a velocity
/// estimate (the truth's v_H, which the client turns into NED with the FC's yaw).
struct VehicleLoop {
  hq::vehicle::MavlinkFlightController& fc;
  hq::frame_channel::FrameChannelReader& frames;
  double hover_n;
  CountingSink sink;
  cv::Mat image, depth;
  hq::frame_channel::FrameInfo frame;
  std::mt19937 rng{7};
  std::normal_distribution<double> noise{0.0, 1.0};

  void run_for(double seconds, bool setpoints) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      const std::int64_t t_ns = hq::monotonic_now_ns();
      fc.poll(t_ns, sink);
      frames.take_latest(image, depth, frame);
      if (setpoints) {
        const double v_up_mps = -frame.truth.v_H_mps[2];
        const double a_up_mps2 = 2.0 * (1.5 - frame.truth.p_W_m[2]) - 2.5 * v_up_mps;
        hq::control::AttitudeSetpoint sp;
        sp.thrust_n = hover_n * (1.0 + std::clamp(a_up_mps2, -3.0, 3.0) / 9.81);
        fc.send_setpoint(t_ns, sp);
      }
      // The truth's v_H with 0.1 m/s of white noise per axis, as the report says, stamped at
      // the frame's exposure: what the SITL's filter fuses with its IMU (level flight: roll and
      // pitch near zero). It goes on when the setpoints stop, as the runtime's does, so the
      // SITL's LAND descends on it.
      hq::vehicle::VelocityReport report;
      report.t_ns = frame.t_ns > 0 ? frame.t_ns : t_ns;
      report.v_H_mps =
          Eigen::Vector3d(frame.truth.v_H_mps[0], frame.truth.v_H_mps[1], frame.truth.v_H_mps[2]);
      for (int i = 0; i < 3; ++i) report.v_H_mps[i] += kVelocityNoiseMps * noise(rng);
      report.covariance_H_m2ps2 =
          kVelocityNoiseMps * kVelocityNoiseMps * Eigen::Matrix3d::Identity();
      fc.send_velocity(report);
      // Polled every 2 ms in between, as the runtime polls every control period: an answer's
      // receipt is stamped at the poll that reads it, which bounds the TIMESYNC round trip.
      for (int i = 0; i < 10; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        fc.poll(hq::monotonic_now_ns(), sink);
      }
    }
  }
};

/// The frame channel `channel` once hq-sim has created it (up to 5 s), else nullptr.
std::unique_ptr<hq::frame_channel::FrameChannelReader> open_channel(const std::string& channel) {
  for (int i = 0; i < 100; ++i) {
    try {
      return std::make_unique<hq::frame_channel::FrameChannelReader>(channel);
    } catch (const hq::InputError&) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
  return nullptr;
}

// The vehicle's MavlinkFlightController (onboard/vehicle) against the SITL FC: the contract both
// sides were written to, checked end to end.
TEST_F(SitlProcess, TheVehiclesMavlinkFlightControllerArmsFliesAndIsLandedOnSetpointLoss) {
  const int port = test_port(3);
  const std::string channel = test_channel("vehicle");
  const fs::path out = dir_ / "sim.out";
  Process sim(sim_args(port, channel), out.string());
  ASSERT_TRUE(sim.started());
  const std::unique_ptr<hq::frame_channel::FrameChannelReader> frames = open_channel(channel);
  ASSERT_TRUE(frames) << slurp(out);
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const std::string banner = slurp(out);
  const double hover_n = number_after(banner, "hover");
  ASSERT_GT(hover_n, 0.0) << banner;

  hq::vehicle::MavlinkFcConfig config;
  config.transport = "udp:127.0.0.1:" + std::to_string(port);
  config.max_thrust_n = number_after(banner, "max thrust");
  hq::vehicle::MavlinkFlightController fc(config);
  VehicleLoop loop{fc, *frames, hover_n, {}, {}, {}, {}};
  loop.frame.truth.p_W_m = {0.0, 0.0, 0.08};
  const CountingSink& sink = loop.sink;

  loop.run_for(1.0, true);
  const std::int64_t now_ns = hq::monotonic_now_ns();
  EXPECT_TRUE(fc.status(now_ns).connected) << sink.events;
  EXPECT_GT(sink.imu, 350) << "about 500 Hz";
  EXPECT_TRUE(sink.imu_increasing);
  EXPECT_NEAR(static_cast<double>(sink.last_imu_ns), static_cast<double>(now_ns), 100e6)
      << "IMU stamped on the runtime clock";

  fc.request_arm_offboard(hq::monotonic_now_ns());
  loop.run_for(5.0, true);
  const hq::vehicle::FcStatus flying = fc.status(hq::monotonic_now_ns());
  EXPECT_TRUE(flying.armed) << sink.events << slurp(out);
  EXPECT_TRUE(flying.offboard);
  EXPECT_GT(flying.battery_v, 14.0);
  EXPECT_FALSE(loop.frame.truth.on_ground);
  EXPECT_NEAR(loop.frame.truth.p_W_m[2], 1.5, 0.5);

  // Setpoints stop: the SITL FC lands and disarms; the client reports it.
  loop.run_for(1.0, false);
  EXPECT_FALSE(fc.status(hq::monotonic_now_ns()).offboard);
  EXPECT_THAT(sink.events, HasSubstr("offboard setpoints lost: landing"));
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (fc.status(hq::monotonic_now_ns()).armed && std::chrono::steady_clock::now() < deadline) {
    loop.run_for(0.2, false);
  }
  EXPECT_FALSE(fc.status(hq::monotonic_now_ns()).armed) << sink.events;
  EXPECT_TRUE(loop.frame.truth.on_ground);

  sim.signal(SIGTERM);
  ASSERT_EQ(sim.wait_exit(10.0), 0) << slurp(out);
  const std::string summary = slurp(out);
  fmt::print("{}", summary);
  // The SITL fused the client's ODOMETRY (body FRD) with its own IMU. The received velocity's
  // error is the added noise, 0.1 m/s per axis (0.17 m/s over three), plus the frame truth's
  // age; a Kalman filter on a 30-50 Hz velocity with a 500 Hz IMU averages the white part
  // down by more than half (the unit test measures 0.35 of it), so the fused RMSE must stay
  // below half the noise's.
  const double received = number_after(summary, "against truth \\(NED\\): received");
  const double fused = number_after(summary, "fused with the IMU");
  fmt::print("SITL velocity RMSE: received {:.3f} m/s, fused {:.3f} m/s\n", received, fused);
  EXPECT_GT(number_after(summary, "ODOMETRY received"), 100.0);
  EXPECT_GT(number_after(summary, "fused"), 100.0);
  EXPECT_EQ(number_after(summary, "rejected: frame"), 0.0);
  EXPECT_GT(received, 0.5 * kVelocityNoiseMps * std::sqrt(3.0)) << "the noise reached the SITL";
  EXPECT_LT(fused, 0.5 * kVelocityNoiseMps * std::sqrt(3.0)) << summary;
  EXPECT_LT(fused, received);
  EXPECT_GT(number_after(summary, "LAND descended on vision"), 1.0) << summary;
  // The SITL answers TIMESYNC as PX4 does: the client's clock comes from the round trips. Its
  // clock is the simulated time, paced to the host's: the offset is the SITL's start on the
  // host clock, good to the SITL's 2 ms tick (answers are read once per tick).
  const hq::vehicle::FcCounters fcc = fc.counters();
  fmt::print(
      "TIMESYNC: offset {:.3f} ms, jitter {:.3f} ms, RTT {:.3f} ms, {} answers, {} dropped\n",
      1e-6 * static_cast<double>(fcc.timesync_offset_ns), 1e-6 * fcc.timesync_jitter_ns,
      1e-6 * static_cast<double>(fcc.timesync_rtt_ns),
      static_cast<unsigned long long>(fcc.timesync_samples),
      static_cast<unsigned long long>(fcc.timesync_rejected));
  EXPECT_TRUE(fcc.clock_from_timesync);
  EXPECT_GT(fcc.timesync_samples, 50u);
  EXPECT_LT(fcc.timesync_jitter_ns, 2e6);
  EXPECT_GT(number_after(summary, "TIMESYNC answered"), 50.0);
  EXPECT_THAT(summary, HasSubstr("collision ticks airborne 0"));
}

TEST_F(SitlProcess, BadInputExitsWithStatus2AndAReason) {
  {
    Process sim({HQ_SIM_EXE, "--sitl", "--world", "onboard/sim/worlds/no_such.yaml"},
                (dir_ / "world.out").string());
    EXPECT_EQ(sim.wait_exit(20.0), 2);
    EXPECT_THAT(slurp(dir_ / "world.out"), HasSubstr("no_such.yaml"));
  }
  const int port = test_port(1);
  const std::string channel = test_channel("bad");
  Process first(sim_args(port, channel), (dir_ / "first.out").string());
  ASSERT_TRUE(first.started());
  for (int i = 0; i < 100 && !fs::exists("/dev/shm/hq-" + channel); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ASSERT_TRUE(fs::exists("/dev/shm/hq-" + channel)) << slurp(dir_ / "first.out");
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // past the port's bind

  Process same_channel(sim_args(test_port(2) + 1000, channel), (dir_ / "channel.out").string());
  EXPECT_EQ(same_channel.wait_exit(20.0), 2);
  EXPECT_THAT(slurp(dir_ / "channel.out"),
              HasSubstr("/hq-" + channel + ": frame channel in use by a live writer"));

  Process same_port(sim_args(port, channel + "-2"), (dir_ / "port.out").string());
  EXPECT_EQ(same_port.wait_exit(20.0), 2);
  EXPECT_THAT(slurp(dir_ / "port.out"),
              HasSubstr("UDP port " + std::to_string(port) + " is in use"));
  EXPECT_FALSE(fs::exists("/dev/shm/hq-" + channel + "-2")) << "unlinked on the error path";

  first.signal(SIGINT);
  EXPECT_EQ(first.wait_exit(10.0), 0);
  EXPECT_FALSE(fs::exists("/dev/shm/hq-" + channel));
}

}  // namespace
