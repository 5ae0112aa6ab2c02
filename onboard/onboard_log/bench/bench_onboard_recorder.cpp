// hq-bench-onboard-recorder: what hq-onboard --record costs the frame path, with and without
// in the same run. The frame path's recorder calls are RecordingPort::on_output (one
// push_step: a ChainOutput copied into a queue slot) and push_imu per IMU sample; besides,
// Cyclone delivers the vehicle's own samples to the recorder's readers in the same process on
// the writing thread, so each state write costs more. Timed per step, IMU at 5 samples a step:
//   1. the step's port call and IMU hand-over without a recorder, then with one;
//   2. a VehicleState write (512 obstacle points) without a recorder, then with one;
// and the MCAP size of the vehicle's own channels per minute (every step a frame, 1 kHz IMU:
// an upper bound; a real flight adds the link samples, mostly camera JPEGs).
//   hq-bench-onboard-recorder [--steps 20000] [--out DIR]
#include "hq/base/program.hpp"
#include "hq/link/link.hpp"
#include "hq/onboard_log/onboard_recorder.hpp"
#include "hq/testing/loopback_dds.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <optional>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

void print(const char* what, std::vector<std::int64_t>& ns) {
  std::sort(ns.begin(), ns.end());
  const auto at = [&](double q) {
    return ns[static_cast<std::size_t>(q * static_cast<double>(ns.size() - 1))];
  };
  fmt::print("  {:<52} p50 {:6} ns  p90 {:6} ns  p99 {:7} ns  max {:8} ns  ({})\n", what, at(0.5),
             at(0.9), at(0.99), ns.back(), ns.size());
}

// The runtime's port without a link: what on_output costs without the recorder.
class NullPort final : public hq::vehicle::OperatorPort {
 public:
  hq::modes::OperatorCommand poll(std::int64_t, std::vector<hq::pipeline::ModeRequest>&) override {
    return {};
  }
  void on_output(const hq::pipeline::ChainOutput& out, const hq::vehicle::VehicleStatus&) override {
    sink += out.t_ns;
  }
  std::int64_t sink = 0;
};

// Step and IMU hand-over as the runtime's loop makes them (200 Hz steps, 5 IMU samples each).
std::vector<std::int64_t> time_steps(hq::vehicle::OperatorPort& port,
                                     hq::onboard_log::OnboardRecorder* recorder, int steps) {
  std::vector<std::int64_t> ns;
  ns.reserve(static_cast<std::size_t>(steps));
  hq::pipeline::ChainOutput out;
  out.frame = true;
  hq::vehicle::VehicleStatus status;
  hq::vehicle::FcImuSample imu;
  for (int i = 0; i < steps; ++i) {
    out.t_ns = 1'000'000'000LL + i * 5'000'000LL;
    const std::int64_t t0 = now_ns();
    if (recorder != nullptr) {
      for (int k = 0; k < 5; ++k) {
        imu.t_ns = out.t_ns + k * 1'000'000;
        recorder->push_imu(imu);
      }
    }
    port.on_output(out, status);
    ns.push_back(now_ns() - t0);
    // 1 ms every 5 steps: 20x the real rate, and still within what the queues hold between
    // two drains of the log's thread (so nothing is dropped and the size per step is whole).
    if (i % 5 == 4) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return ns;
}

std::vector<std::int64_t> time_state_writes(hq::link::Participant& participant, int writes) {
  hq::link::Topics topics(participant);
  hq::link::Writer<hq::link::VehicleState> writer(participant, topics.vehicle_state,
                                                  hq::link::vehicle_state_qos());
  hq::link::Sample<hq::link::VehicleState> state;
  hq::link::reserve(state->obstacle_points_B_m, 512);
  state->obstacle_points_B_m._length = 512;
  std::vector<std::int64_t> ns;
  ns.reserve(static_cast<std::size_t>(writes));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // discovery
  for (int i = 0; i < writes; ++i) {
    state->sequence_number = static_cast<std::uint32_t>(i);
    const std::int64_t t0 = now_ns();
    static_cast<void>(writer.write(*state));
    ns.push_back(now_ns() - t0);
    std::this_thread::sleep_for(std::chrono::microseconds(2000));
  }
  return ns;
}

}  // namespace

int main(int argc, char** argv) {
  int steps = 20'000;
  std::string out_dir = (std::filesystem::temp_directory_path() /
                         ("hq_bench_onboard_recorder_" + std::to_string(getpid())))
                            .string();
  CLI::App app{"hq-bench-onboard-recorder: the on-board MCAP recorder's cost per 200 Hz step"};
  app.add_option("--steps", steps, "steps recorded")->check(CLI::Range(100, 100'000'000));
  app.add_option("--out", out_dir, "folder of the record (emptied first)");
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  hq::testing::use_loopback_dds(/*keep_existing=*/true);
  const int domain_id = hq::testing::private_domain_id(0);
  std::filesystem::remove_all(out_dir);
  fmt::print("hq-bench-onboard-recorder: {} steps (200 Hz, 5 IMU samples each), domain {}\n", steps,
             domain_id);

  NullPort null_port;
  auto without = time_steps(null_port, nullptr, steps);
  hq::link::Participant vehicle(domain_id);
  auto state_without = time_state_writes(vehicle, 2000);

  hq::onboard_log::OnboardRecorderOptions options;
  options.dir = out_dir;
  options.link.domain_id = domain_id;
  options.link.security.enabled = false;
  std::int64_t size_bytes = 0;
  double per_minute_steps = 0;
  {
    hq::onboard_log::OnboardRecorder recorder(options);
    hq::onboard_log::RecordingPort port(&null_port, recorder);
    auto with = time_steps(port, &recorder, steps);
    auto state_with = time_state_writes(vehicle, 2000);
    fmt::print("frame path per step:\n");
    print("port.on_output, no recorder", without);
    print("port.on_output + push_step + 5 push_imu, recorder", with);
    fmt::print("VehicleState write (512 points), the vehicle's own writer:\n");
    print("no recorder in the process", state_without);
    print("recorder's reader in the process", state_with);
    const hq::flight_log::RecorderReport& report = recorder.close();
    size_bytes = static_cast<std::int64_t>(report.bytes);
    per_minute_steps = 60.0 * 200.0 / steps;
    fmt::print("recorded {} messages, {} dropped, {}\n", report.messages,
               report.local_samples_dropped, report.error.empty() ? "no error" : report.error);
  }
  fmt::print(
      "vehicle's own channels (every step a frame, 1 kHz IMU): {:.1f} MB per minute of flight "
      "({:.1f} MB for {} steps; + link samples, mostly camera JPEGs)\n",
      1e-6 * static_cast<double>(size_bytes) * per_minute_steps,
      1e-6 * static_cast<double>(size_bytes), steps);
  std::filesystem::remove_all(out_dir);
  return 0;
}
