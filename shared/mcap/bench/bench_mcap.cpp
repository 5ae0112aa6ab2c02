// hq-bench-mcap: the MCAP writer's throughput for 1 kB messages, zstd and uncompressed, beside a
// plain fwrite of the same bytes in the same run (this machine's timing is noisy: compare within
// a run), and the file size per minute of a typical flight (200 Hz state of ~300 B, 10 Hz
// 20 kB JPEG).
//   hq-bench-mcap [--messages N] [--passes P] [--dir DIR]

#include "hq/base/error.hpp"
#include "hq/base/log.hpp"
#include "hq/base/program.hpp"
#include "hq/mcap/mcap.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;
using hq::mcap::Compression;

// 1 kB like a telemetry sample: slowly varying doubles with noise in the low bytes, so zstd
// sees what it would in flight (neither all zeros nor white noise).
std::vector<std::uint8_t> telemetry(std::size_t size, int i, std::mt19937& rng) {
  std::vector<std::uint8_t> out(size);
  std::normal_distribution<double> noise(0.0, 1e-3);
  for (std::size_t k = 0; k + 8 <= size; k += 8) {
    const double v = std::sin(0.01 * i + 0.1 * static_cast<double>(k)) + noise(rng);
    std::memcpy(out.data() + k, &v, 8);
  }
  return out;
}

struct Result {
  double seconds = 0;
  std::uint64_t file_bytes = 0;
};

Result run_mcap(const std::string& path, Compression compression,
                const std::vector<std::vector<std::uint8_t>>& messages) {
  const auto start = Clock::now();
  hq::mcap::McapWriter writer;
  hq::mcap::WriterOptions options;
  options.compression = compression;
  writer.open(path, options);
  const std::uint16_t channel = writer.add_channel(0, "/bench", "raw");
  std::int64_t t_ns = 0;
  std::uint32_t sequence = 0;
  for (const auto& m : messages) {
    writer.write(channel, sequence++, t_ns, t_ns, m);
    t_ns += 1'000'000;
  }
  writer.close();
  return {std::chrono::duration<double>(Clock::now() - start).count(),
          static_cast<std::uint64_t>(std::filesystem::file_size(path))};
}

Result run_fwrite(const std::string& path, const std::vector<std::vector<std::uint8_t>>& messages) {
  const auto start = Clock::now();
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) throw hq::InputError(path + ": cannot open for writing");
  for (const auto& m : messages) {
    if (std::fwrite(m.data(), 1, m.size(), f) != m.size())
      throw hq::InputError(path + ": fwrite failed");
  }
  if (std::fclose(f) != 0) throw hq::InputError(path + ": fclose failed");
  return {std::chrono::duration<double>(Clock::now() - start).count(),
          static_cast<std::uint64_t>(std::filesystem::file_size(path))};
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

// One simulated minute of a typical flight; returns the file size.
std::uint64_t flight_minute(const std::string& path, Compression compression) {
  std::mt19937 rng(7);
  hq::mcap::McapWriter writer;
  hq::mcap::WriterOptions options;
  options.compression = compression;
  writer.open(path, options);
  const std::uint16_t state = writer.add_channel(0, "/state", "cdr");
  const std::uint16_t image = writer.add_channel(0, "/camera/jpeg", "cdr");
  std::vector<std::uint8_t> jpeg(20'000);
  std::uniform_int_distribution<int> byte(0, 255);  // JPEG is entropy-coded: incompressible
  std::uint32_t state_seq = 0;
  std::uint32_t image_seq = 0;
  for (int i = 0; i < 60 * 200; ++i) {
    const std::int64_t t_ns = static_cast<std::int64_t>(i) * 5'000'000;
    const auto sample = telemetry(296, i, rng);
    writer.write(state, state_seq++, t_ns, t_ns, sample);
    if (i % 20 == 0) {
      for (auto& b : jpeg) b = static_cast<std::uint8_t>(byte(rng));
      writer.write(image, image_seq++, t_ns, t_ns, jpeg);
    }
  }
  writer.close();
  return std::filesystem::file_size(path);
}

}  // namespace

int main(int argc, char** argv) {
  int count = 100'000;
  int passes = 5;
  std::string dir = std::filesystem::temp_directory_path().string();
  CLI::App app{"hq-bench-mcap: MCAP write and read throughput"};
  app.add_option("--messages", count, "messages per pass")->check(CLI::PositiveNumber);
  app.add_option("--passes", passes, "passes (the median is reported)")->check(CLI::PositiveNumber);
  app.add_option("--dir", dir, "folder of the scratch files");
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  if (count <= 0 || passes <= 0) {
    hq::log::error("hq-bench-mcap: --messages and --passes must be > 0\n");
    return 2;
  }
  try {
    std::mt19937 rng(1);
    std::vector<std::vector<std::uint8_t>> messages;
    messages.reserve(static_cast<std::size_t>(count));
    for (int i = 0; i < count; ++i) messages.push_back(telemetry(1000, i, rng));
    const double payload_mb = count * 1000.0 / 1e6;
    const std::string path = dir + "/hq-bench-mcap.bin";

    fmt::print("{} messages of 1000 B ({:.0f} MB) to {}, median of {} passes, 1 MiB chunks\n",
               count, payload_mb, dir, passes);
    fmt::print("{:<22} {:>10} {:>10} {:>12} {:>14}\n", "writer", "MB/s", "ns/msg", "file MB",
               "ratio");
    struct Case {
      const char* name;
      int kind;  // 0 fwrite, 1 mcap none, 2 mcap zstd
    };
    const std::array<Case, 3> cases = {
        {{"fwrite (peer)", 0}, {"mcap, no compression", 1}, {"mcap, zstd level 1", 2}}};
    for (const Case& c : cases) {
      std::vector<double> seconds;
      std::uint64_t bytes = 0;
      for (int p = 0; p < passes; ++p) {
        const Result r =
            c.kind == 0
                ? run_fwrite(path, messages)
                : run_mcap(path, c.kind == 1 ? Compression::kNone : Compression::kZstd, messages);
        seconds.push_back(r.seconds);
        bytes = r.file_bytes;
      }
      const double s = median(seconds);
      fmt::print("{:<22} {:10.0f} {:10.0f} {:12.1f} {:14.3f}\n", c.name, payload_mb / s,
                 s * 1e9 / count, static_cast<double>(bytes) / 1e6,
                 static_cast<double>(bytes) / (payload_mb * 1e6));
    }
    std::filesystem::remove(path);

    const std::string flight = dir + "/hq-bench-mcap-flight.mcap";
    const double zstd_mb = static_cast<double>(flight_minute(flight, Compression::kZstd)) / 1e6;
    const double none_mb = static_cast<double>(flight_minute(flight, Compression::kNone)) / 1e6;
    std::filesystem::remove(flight);
    fmt::print(
        "typical flight (200 Hz state 296 B + 10 Hz JPEG 20 kB): {:.1f} MB/min with zstd, {:.1f} "
        "MB/min uncompressed ({:.2f} GB/h with zstd)\n",
        zstd_mb, none_mb, zstd_mb * 60 / 1e3);
  } catch (const hq::InputError& e) {
    hq::log::error("hq-bench-mcap: {}\n", e.what());
    return 2;
  }
  return 0;
}
