// hq-bench-gcs-forwarding: what routing a GCS through the companion costs. A fake FC sends
// HIGHRES_IMU stamped with its send time at a fixed rate; a fake GCS receives them
//   floor       straight from the FC's socket (loopback UDP, one hop: the plain transport);
//   1 kHz loop  through MavlinkFlightController polled every millisecond, as hq-onboard's live
//               loop steps (FC -> companion -> GCS: two hops, a parse, a route, a send);
//   busy poll   the same, polled without sleeping: the router's own cost beside the transport's.
// For each rate: messages sent, received, lost, and the latency p50/p99/max in microseconds.
// The machine is shared, so compare the columns of one run, not runs.
//   hq-bench-gcs-forwarding [--seconds S] [--rates 300,1000,5000,20000]
#include "hq/base/monotonic_clock.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/mavlink/codec.hpp"
#include "hq/mavlink/transport.hpp"
#include "hq/vehicle/mavlink_flight_controller.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <fmt/format.h>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

namespace ml = hq::mavlink;

enum class Path { kFloor, kLoop1kHz, kBusyPoll };

const char* path_name(Path path) {
  switch (path) {
    case Path::kFloor:
      return "floor (UDP, one hop)";
    case Path::kLoop1kHz:
      return "companion, 1 kHz loop";
    case Path::kBusyPoll:
      return "companion, busy poll";
  }
  return "?";
}

struct Result {
  std::int64_t sent = 0;
  std::int64_t received = 0;
  double p50_us = 0, p99_us = 0, max_us = 0;
};

struct NullSink final : hq::vehicle::FcSink {
  void on_imu(const hq::vehicle::FcImuSample& /*sample*/) override {}
};

int next_port() {
  static int offset = 0;
  return 40000 + static_cast<int>(::getpid() % 10000) * 2 + (offset++ % 2000) * 20;
}

/// The GCS: each IMU frame's latency from its send stamp, until sending ended and nothing more
/// arrived for 200 ms.
void receive_latencies(ml::Transport& gcs, const std::atomic<bool>& sending_done,
                       const std::atomic<bool>& stop, std::vector<std::int64_t>& latency_ns) {
  ml::Parser parser;
  std::array<std::uint8_t, 2048> rx{};
  std::int64_t quiet_since_ns = -1;
  while (!stop.load()) {
    if (!gcs.wait_readable(2'000'000)) {
      const std::int64_t now = hq::monotonic_now_ns();
      if (sending_done.load()) {
        if (quiet_since_ns < 0) quiet_since_ns = now;
        if (now - quiet_since_ns > 200'000'000) return;
      }
      continue;
    }
    quiet_since_ns = -1;
    for (std::size_t n = gcs.receive(rx); n > 0; n = gcs.receive(rx)) {
      const std::int64_t now = hq::monotonic_now_ns();
      parser.feed(std::span<const std::uint8_t>(rx.data(), n),
                  [&](const ml::FrameHeader& header, const ml::Message& message) {
                    const auto* imu = std::get_if<ml::HighresImu>(&message);
                    if (imu == nullptr || header.component_id != 1) return;
                    latency_ns.push_back(now - static_cast<std::int64_t>(imu->time_usec));
                  });
      parser.end_of_datagram();
    }
  }
}

/// The companion's loop: every millisecond as hq-onboard's live loop, or without sleeping.
void poll_companion(hq::vehicle::MavlinkFlightController& companion, Path path,
                    const std::atomic<bool>& stop) {
  NullSink sink;
  std::int64_t next_ns = hq::monotonic_now_ns();
  while (!stop.load()) {
    companion.poll(hq::monotonic_now_ns(), sink);
    if (path == Path::kLoop1kHz) {
      next_ns += 1'000'000;
      const std::int64_t now = hq::monotonic_now_ns();
      if (next_ns < now) next_ns = now;
      hq::sleep_until_monotonic_ns(next_ns);
    }
  }
}

Result run(Path path, double rate_hz, double seconds) {
  const int fc_port = next_port();
  const int gcs_port = fc_port + 1;
  // The GCS listens as QGroundControl does; the FC listens as SITL does.
  const auto gcs = ml::open_transport("udp-listen:" + std::to_string(gcs_port));
  std::unique_ptr<ml::Transport> fc;
  std::unique_ptr<hq::vehicle::MavlinkFlightController> companion;
  if (path == Path::kFloor) {
    fc = ml::open_transport("udp:127.0.0.1:" + std::to_string(gcs_port));
  } else {
    fc = ml::open_transport("udp-listen:" + std::to_string(fc_port));
    hq::vehicle::MavlinkFcConfig config;
    config.transport = "udp:127.0.0.1:" + std::to_string(fc_port);
    config.gcs = "udp:127.0.0.1:" + std::to_string(gcs_port);
    companion = std::make_unique<hq::vehicle::MavlinkFlightController>(config);
    NullSink sink;
    // The companion's first heartbeat tells the listening FC where the companion is.
    std::array<std::uint8_t, 2048> rx{};
    for (int i = 0; i < 1000 && fc->receive(rx) == 0; ++i) {
      companion->poll(hq::monotonic_now_ns(), sink);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }

  const auto count = static_cast<std::int64_t>(rate_hz * seconds);
  std::vector<std::int64_t> latency_ns;
  latency_ns.reserve(static_cast<std::size_t>(count));
  std::atomic<bool> sending_done{false};
  std::atomic<bool> stop{false};

  std::thread receiver([&] { receive_latencies(*gcs, sending_done, stop, latency_ns); });

  std::thread router;
  if (companion) router = std::thread([&] { poll_companion(*companion, path, stop); });

  ml::Encoder encoder(1, ml::kMavCompIdAutopilot1);
  std::array<std::uint8_t, ml::kMaxFrameSize> frame{};
  ml::HighresImu imu;
  imu.fields_updated = 0x3F;
  imu.zacc_mps2 = -9.81f;
  const auto period_ns = static_cast<std::int64_t>(1e9 / rate_hz);
  const std::int64_t start_ns = hq::monotonic_now_ns() + 20'000'000;
  Result result;
  for (std::int64_t i = 0; i < count; ++i) {
    hq::sleep_until_monotonic_ns(start_ns + i * period_ns);
    imu.time_usec = static_cast<std::uint64_t>(hq::monotonic_now_ns());  // ns: a bench stamp
    const std::size_t n = encoder.encode(imu, frame);
    if (fc->send(std::span<const std::uint8_t>(frame.data(), n))) ++result.sent;
  }
  sending_done = true;
  receiver.join();
  stop = true;
  if (router.joinable()) router.join();

  result.received = static_cast<std::int64_t>(latency_ns.size());
  if (!latency_ns.empty()) {
    std::sort(latency_ns.begin(), latency_ns.end());
    auto at = [&](double q) {
      const auto k = static_cast<std::size_t>(q * static_cast<double>(latency_ns.size() - 1));
      return static_cast<double>(latency_ns[k]) * 1e-3;
    };
    result.p50_us = at(0.5);
    result.p99_us = at(0.99);
    result.max_us = static_cast<double>(latency_ns.back()) * 1e-3;
  }
  return result;
}

int run_bench(int argc, char** argv) {
  CLI::App app{"hq-bench-gcs-forwarding: FC -> GCS through the companion, beside plain UDP"};
  double seconds = 2.0;
  std::vector<double> rates{300, 1000, 5000, 20000};
  app.add_option("--seconds", seconds, "per rate and path")->check(CLI::Range(0.2, 60.0));
  app.add_option("--rates", rates, "messages per second")->delimiter(',');
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;

  fmt::print(
      "hq-bench-gcs-forwarding: HIGHRES_IMU (74-byte frames) FC -> GCS on loopback UDP, "
      "{:.1f} s per rate and path; latency in microseconds\n",
      seconds);
  fmt::print("{:>8}  {:<24} {:>8} {:>9} {:>6} {:>9} {:>9} {:>9}\n", "msg/s", "path", "sent",
             "received", "lost", "p50", "p99", "max");
  for (const double rate : rates) {
    for (const Path path : {Path::kFloor, Path::kLoop1kHz, Path::kBusyPoll}) {
      const Result r = run(path, rate, seconds);
      fmt::print("{:>8.0f}  {:<24} {:>8} {:>9} {:>6} {:>9.1f} {:>9.1f} {:>9.1f}\n", rate,
                 path_name(path), r.sent, r.received, r.sent - r.received, r.p50_us, r.p99_us,
                 r.max_us);
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return hq::run_tool("hq-bench-gcs-forwarding", argc, argv, run_bench);
}
