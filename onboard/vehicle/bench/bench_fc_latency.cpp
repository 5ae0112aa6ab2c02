// hq-bench-fc-latency: how long a frame takes to become a setpoint on the flight controller's
// wire. The same VehicleRuntime and chain run the same rendered frames twice in one run:
//   in-process   the setpoint handed to an in-process flight controller (a function call);
//   mavlink/udp  the SET_ATTITUDE_TARGET received by a flight controller on a loopback UDP socket
//                (MavlinkFlightController -> encode -> sendto -> recvfrom -> parse);
// beside the floor of the wire alone: one SET_ATTITUDE_TARGET encoded, sent and received on the
// same sockets. Medians and tails in microseconds; the machine is shared, so compare columns of
// one run, not runs.
//   hq-bench-fc-latency [--frames N]
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/mavlink/codec.hpp"
#include "hq/mavlink/transport.hpp"
#include "hq/odometry/rendered_plane.hpp"
#include "hq/vehicle/mavlink_flight_controller.hpp"
#include "hq/vehicle/vehicle_runtime.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fmt/format.h>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <time.h>
#include <unistd.h>
#include <vector>

namespace {

namespace ml = hq::mavlink;

std::int64_t now_ns() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec * 1'000'000'000LL + t.tv_nsec;
}

const hq::geometry::PinholeCamera kCamera{260.0, 260.0, 159.5, 119.5, 320, 240};
constexpr std::int64_t kFramePeriodNs = 33'333'333;

/// Pre-rendered frames handed out one per call, stamped as they are taken.
class RenderedFrames final : public hq::sources::FrameSource {
 public:
  explicit RenderedFrames(int count) {
    frames_.resize(static_cast<std::size_t>(count));
    for (int k = 0; k < count; ++k) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation().x() = 0.3 * k / 30.0;
      T.translation().y() = 0.05 * std::sin(0.2 * k);
      hq::sources::RgbdFrame& frame = frames_[static_cast<std::size_t>(k)];
      hq::odometry::test::render_textured_plane(kCamera, T, 2.0, frame.gray, frame.depth_m);
    }
  }
  hq::sources::FrameStatus next(hq::sources::RgbdFrame& frame) override {
    if (!due_) return hq::sources::FrameStatus::kNoFrame;
    due_ = false;
    const hq::sources::RgbdFrame& f = frames_[index_++ % frames_.size()];
    frame.gray = f.gray;
    frame.depth_m = f.depth_m;
    frame.t_ns = stamp_ns_;
    return hq::sources::FrameStatus::kFrame;
  }
  [[nodiscard]] hq::geometry::PinholeCamera camera() const override { return kCamera; }
  [[nodiscard]] std::string describe() const override { return "rendered plane"; }
  void arm(std::int64_t stamp_ns) {
    due_ = true;
    stamp_ns_ = stamp_ns;
  }

 private:
  std::vector<hq::sources::RgbdFrame> frames_;
  std::size_t index_ = 0;
  bool due_ = false;
  std::int64_t stamp_ns_ = 0;
};

/// The in-process flight controller: the setpoint's arrival is the call.
class CallFc final : public hq::vehicle::FlightController {
 public:
  void poll(std::int64_t t_ns, hq::vehicle::FcSink& sink) override {
    for (; next_imu_ns_ <= t_ns; next_imu_ns_ += 5'000'000) {
      if (next_imu_ns_ > 0) {
        sink.on_imu({next_imu_ns_, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, -9.80665)});
      }
    }
  }
  void send_setpoint(std::int64_t, const hq::control::AttitudeSetpoint&) override {
    last_call_ns = now_ns();
  }
  [[nodiscard]] hq::vehicle::FcStatus status(std::int64_t) const override { return {}; }
  [[nodiscard]] std::string describe() const override { return "in-process call"; }
  std::int64_t last_call_ns = 0;

 private:
  std::int64_t next_imu_ns_ = -1;
};

/// A flight controller on a loopback UDP socket, on a thread of its own: heartbeats and IMU out,
/// the receipt time of every SET_ATTITUDE_TARGET in.
class WireFc {
 public:
  explicit WireFc(int port) : transport_(ml::open_transport("udp-listen:" + std::to_string(port))) {
    receipts_.reserve(100'000);
    thread_ = std::thread([this] { loop(); });
  }
  ~WireFc() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  std::vector<std::int64_t> receipts() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    return receipts_;
  }

 private:
  void loop() {
    std::array<std::uint8_t, 2048> buffer{};
    std::int64_t next_beat_ns = 0;
    const std::int64_t boot_ns = now_ns();
    std::int64_t next_imu_ns = boot_ns;
    while (!stop_) {
      // A level vehicle at rest, as an FC streams it: the chain needs an attitude to estimate.
      for (; now_ns() >= next_imu_ns; next_imu_ns += 5'000'000) {
        ml::HighresImu imu;
        imu.time_usec = static_cast<std::uint64_t>((next_imu_ns - boot_ns) / 1000);
        imu.zacc_mps2 = -9.80665f;
        std::array<std::uint8_t, ml::kMaxFrameSize> frame{};
        const std::size_t n = encoder_.encode(imu, frame);
        transport_->send(std::span<const std::uint8_t>(frame.data(), n));
      }
      if (now_ns() >= next_beat_ns) {
        ml::Heartbeat hb;
        hb.type = ml::kMavTypeQuadrotor;
        hb.autopilot = ml::kMavAutopilotPx4;
        std::array<std::uint8_t, ml::kMaxFrameSize> frame{};
        const std::size_t n = encoder_.encode(hb, frame);
        transport_->send(std::span<const std::uint8_t>(frame.data(), n));
        next_beat_ns = now_ns() + 200'000'000;
      }
      if (!transport_->wait_readable(1'000'000)) continue;
      std::size_t n = 0;
      while ((n = transport_->receive(buffer)) > 0) {
        const std::int64_t t = now_ns();
        parser_.feed(std::span<const std::uint8_t>(buffer.data(), n),
                     [&](const ml::FrameHeader&, const ml::Message& m) {
                       if (std::holds_alternative<ml::SetAttitudeTarget>(m)) receipts_.push_back(t);
                     });
        parser_.end_of_datagram();
      }
    }
  }

  std::unique_ptr<ml::Transport> transport_;
  ml::Encoder encoder_{1, 1};
  ml::Parser parser_;
  std::vector<std::int64_t> receipts_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

struct Figures {
  double p50_us = 0, p90_us = 0, p99_us = 0;
  std::size_t n = 0;
};

Figures figures(std::vector<double> us) {
  Figures f;
  f.n = us.size();
  if (us.empty()) return f;
  std::sort(us.begin(), us.end());
  const auto at = [&](double q) {
    return us[static_cast<std::size_t>(q * static_cast<double>(us.size() - 1))];
  };
  f.p50_us = at(0.5);
  f.p90_us = at(0.9);
  f.p99_us = at(0.99);
  return f;
}

hq::pipeline::OnboardConfig airborne() {
  hq::pipeline::OnboardConfig c;
  c.modes.start_landed = false;
  return c;
}

/// Steps the runtime once per frame at the camera's pace; returns per-frame arrival times of the
/// frames whose step sent a setpoint.
std::vector<std::int64_t> fly(hq::vehicle::VehicleRuntime& runtime, RenderedFrames& source,
                              int frames, const std::function<void(std::int64_t)>& after_step) {
  std::vector<std::int64_t> arrivals;
  arrivals.reserve(static_cast<std::size_t>(frames));
  std::int64_t next_ns = now_ns();
  for (int k = 0; k < frames; ++k) {
    next_ns += kFramePeriodNs / 4;  // 4x the camera rate: the bench, not the camera, is timed
    while (now_ns() < next_ns) std::this_thread::sleep_for(std::chrono::microseconds(200));
    const std::uint64_t before = runtime.counters().setpoints;
    const std::int64_t arrival_ns = now_ns();
    source.arm(arrival_ns);
    runtime.step(arrival_ns);
    if (runtime.counters().setpoints > before) {
      arrivals.push_back(arrival_ns);
      after_step(arrival_ns);
    }
  }
  return arrivals;
}

int run(int argc, char** argv) {
  CLI::App app{"hq-bench-fc-latency: frame to setpoint on the flight controller's wire"};
  int frames = 600;
  app.add_option("--frames", frames, "frames per path")->check(CLI::Range(50, 100000));
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  const int port = 30000 + getpid() % 20000;

  // In process.
  std::vector<double> in_process_us;
  {
    hq::pipeline::OnboardChain chain(airborne(), hq::VehicleConfig{}, kCamera);
    RenderedFrames source(60);
    CallFc fc;
    hq::vehicle::VehicleRuntime runtime(chain, source, fc, nullptr);
    fly(runtime, source, frames, [&](std::int64_t arrival_ns) {
      in_process_us.push_back(1e-3 * static_cast<double>(fc.last_call_ns - arrival_ns));
    });
  }

  // Over MAVLink on loopback UDP.
  std::vector<double> wire_us;
  std::vector<double> floor_us;
  {
    WireFc wire(port);
    hq::vehicle::MavlinkFcConfig config;
    config.transport = "udp:127.0.0.1:" + std::to_string(port);
    hq::vehicle::MavlinkFlightController fc(config);
    hq::pipeline::OnboardChain chain(airborne(), hq::VehicleConfig{}, kCamera);
    RenderedFrames source(60);
    hq::vehicle::VehicleRuntime runtime(chain, source, fc, nullptr);
    // Until the FC is heard, setpoints are not sent: warm up first.
    for (int i = 0; i < 200 && !fc.status(now_ns()).connected; ++i) {
      runtime.step(now_ns());
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    const std::uint64_t sent_before = fc.counters().setpoints_sent;
    std::vector<std::int64_t> arrivals = fly(runtime, source, frames, [](std::int64_t) {});
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    std::vector<std::int64_t> receipts = wire.receipts();
    // Setpoints sent during warm-up came first on the wire.
    const std::size_t skip = static_cast<std::size_t>(sent_before);
    if (receipts.size() < skip + arrivals.size()) {
      fmt::print(
          stderr, "hq-bench-fc-latency: {} setpoints sent, {} received (FC {}, {} send failures)\n",
          skip + arrivals.size(), receipts.size(),
          fc.status(now_ns()).connected ? "connected" : "not heard", fc.counters().send_failures);
    }
    for (std::size_t k = 0; k < arrivals.size() && skip + k < receipts.size(); ++k) {
      wire_us.push_back(1e-3 * static_cast<double>(receipts[skip + k] - arrivals[k]));
    }
  }
  {
    // The floor: one SET_ATTITUDE_TARGET encoded, sent and received, nothing else.
    auto rx = ml::open_transport("udp-listen:" + std::to_string(port + 1));
    auto tx = ml::open_transport("udp:127.0.0.1:" + std::to_string(port + 1));
    ml::Encoder encoder(1, 191);
    ml::Parser parser;
    std::array<std::uint8_t, ml::kMaxFrameSize> frame{};
    std::array<std::uint8_t, 2048> buffer{};
    for (int k = 0; k < frames; ++k) {
      const std::int64_t t0 = now_ns();
      const std::size_t n = encoder.encode(ml::SetAttitudeTarget{}, frame);
      tx->send(std::span<const std::uint8_t>(frame.data(), n));
      rx->wait_readable(100'000'000);
      const std::size_t got = rx->receive(buffer);
      bool seen = false;
      parser.feed(std::span<const std::uint8_t>(buffer.data(), got),
                  [&](const ml::FrameHeader&, const ml::Message&) { seen = true; });
      parser.end_of_datagram();
      if (seen) floor_us.push_back(1e-3 * static_cast<double>(now_ns() - t0));
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }

  fmt::print("hq-bench-fc-latency: {} frames of 320x240 per path, frame arrival to setpoint\n",
             frames);
  fmt::print("{:<34} {:>8} {:>8} {:>8} {:>6}\n", "path", "p50_us", "p90_us", "p99_us", "n");
  const auto row = [](const char* name, const Figures& f) {
    fmt::print("{:<34} {:8.1f} {:8.1f} {:8.1f} {:6}\n", name, f.p50_us, f.p90_us, f.p99_us, f.n);
  };
  row("in-process (function call)", figures(in_process_us));
  row("mavlink:udp (received by the FC)", figures(wire_us));
  row("floor: encode+send+receive only", figures(floor_us));
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-bench-fc-latency", argc, argv, run); }
