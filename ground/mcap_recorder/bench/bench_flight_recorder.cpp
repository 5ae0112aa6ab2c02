// hq-bench-flight-recorder: what the MCAP recorder costs hq-ground's command path. The command
// path's only recorder call is FlightRecorder::push() (one GroundSample into a lock-free queue);
// this times it at the 1 kHz tick rate while the recorder thread records a link stream
// (states at 100 Hz with 512 obstacle points, 20 KB camera frames at 30 Hz) from a publisher on
// the same host, beside the DDS write of the velocity command the tick sends anyway.
//   hq-bench-flight-recorder [--duration-s 5] [--out /tmp/bench_flight.mcap]
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "hq/link/link.hpp"
#include "hq/mcap_recorder/flight_recorder.hpp"

namespace {

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

void print(const char* what, std::vector<std::int64_t>& ns) {
  std::sort(ns.begin(), ns.end());
  const auto at = [&](double q) { return ns[static_cast<std::size_t>(q * (ns.size() - 1))]; };
  std::printf("  %-44s p50 %6lld ns  p99 %6lld ns  p99.9 %7lld ns  max %8lld ns  (%zu)\n", what,
              static_cast<long long>(at(0.5)), static_cast<long long>(at(0.99)),
              static_cast<long long>(at(0.999)), static_cast<long long>(ns.back()), ns.size());
}

}  // namespace

int main(int argc, char** argv) {
  double duration_s = 5.0;
  std::string out = "/tmp/bench_flight.mcap";
  for (int i = 1; i + 1 < argc; i += 2) {
    if (std::strcmp(argv[i], "--duration-s") == 0) duration_s = std::atof(argv[i + 1]);
    if (std::strcmp(argv[i], "--out") == 0) out = argv[i + 1];
  }
  setenv("CYCLONEDDS_URI",
         "<CycloneDDS><Domain><General><Interfaces><NetworkInterface name=\"lo\"/>"
         "</Interfaces></General></Domain></CycloneDDS>",
         0);
  hq::mcap_recorder::FlightRecorderOptions options;
  options.path = out;
  options.link.domain_id = 201 + static_cast<int>(std::chrono::steady_clock::now()
                                                      .time_since_epoch().count() % 20);
  hq::mcap_recorder::FlightRecorder recorder(options);

  hq::link::Participant participant(options.link.domain_id);
  hq::link::Topics topics(participant);
  hq::link::Writer<hq::link::VehicleState> state_writer(participant, topics.vehicle_state,
                                                        hq::link::vehicle_state_qos());
  hq::link::Writer<hq::link::CameraFrame> camera_writer(participant, topics.camera,
                                                        hq::link::camera_qos());
  hq::link::Writer<hq::link::VelocityCommand> command_writer(
      participant, topics.command,
      hq::link::command_qos(options.link, hq::link::End::kWriter));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // discovery

  std::atomic<bool> done{false};
  std::thread vehicle([&] {
    hq::link::Sample<hq::link::VehicleState> state;
    hq::link::reserve(state->obstacle_points_body_m, 512);
    state->obstacle_points_body_m._length = 512;
    hq::link::Sample<hq::link::CameraFrame> frame;
    hq::link::reserve(frame->rgb_jpeg, 20'000);
    frame->rgb_jpeg._length = 20'000;
    std::memset(frame->rgb_jpeg._buffer, 0x5A, 20'000);
    frame->rgb_jpeg._buffer[0] = 0xFF;
    frame->rgb_jpeg._buffer[1] = 0xD8;
    for (std::uint64_t i = 0; !done; ++i) {
      state->sequence_number = i;
      state_writer.write(*state);
      if (i % 3 == 0) camera_writer.write(*frame);
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  });

  const auto ticks = static_cast<std::size_t>(duration_s * 1000.0);
  std::vector<std::int64_t> push_ns;
  std::vector<std::int64_t> write_ns;
  push_ns.reserve(ticks);
  write_ns.reserve(ticks);
  hq::link::VelocityCommand command{};
  command.vehicle_id = 1;
  hq::mcap_recorder::GroundSample g;
  std::int64_t next = now_ns();
  for (std::size_t i = 0; i < ticks; ++i) {
    next += 1'000'000;
    std::this_thread::sleep_for(std::chrono::nanoseconds(next - now_ns()));
    command.sequence_number = i;
    const std::int64_t t0 = now_ns();
    command_writer.write(command);
    const std::int64_t t1 = now_ns();
    g.t_ns = dds_time();
    recorder.push(g);
    const std::int64_t t2 = now_ns();
    write_ns.push_back(t1 - t0);
    push_ns.push_back(t2 - t1);
  }
  done = true;
  vehicle.join();
  const hq::mcap_recorder::RecorderReport& r = recorder.close();
  std::printf("hq-bench-flight-recorder: %.1f s at 1 kHz, recorder wrote %llu messages, %llu "
              "bytes to %s, %llu ground samples dropped%s%s\n",
              duration_s, static_cast<unsigned long long>(r.messages),
              static_cast<unsigned long long>(r.bytes), out.c_str(),
              static_cast<unsigned long long>(r.ground_samples_dropped),
              r.error.empty() ? "" : ", error: ", r.error.c_str());
  print("command path: FlightRecorder::push()", push_ns);
  print("for scale: the command's DDS write", write_ns);
  return 0;
}
