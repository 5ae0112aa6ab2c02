// hq-bench-flight-recorder: what the MCAP recorder costs hq-ground's command path. The command
// path's only recorder call is FlightRecorder::push() (one GroundSample into a lock-free queue);
// besides, Cyclone delivers a sample to readers in the same process on the writing thread, so
// the recorder's command reader adds to the command's DDS write. Timed at the 1 kHz tick rate:
// the write without a recorder, then the write and push() with one recording a link stream from
// a vehicle process (this program re-run with --vehicle: states at 100 Hz with 512 obstacle
// points, 20 KB camera frames at 33 Hz, and the reader of the commands). Each phase lasts
// --duration-s.
//   hq-bench-flight-recorder [--duration-s 5] [--out /tmp/bench_flight.mcap]
#include "hq/base/log.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/base/program.hpp"
#include "hq/base/quantile.hpp"
#include "hq/link/link.hpp"
#include "hq/mcap_recorder/flight_recorder.hpp"
#include "hq/testing/loopback_dds.hpp"
#include "hq/testing/process.hpp"

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fmt/format.h>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

std::int64_t now_ns() { return hq::monotonic_now_ns(); }

void print(const char* what, const std::vector<std::int64_t>& ns) {
  fmt::print("  {:<44} p50 {:6.0f} ns  p99 {:6.0f} ns  p99.9 {:7.0f} ns  max {:8.0f} ns  ({})\n",
             what, hq::quantile(ns, 0.5), hq::quantile(ns, 0.99), hq::quantile(ns, 0.999),
             hq::quantile(ns, 1.0), ns.size());
}

// The child: states at 100 Hz (512 obstacle points) and 20 KB camera frames at 33 Hz, and a
// reader taking the commands.
int run_vehicle(int domain_id, double duration_s) {
  hq::link::LinkConfig config;
  config.domain_id = domain_id;
  hq::link::Participant participant(domain_id);
  hq::link::Topics topics(participant);
  hq::link::Writer<hq::link::VehicleState> state_writer(participant, topics.vehicle_state,
                                                        hq::link::vehicle_state_qos());
  hq::link::Writer<hq::link::CameraFrame> camera_writer(participant, topics.camera,
                                                        hq::link::camera_qos());
  hq::link::Reader<hq::link::VelocityCommand> command_reader(
      participant, topics.command, hq::link::command_qos(config, hq::link::End::kReader));
  hq::link::Sample<hq::link::VehicleState> state;
  hq::link::reserve(state->obstacle_points_B_m, 512);
  state->obstacle_points_B_m._length = 512;
  hq::link::Sample<hq::link::CameraFrame> frame;
  hq::link::reserve(frame->rgb_jpeg, 20'000);
  frame->rgb_jpeg._length = 20'000;
  std::memset(frame->rgb_jpeg._buffer, 0x5A, 20'000);
  frame->rgb_jpeg._buffer[0] = 0xFF;
  frame->rgb_jpeg._buffer[1] = 0xD8;
  hq::link::VelocityCommand command{};
  dds_sample_info_t info{};
  const auto steps = static_cast<std::uint64_t>(duration_s * 100.0);
  for (std::uint64_t i = 0; i < steps; ++i) {
    state->sequence_number = i;
    state_writer.write(*state);
    if (i % 3 == 0) camera_writer.write(*frame);
    while (command_reader.take(command, info)) {
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  double duration_s = 5.0;
  std::string out = "/tmp/bench_flight.mcap";
  int vehicle_domain = -1;
  CLI::App app{
      "hq-bench-flight-recorder: the MCAP flight recorder's write rate and drops "
      "against a vehicle in another process"};
  app.add_option("--duration-s", duration_s, "recording length")->check(CLI::Range(0.1, 3600.0));
  app.add_option("--out", out, "the MCAP file written");
  app.add_option("--vehicle", vehicle_domain,
                 "internal: run as the vehicle process on this DDS domain")
      ->check(CLI::Range(0, 232));
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  hq::testing::use_loopback_dds(/*keep_existing=*/true);
  hq::mcap_recorder::FlightRecorderOptions options;
  options.path = out;
  options.link.domain_id =
      201 + static_cast<int>(std::chrono::steady_clock::now().time_since_epoch().count() % 20);
  options.link.security.enabled = false;  // plain DDS: the station's writers share the process

  if (vehicle_domain >= 0) return run_vehicle(vehicle_domain, duration_s);
  // The vehicle in a process of its own, as hq-onboard: it reads the commands (a remote
  // reader, as in flight) and publishes states and frames.
  const std::string domain_arg = std::to_string(options.link.domain_id);
  const std::string vehicle_duration = std::to_string(2 * duration_s + 3);
  // Its output beside the record, so the two programs' lines do not interleave.
  hq::testing::Process vehicle({argv[0], "--vehicle", domain_arg, "--duration-s", vehicle_duration},
                               out + ".vehicle.txt");
  if (!vehicle.started()) {
    hq::log::error("hq-bench-flight-recorder: cannot start the vehicle process\n");
    return 1;
  }
  hq::link::Participant participant(options.link.domain_id);
  hq::link::Topics topics(participant);
  hq::link::Writer<hq::link::VelocityCommand> command_writer(
      participant, topics.command, hq::link::command_qos(options.link, hq::link::End::kWriter));
  for (int i = 0; i < 500 && command_writer.matched_readers() == 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }

  const auto ticks = static_cast<std::size_t>(duration_s * 1000.0);
  hq::link::VelocityCommand command{};
  command.vehicle_id = 1;
  hq::mcap_recorder::GroundSample g;
  // One command tick per ms: the command's DDS write, then (with a recorder) the push.
  const auto fly = [&](hq::mcap_recorder::FlightRecorder* recorder,
                       std::vector<std::int64_t>& write_ns, std::vector<std::int64_t>& push_ns) {
    write_ns.reserve(ticks);
    push_ns.reserve(ticks);
    std::int64_t next = now_ns();
    for (std::size_t i = 0; i < ticks; ++i) {
      next += 1'000'000;
      std::this_thread::sleep_for(std::chrono::nanoseconds(next - now_ns()));
      command.sequence_number = i;
      const std::int64_t t0 = now_ns();
      command_writer.write(command);
      const std::int64_t t1 = now_ns();
      write_ns.push_back(t1 - t0);
      if (recorder != nullptr) {
        g.t_ns = dds_time();
        recorder->push(g);
        push_ns.push_back(now_ns() - t1);
      }
    }
  };
  std::vector<std::int64_t> write_alone_ns, unused, write_ns, push_ns;
  fly(nullptr, write_alone_ns, unused);
  // Cyclone delivers a sample to readers in the same process on the writing thread: the
  // recorder's command reader adds that delivery (a reference to the serialized sample) to the
  // command's write, measured here against the write without it.
  auto recorder = std::make_unique<hq::mcap_recorder::FlightRecorder>(options);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // discovery
  fly(recorder.get(), write_ns, push_ns);
  vehicle.signal(SIGTERM);
  vehicle.wait_exit(10.0);
  const hq::mcap_recorder::RecorderReport& r = recorder->close();
  fmt::print(
      "hq-bench-flight-recorder: {:.1f} s at 1 kHz, recorder wrote {} messages, {} bytes to {}, "
      "{} ground samples dropped{}{}\n",
      duration_s, r.messages, r.bytes, out, r.ground_samples_dropped,
      r.error.empty() ? "" : ", error: ", r.error);
  print("command's DDS write, no recorder", write_alone_ns);
  print("command's DDS write, recorder reading it", write_ns);
  print("FlightRecorder::push()", push_ns);
  return 0;
}
