// hq-bench-mavlink: encode and decode cost per message, beside the floor of the same run (copying
// the frame bytes and computing its CRC alone), so the figures say what the codec adds.

#include "hq/mavlink/codec.hpp"

#include <benchmark/benchmark.h>

#include <array>
#include <cstring>

namespace {

using hq::mavlink::Encoder;
using hq::mavlink::FrameHeader;
using hq::mavlink::kMaxFrameSize;
using hq::mavlink::Message;
using hq::mavlink::Parser;

Message highres_imu() {
  hq::mavlink::HighresImu m{123456789, 0.1f, -0.2f,    -9.81f, 0.01f, 0.02f, -0.03f, 0.2f,
                            0.1f,      0.4f, 1013.25f, 0.5f,   120.f, 25.5f, 0x1FFF, 0};
  return m;
}

Message set_attitude_target() {
  hq::mavlink::SetAttitudeTarget m;
  m.time_boot_ms = 987654;
  m.q = {0.99f, 0.05f, -0.07f, 0.1f};
  m.body_yaw_rate_radps = 0.3f;
  m.thrust = 0.55f;
  m.target_system = 1;
  m.target_component = 1;
  m.type_mask = 3;
  return m;
}

void encode(benchmark::State& state, const Message& message) {
  Encoder encoder(1, 191);
  std::array<std::uint8_t, kMaxFrameSize> frame{};
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores): the benchmark loop
    benchmark::DoNotOptimize(encoder.encode(message, frame));
    benchmark::ClobberMemory();
  }
}

void decode(benchmark::State& state, const Message& message) {
  Encoder encoder(1, 1);
  std::array<std::uint8_t, kMaxFrameSize> frame{};
  const std::size_t n = encoder.encode(message, frame);
  Parser parser;
  std::size_t frames = 0;
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores): the benchmark loop
    parser.feed(std::span<const std::uint8_t>(frame.data(), n),
                [&](const FrameHeader&, const Message& m) {
                  benchmark::DoNotOptimize(&m);
                  ++frames;
                });
  }
  if (frames != static_cast<std::size_t>(state.iterations())) state.SkipWithError("frames lost");
}

// The floor: what any codec must do with the same bytes (copy them, checksum them).
void floor(benchmark::State& state, const Message& message) {
  Encoder encoder(1, 1);
  std::array<std::uint8_t, kMaxFrameSize> frame{};
  std::array<std::uint8_t, kMaxFrameSize> copy{};
  const std::size_t n = encoder.encode(message, frame);
  for (auto _ : state) {  // NOLINT(clang-analyzer-deadcode.DeadStores): the benchmark loop
    benchmark::DoNotOptimize(frame.data());
    std::memcpy(copy.data(), frame.data(), n);
    benchmark::DoNotOptimize(
        hq::mavlink::crc16_mcrf4xx(std::span<const std::uint8_t>(copy.data() + 1, n - 3)));
    benchmark::ClobberMemory();
  }
}

BENCHMARK_CAPTURE(encode, highres_imu, highres_imu());
BENCHMARK_CAPTURE(decode, highres_imu, highres_imu());
BENCHMARK_CAPTURE(floor, highres_imu, highres_imu());
BENCHMARK_CAPTURE(encode, set_attitude_target, set_attitude_target());
BENCHMARK_CAPTURE(decode, set_attitude_target, set_attitude_target());
BENCHMARK_CAPTURE(floor, set_attitude_target, set_attitude_target());

}  // namespace

BENCHMARK_MAIN();
