// hq-bench-link: command latency ground -> onboard over loopback between two processes, beside
// Cyclone's own ddsperf ping/pong floor measured in the same run, and camera stream throughput
// and drop rate at 30 Hz, and the cost of DDS Security on the command path (plain beside
// secured in the same run). Prints figures; asserts nothing.

#include "hq/base/log.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/base/program.hpp"
#include "hq/base/quantile.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/link/link.hpp"
#include "hq/testing/loopback_dds.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fmt/format.h>
#include <optional>
#include <string>
#include <sys/mman.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <vector>

namespace hq::link {
namespace {

constexpr std::uint64_t kDone = ~std::uint64_t{0};
constexpr int kWarmup = 200;

std::int64_t now_ns() { return hq::monotonic_now_ns(); }

// The command-path QoS variants measured, to show what each choice costs.
enum class Variant { kCommand, kPlainBestEffort, kReliable };
constexpr std::array<Variant, 3> kVariants = {Variant::kCommand, Variant::kPlainBestEffort,
                                              Variant::kReliable};

const char* describe(Variant variant) {
  switch (variant) {
    case Variant::kCommand:
      return "command QoS (best-effort, deadline, EXCLUSIVE, manual liveliness)";
    case Variant::kPlainBestEffort:
      return "plain best-effort keep-last-1";
    case Variant::kReliable:
      return "reliable keep-last-1";
  }
  return "";
}

Qos qos_for(Variant variant, const LinkConfig& config, End end) {
  if (variant == Variant::kCommand) return command_qos(config, end);
  if (variant == Variant::kPlainBestEffort) return vehicle_state_qos();
  Qos qos;
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 1);
  return qos;
}

std::string topic_name(const char* base, std::size_t index) {
  return std::string(base) + "_" + std::to_string(index);
}

struct Stats {
  double p50_us = 0;
  double p99_us = 0;
  double max_us = 0;
  std::size_t count = 0;
};

Stats stats_of(const std::vector<std::int64_t>& values_ns) {
  Stats s;
  s.count = values_ns.size();
  if (values_ns.empty()) return s;
  s.p50_us = 1e-3 * quantile(values_ns, 0.5);
  s.p99_us = 1e-3 * quantile(values_ns, 0.99);
  s.max_us = 1e-3 * quantile(values_ns, 1.0);
  return s;
}

// Blocks on `waitset` until `reader` yields a sample or `timeout_ns` passes.
template <typename T>
bool receive(WaitSet& waitset, Reader<T>& reader, T& sample, dds_sample_info_t& info,
             dds_duration_t timeout_ns) {
  std::array<dds_attach_t, 1> triggered{};
  const std::int64_t deadline = now_ns() + timeout_ns;
  for (;;) {
    if (reader.take(sample, info)) return true;
    const std::int64_t left = deadline - now_ns();
    if (left <= 0) return false;
    waitset.wait(triggered, left);
  }
}

// ---- the on-board side (child process) ----

void onboard_echo(const LinkConfig& config, int samples, std::int64_t* one_way_ns) {
  Participant participant(config.domain_id);
  for (std::size_t v = 0; v < kVariants.size(); ++v) {
    Topic<VelocityCommand> command_topic(participant, topic_name("bench_command", v));
    Topic<VelocityCommand> echo_topic(participant, topic_name("bench_echo", v));
    Reader<VelocityCommand> reader(participant, command_topic,
                                   qos_for(kVariants[v], config, End::kReader));
    Writer<VelocityCommand> writer(participant, echo_topic,
                                   qos_for(kVariants[v], config, End::kWriter));
    WaitSet waitset(participant);
    ReadCondition condition(reader);
    waitset.attach(condition.handle(), 1);
    VelocityCommand command{};
    dds_sample_info_t info{};
    for (;;) {
      if (!receive(waitset, reader, command, info, DDS_SECS(30))) return;
      const std::int64_t t_receipt_ns = now_ns();
      const std::uint64_t index = command.sequence_number;
      writer.write(command);
      if (index == kDone) break;
      if (index < static_cast<std::uint64_t>(samples)) {
        one_way_ns[v * static_cast<std::size_t>(samples) + index] = t_receipt_ns - command.t_ns;
      }
    }
  }
  // Camera: publish 30 Hz frames of ~40 KB (JPEG-sized) on absolute deadlines.
  Topic<CameraFrame> camera_topic(participant);
  Writer<CameraFrame> camera(participant, camera_topic, camera_qos());
  Topic<Heartbeat> ready_topic(participant, "bench_ready");
  Reader<Heartbeat> ready(participant, ready_topic, mode_request_qos());
  WaitSet waitset(participant);
  ReadCondition condition(ready);
  waitset.attach(condition.handle(), 1);
  Heartbeat go{};
  dds_sample_info_t info{};
  if (!receive(waitset, ready, go, info, DDS_SECS(30))) return;
  const int frames = static_cast<int>(go.sequence_number);
  Sample<CameraFrame> frame;
  frame->vehicle_id = config.vehicle_id;
  frame->width_px = 640;
  frame->height_px = 480;
  constexpr std::uint32_t kJpegBytes = 40'000;
  reserve(frame->rgb_jpeg, kJpegBytes);
  frame->rgb_jpeg._length = kJpegBytes;
  for (std::uint32_t i = 0; i < kJpegBytes; ++i) frame->rgb_jpeg._buffer[i] = i * 131 % 256;
  constexpr std::int64_t kPeriodNs = 1'000'000'000 / 30;
  std::int64_t next_ns = now_ns();
  for (int i = 0; i < frames; ++i) {
    next_ns += kPeriodNs;
    hq::sleep_until_monotonic_ns(next_ns);
    frame->sequence_number = static_cast<std::uint64_t>(i);
    frame->t_ns = now_ns();
    camera.write(*frame);
  }
  // Let the last frame leave before the participant goes.
  timespec linger{0, 200'000'000};
  nanosleep(&linger, nullptr);
}

// ---- DDS Security's cost: the same command stream, plain and secured ----
//
// One way, write -> take, on the link's own topic and command QoS, the station writing every
// 1 ms on an absolute schedule (faster than the control rate, slower than a take). Both
// processes read CLOCK_MONOTONIC, so the stamp difference is the latency. Plain and secured run
// one after the other in the same run, each on a domain of its own (a process with Cyclone's
// security plugins loaded for a domain accepts only secured participants on it).

constexpr int kSecurityWarmup = 300;

// The vehicle (child): records t_take - t_write per sequence number until kDone.
void security_vehicle(const LinkConfig& config, int samples, std::int64_t* one_way_ns) {
  Participant participant(config, security::Role::kVehicle);
  Topic<VelocityCommand> topic(participant);
  Reader<VelocityCommand> reader(participant, topic, command_qos(config, End::kReader));
  WaitSet waitset(participant);
  ReadCondition condition(reader);
  waitset.attach(condition.handle(), 1);
  VelocityCommand command{};
  dds_sample_info_t info{};
  // The first sample may come after the whole rest of the bench.
  dds_duration_t timeout_ns = DDS_SECS(600);
  while (receive(waitset, reader, command, info, timeout_ns)) {
    const std::int64_t t_take_ns = now_ns();
    timeout_ns = DDS_SECS(10);
    if (command.sequence_number == kDone) break;
    const std::uint64_t index = command.sequence_number - kSecurityWarmup;
    if (command.sequence_number >= kSecurityWarmup && index < static_cast<std::uint64_t>(samples)) {
      one_way_ns[index] = t_take_ns - command.t_ns;
    }
  }
}

// The station (parent): waits for the match, then writes warm-up + `samples` commands.
void security_station(const LinkConfig& config, int samples) {
  Participant participant(config, security::Role::kStation);
  Topic<VelocityCommand> topic(participant);
  Writer<VelocityCommand> writer(participant, topic, command_qos(config, End::kWriter));
  check(dds_set_status_mask(writer.handle(), DDS_PUBLICATION_MATCHED_STATUS), "dds_set_status_mask",
        "bench command writer");
  WaitSet waitset(participant);
  waitset.attach(writer.handle(), 1);
  std::array<dds_attach_t, 1> triggered{};
  const std::int64_t give_up_ns = now_ns() + 20'000'000'000;
  while (writer.matched_readers() == 0 && now_ns() < give_up_ns) {
    waitset.wait(triggered, DDS_MSECS(100));
  }
  if (writer.matched_readers() == 0) {
    throw InputError("hq-bench-link: the vehicle's command reader never matched (domain " +
                     std::to_string(config.domain_id) + ")");
  }
  VelocityCommand command{};
  command.vehicle_id = config.vehicle_id;
  std::int64_t next_ns = now_ns();
  const auto tick = [&next_ns] {
    next_ns += 1'000'000;
    hq::sleep_until_monotonic_ns(next_ns);
  };
  for (int i = 0; i < kSecurityWarmup + samples; ++i) {
    tick();
    command.sequence_number = static_cast<std::uint64_t>(i);
    command.t_ns = now_ns();
    writer.write(command);
  }
  // Best effort: repeat the end marker so that one of them arrives.
  command.sequence_number = kDone;
  for (int i = 0; i < 20; ++i) {
    tick();
    writer.write(command);
  }
}

// ---- the ground side (parent process) ----

struct VariantResult {
  std::vector<std::int64_t> round_trip_ns;
  int lost = 0;
};

VariantResult ground_ping(Participant& participant, const LinkConfig& config, std::size_t v,
                          int samples) {
  Topic<VelocityCommand> command_topic(participant, topic_name("bench_command", v));
  Topic<VelocityCommand> echo_topic(participant, topic_name("bench_echo", v));
  Reader<VelocityCommand> reader(participant, echo_topic,
                                 qos_for(kVariants[v], config, End::kReader));
  Writer<VelocityCommand> writer(participant, command_topic,
                                 qos_for(kVariants[v], config, End::kWriter));
  WaitSet waitset(participant);
  ReadCondition condition(reader);
  waitset.attach(condition.handle(), 1);
  check(dds_set_status_mask(writer.handle(), DDS_PUBLICATION_MATCHED_STATUS), "dds_set_status_mask",
        "bench writer");
  WaitSet match_waitset(participant);
  match_waitset.attach(writer.handle(), 1);
  std::array<dds_attach_t, 1> triggered{};
  const std::int64_t match_deadline = now_ns() + DDS_SECS(10);
  while (writer.matched_readers() == 0 || reader.matched_writers() == 0) {
    if (now_ns() > match_deadline) throw InputError("hq-bench-link: echo process never matched");
    match_waitset.wait(triggered, DDS_MSECS(10));
  }
  VariantResult result;
  result.round_trip_ns.reserve(static_cast<std::size_t>(samples));
  VelocityCommand command{};
  command.vehicle_id = config.vehicle_id;
  command.station_id = config.station_id;
  VelocityCommand echo{};
  dds_sample_info_t info{};
  // Warm-up samples use indices past `samples` so the echo side does not record them.
  for (int i = -kWarmup; i < samples; ++i) {
    command.sequence_number = static_cast<std::uint64_t>(i < 0 ? samples + (i + kWarmup) : i);
    command.t_ns = now_ns();
    writer.write(command);
    bool got = false;
    while (receive(waitset, reader, echo, info, DDS_SECS(1))) {
      if (echo.sequence_number == command.sequence_number) {
        got = true;
        break;
      }
    }
    const std::int64_t t_back_ns = now_ns();
    if (i < 0) continue;
    if (got) {
      result.round_trip_ns.push_back(t_back_ns - command.t_ns);
    } else {
      ++result.lost;
    }
  }
  command.sequence_number = kDone;
  for (int attempt = 0; attempt < 20; ++attempt) {
    writer.write(command);
    if (receive(waitset, reader, echo, info, DDS_MSECS(100)) && echo.sequence_number == kDone) {
      break;
    }
  }
  return result;
}

struct CameraResult {
  int received = 0;
  int sent = 0;
  double mbit_per_s = 0;
  Stats latency;
};

CameraResult ground_camera(Participant& participant, const LinkConfig& config, int frames) {
  Topic<CameraFrame> camera_topic(participant);
  Reader<CameraFrame> reader(participant, camera_topic, camera_qos());
  Topic<Heartbeat> ready_topic(participant, "bench_ready");
  Writer<Heartbeat> ready(participant, ready_topic, mode_request_qos());
  // Match before the publisher starts so that no frame is lost to discovery.
  std::array<dds_attach_t, 1> triggered{};
  WaitSet waitset(participant);
  ReadCondition condition(reader);
  waitset.attach(condition.handle(), 1);
  WaitSet match_waitset(participant);
  check(dds_set_status_mask(reader.handle(), DDS_SUBSCRIPTION_MATCHED_STATUS),
        "dds_set_status_mask", "bench camera reader");
  match_waitset.attach(reader.handle(), 1);
  const std::int64_t match_deadline = now_ns() + DDS_SECS(10);
  while (reader.matched_writers() == 0) {
    if (now_ns() > match_deadline)
      throw InputError("hq-bench-link: camera publisher never matched");
    match_waitset.wait(triggered, DDS_MSECS(10));
  }
  Heartbeat go{};
  go.vehicle_id = config.vehicle_id;
  go.sequence_number = static_cast<std::uint64_t>(frames);
  ready.write(go);
  Sample<CameraFrame> frame;
  reserve(frame->rgb_jpeg, hq_msgs_kMaxJpegBytes);
  reserve(frame->depth_preview, hq_msgs_kMaxDepthPreviewBytes);
  dds_sample_info_t info{};
  CameraResult result;
  result.sent = frames;
  std::vector<std::int64_t> latency_ns;
  std::uint64_t bytes = 0;
  std::int64_t t_first_ns = 0;
  std::int64_t t_last_ns = 0;
  while (receive(waitset, reader, *frame, info, DDS_SECS(2))) {
    const std::int64_t t_ns = now_ns();
    if (result.received == 0) t_first_ns = t_ns;
    t_last_ns = t_ns;
    latency_ns.push_back(t_ns - frame->t_ns);
    bytes += frame->rgb_jpeg._length;
    ++result.received;
    if (frame->sequence_number + 1 == static_cast<std::uint64_t>(frames)) break;
  }
  if (result.received > 1) {
    result.mbit_per_s = static_cast<double>(bytes) * 8e-6 /
                        (static_cast<double>(t_last_ns - t_first_ns) * 1e-9) *
                        (result.received - 1) / result.received;
  }
  result.latency = stats_of(latency_ns);
  return result;
}

// ---- Cyclone's ddsperf floor ----

struct DdsperfResult {
  bool ran = false;
  Stats half_round_trip;  // ddsperf prints latency as half the round trip
  std::size_t lines = 0;
};

double parse_us(const std::string& line, const std::string& key) {
  const std::size_t at = line.find(" " + key + " ");
  if (at == std::string::npos) return -1;
  return std::strtod(line.c_str() + at + key.size() + 2, nullptr);
}

DdsperfResult run_ddsperf(int domain_id, int duration_s) {
  DdsperfResult result;
  const std::string domain = std::to_string(domain_id);
  const std::string pong =
      "ddsperf -i " + domain + " -D " + std::to_string(duration_s + 2) + " pong >/dev/null 2>&1 &";
  const std::string ping =
      "ddsperf -i " + domain + " -D " + std::to_string(duration_s) + " ping 2>/dev/null";
  if (std::system(pong.c_str()) != 0) return result;
  FILE* out = popen(ping.c_str(), "r");
  if (out == nullptr) return result;
  std::vector<double> p50;
  std::vector<double> p99;
  char buffer[512];
  while (std::fgets(buffer, sizeof(buffer), out) != nullptr) {
    const std::string line(buffer);
    if (line.find(" 50% ") == std::string::npos) continue;
    p50.push_back(parse_us(line, "50%"));
    p99.push_back(parse_us(line, "99%"));
    result.half_round_trip.max_us = std::max(result.half_round_trip.max_us, parse_us(line, "max"));
    result.half_round_trip.count += static_cast<std::size_t>(std::max(0.0, parse_us(line, "cnt")));
  }
  pclose(out);
  // ddsperf prints percentiles per second; the median of those is reported.
  result.lines = p50.size();
  if (p50.empty()) return result;
  std::sort(p50.begin(), p50.end());
  std::sort(p99.begin(), p99.end());
  result.half_round_trip.p50_us = p50[p50.size() / 2];
  result.half_round_trip.p99_us = p99[p99.size() / 2];
  result.ran = true;
  return result;
}

void print(const char* label, const Stats& s) {
  fmt::print("  {:<34} p50 {:8.1f} us  p99 {:8.1f} us  max {:9.1f} us  (n={})\n", label, s.p50_us,
             s.p99_us, s.max_us, s.count);
}

struct BenchOptions {
  LinkConfig config;
  int samples = 10'000;          ///< Command round trips per QoS variant.
  double camera_s = 4.0;         ///< Camera stream duration.
  int ddsperf_s = 5;             ///< ddsperf ping duration, 0: skipped.
  int security_samples = 5'000;  ///< Commands measured plain and secured, 0: skipped.
};

// The command line; an exit status when told to stop (--help, a parse error).
std::optional<int> parse_options(int argc, char** argv, BenchOptions& o) {
  CLI::App app("hq-bench-link: DDS command latency and camera throughput on loopback");
  LinkOverrides overrides;
  add_link_options(app, overrides);
  app.add_option("--samples", o.samples, "command round trips per QoS variant")
      ->check(CLI::Range(100, 1'000'000));
  app.add_option("--camera-s", o.camera_s, "camera stream duration")->check(CLI::Range(0.5, 60.0));
  app.add_option("--ddsperf-s", o.ddsperf_s, "ddsperf ping duration (0 skips it)")
      ->check(CLI::Range(0, 60));
  app.add_option("--security-samples", o.security_samples,
                 "commands (1 ms apart) measured plain and then secured (0 skips it)")
      ->check(CLI::Range(0, 1'000'000));
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  if (!overrides.domain_id) overrides.domain_id = 150 + static_cast<int>(getpid() % 70);
  apply_overrides(overrides, o.config);
  return std::nullopt;
}

// Stamps the child processes write and the parent reads: shared anonymous memory, -1 = none.
class SharedStamps {
 public:
  explicit SharedStamps(std::size_t count)
      : count_(std::max<std::size_t>(count, 1)), bytes_(sizeof(std::int64_t) * count_) {
    void* p = mmap(nullptr, bytes_, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw InputError("hq-bench-link: mmap failed");
    ns_ = static_cast<std::int64_t*>(p);
    std::fill(ns_, ns_ + count_, std::int64_t{-1});
  }
  ~SharedStamps() { munmap(ns_, bytes_); }
  SharedStamps(const SharedStamps&) = delete;
  SharedStamps& operator=(const SharedStamps&) = delete;
  [[nodiscard]] std::int64_t* data() { return ns_; }
  /// The stamps written among [first, first + count).
  [[nodiscard]] std::vector<std::int64_t> written(std::size_t first, std::size_t count) const {
    std::vector<std::int64_t> values;
    for (std::size_t i = first; i < first + count; ++i) {
      if (ns_[i] >= 0) values.push_back(ns_[i]);
    }
    return values;
  }

 private:
  std::size_t count_;
  std::size_t bytes_;
  std::int64_t* ns_ = nullptr;
};

// DDS Security's cost: keys for vehicle_1 and station_1; plain and secured each on a domain of
// its own (secured domains end at security::kMaxSecuredDomainId).
struct SecurityPair {
  LinkConfig plain;
  LinkConfig secured;
  std::string keys_dir;
};

SecurityPair security_pair(const LinkConfig& config, bool make_keys) {
  SecurityPair pair;
  pair.keys_dir = "/tmp/hq-bench-link-keys-" + std::to_string(getpid());
  pair.plain = config;
  pair.plain.security.enabled = false;
  pair.plain.domain_id = (config.domain_id + 2) % (security::kMaxSecuredDomainId + 1);
  pair.secured = config;
  pair.secured.security = SecurityConfig{};
  pair.secured.security.keys_dir = pair.keys_dir;
  pair.secured.vehicle_id = 1;
  pair.secured.station_id = 1;
  pair.secured.domain_id = (config.domain_id + 3) % (security::kMaxSecuredDomainId + 1);
  if (!make_keys) return pair;
  std::filesystem::remove_all(pair.keys_dir);
  const std::int64_t t_s = static_cast<std::int64_t>(std::time(nullptr));
  security::make_ca(pair.keys_dir, security::valid_for_days(t_s, 1));
  security::make_governance(pair.keys_dir, security::DomainRange{});
  security::IdentityRequest request;
  request.validity = security::valid_for_days(t_s, 1);
  request.role = security::Role::kVehicle;
  security::make_identity(pair.keys_dir, request);
  request.role = security::Role::kStation;
  request.vehicles = {1};
  security::make_identity(pair.keys_dir, request);
  return pair;
}

// The secured and plain vehicles, each a child process writing its one-way stamps.
std::array<pid_t, 2> fork_security_vehicles(const BenchOptions& o, const SecurityPair& pair,
                                            SharedStamps& security_ns) {
  std::array<pid_t, 2> children{-1, -1};
  for (std::size_t k = 0; k < 2 && o.security_samples > 0; ++k) {
    children[k] = fork();
    if (children[k] < 0) throw InputError("hq-bench-link: fork failed");
    if (children[k] == 0) {
      int code = 0;
      try {
        security_vehicle(k == 0 ? pair.plain : pair.secured, o.security_samples,
                         security_ns.data() + k * static_cast<std::size_t>(o.security_samples));
      } catch (const std::exception& e) {
        hq::log::error("hq-bench-link: vehicle: {}\n", e.what());
        code = 2;
      }
      std::_Exit(code);
    }
  }
  return children;
}

void print_commands(const BenchOptions& o, const std::vector<VariantResult>& results,
                    const SharedStamps& one_way_ns, const DdsperfResult& ddsperf) {
  fmt::print("hq-bench-link: loopback, two processes, domain {}, {} samples per variant\n",
             o.config.domain_id, o.samples);
  if (ddsperf.ran) {
    fmt::print(
        "Cyclone ddsperf ping/pong floor (reliable, 12 B, listener; {} one-second lines, median of "
        "per-second percentiles):\n",
        ddsperf.lines);
    print("ddsperf half round trip", ddsperf.half_round_trip);
  } else if (o.ddsperf_s > 0) {
    fmt::print("ddsperf: not run or printed no latency (is cyclonedds-tools installed?)\n");
  }
  const auto samples = static_cast<std::size_t>(o.samples);
  for (std::size_t v = 0; v < kVariants.size(); ++v) {
    std::vector<std::int64_t> half(results[v].round_trip_ns);
    for (std::int64_t& h : half) h /= 2;
    const Stats one = stats_of(one_way_ns.written(v * samples, samples));
    const Stats round = stats_of(results[v].round_trip_ns);
    const Stats halved = stats_of(half);
    fmt::print("{}  (lost {})\n", describe(kVariants[v]), results[v].lost);
    print("one way ground -> onboard", one);
    print("round trip", round);
    print("half round trip", halved);
    if (ddsperf.ran && ddsperf.half_round_trip.p50_us > 0) {
      fmt::print("  half round trip / ddsperf: p50 x{:.2f}  p99 x{:.2f}\n",
                 halved.p50_us / ddsperf.half_round_trip.p50_us,
                 halved.p99_us / ddsperf.half_round_trip.p99_us);
    }
  }
}

void print_camera(const BenchOptions& o, const CameraResult& camera) {
  fmt::print("camera 30 Hz, 40 KB frames, best-effort keep-last-1, {:.1f} s:\n", o.camera_s);
  fmt::print("  received {} of {} (drop rate {:.2f} %), {:.2f} Mbit/s\n", camera.received,
             camera.sent, 100.0 * (camera.sent - camera.received) / std::max(1, camera.sent),
             camera.mbit_per_s);
  print("frame latency publish -> receipt", camera.latency);
}

void print_security(const BenchOptions& o, const SecurityPair& pair,
                    const SharedStamps& security_ns) {
  fmt::print(
      "DDS Security's cost, hq_velocity_command with the command QoS, one way write -> take, {} "
      "commands 1 ms apart after {} warm-up, plain (domain {}) then secured (domain {}: "
      "authenticated, access-controlled, payload and metadata AES-GCM):\n",
      o.security_samples, kSecurityWarmup, pair.plain.domain_id, pair.secured.domain_id);
  const auto samples = static_cast<std::size_t>(o.security_samples);
  std::array<Stats, 2> s;
  for (std::size_t k = 0; k < 2; ++k) {
    s[k] = stats_of(security_ns.written(k * samples, samples));
    print(k == 0 ? "plain DDS" : "DDS Security", s[k]);
  }
  if (s[0].p50_us > 0) {
    fmt::print("  secured - plain: p50 {:+.1f} us  p99 {:+.1f} us\n", s[1].p50_us - s[0].p50_us,
               s[1].p99_us - s[0].p99_us);
  }
}

int run(int argc, char** argv) {
  BenchOptions o;
  if (const std::optional<int> status = parse_options(argc, argv, o)) return *status;
  const LinkConfig& config = o.config;
  // Loopback only, as the on-board/ground pair runs in the demo and tests.
  hq::testing::use_loopback_dds(/*keep_existing=*/true);
  SharedStamps one_way_ns(kVariants.size() * static_cast<std::size_t>(o.samples));
  SharedStamps security_ns(2 * static_cast<std::size_t>(o.security_samples));
  const SecurityPair pair = security_pair(config, o.security_samples > 0);

  // Fork before any DDS entity exists: Cyclone's threads do not survive fork().
  const pid_t child = fork();
  if (child < 0) throw InputError("hq-bench-link: fork failed");
  if (child == 0) {
    onboard_echo(config, o.samples, one_way_ns.data());
    std::_Exit(0);
  }
  const std::array<pid_t, 2> security_children = fork_security_vehicles(o, pair, security_ns);
  std::vector<VariantResult> results;
  CameraResult camera;
  {
    Participant participant(config.domain_id);
    for (std::size_t v = 0; v < kVariants.size(); ++v) {
      results.push_back(ground_ping(participant, config, v, o.samples));
    }
    camera = ground_camera(participant, config, static_cast<int>(o.camera_s * 30.0));
  }
  int status = 0;
  waitpid(child, &status, 0);
  bool security_ok = true;
  if (o.security_samples > 0) {
    security_station(pair.plain, o.security_samples);
    security_station(pair.secured, o.security_samples);
    for (const pid_t pid : security_children) {
      int s = 0;
      waitpid(pid, &s, 0);
      security_ok = security_ok && WIFEXITED(s) && WEXITSTATUS(s) == 0;
    }
    std::filesystem::remove_all(pair.keys_dir);
  }
  DdsperfResult ddsperf;
  if (o.ddsperf_s > 0) {
    ddsperf = run_ddsperf((config.domain_id + 1) % (kMaxDomainId + 1), o.ddsperf_s);
  }
  print_commands(o, results, one_way_ns, ddsperf);
  print_camera(o, camera);
  if (o.security_samples > 0) print_security(o, pair, security_ns);
  return WIFEXITED(status) && WEXITSTATUS(status) == 0 && security_ok ? 0 : 1;
}

}  // namespace
}  // namespace hq::link

int main(int argc, char** argv) { return hq::run_tool("hq-bench-link", argc, argv, hq::link::run); }
