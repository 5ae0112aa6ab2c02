#pragma once
/// CLOCK_MONOTONIC: the one clock of every stamp that crosses a thread or a process on a host
/// (frames from the SITL channel, MAVLink stamps mapped onto the companion, link latencies), and
/// absolute sleeps on it, so a late wake-up is never added to the next period.

#include <atomic>
#include <cerrno>
#include <cstdint>
#include <time.h>

namespace hq {

/// A stamp or duration in ns as seconds, for printing and for the few formulas written in
/// seconds; stamps themselves stay std::int64_t ns.
constexpr double to_seconds(std::int64_t t_ns) { return 1e-9 * static_cast<double>(t_ns); }

/// CLOCK_MONOTONIC now, ns.
inline std::int64_t monotonic_now_ns() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000LL + now.tv_nsec;
}

/// Sleeps until CLOCK_MONOTONIC reaches deadline_ns. A signal restarts the sleep unless `stop`
/// (optional) is set by then, which returns at once so that SIGINT/SIGTERM end a loop promptly.
inline void sleep_until_monotonic_ns(std::int64_t deadline_ns,
                                     const std::atomic<bool>* stop = nullptr) {
  timespec deadline{};
  deadline.tv_sec = deadline_ns / 1'000'000'000LL;
  deadline.tv_nsec = deadline_ns % 1'000'000'000LL;
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, nullptr) == EINTR) {
    if (stop != nullptr && stop->load()) return;
  }
}

}  // namespace hq
