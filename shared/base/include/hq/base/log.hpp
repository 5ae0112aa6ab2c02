#pragma once
/// The one log layer of every program: four levels, set once by --quiet / --verbose
/// (hq/base/program.hpp), and fmt's formatting. A thin layer on fmt rather than spdlog: fmt is
/// already a dependency, a filtered line costs one relaxed atomic load and formats nothing, and
/// a line that passes is formatted into a stack buffer (fmt::memory_buffer, 500 bytes inline)
/// and written with one fwrite, so it neither allocates nor takes a lock of its own (spdlog's
/// sinks take a mutex per line and its loggers live in shared_ptrs). hq_base_test counts
/// operator new around a logged line and expects none.
///
/// Where a line goes is kept from the printf it replaces: error, warn and note (progress and
/// "which file serves" chatter beside a program's data) on stderr; info and debug, the
/// program's own narrative, on stdout. As with printf, the format carries its own "\n" or "\r".

#include <atomic>
#include <cstdio>
#include <fmt/format.h>
#include <iterator>
#include <utility>

namespace hq::log {

/// Errors always show; --quiet keeps warnings and errors; --verbose adds debug.
enum class Level : int { kError = 0, kWarning = 1, kInfo = 2, kDebug = 3 };

inline std::atomic<Level>& threshold() {
  static std::atomic<Level> level{Level::kInfo};
  return level;
}

inline void set_level(Level level) { threshold().store(level, std::memory_order_relaxed); }

inline bool enabled(Level level) {
  return static_cast<int>(level) <= static_cast<int>(threshold().load(std::memory_order_relaxed));
}

/// Formats and writes one line (or part of one) if `level` is enabled.
template <typename... Args>
void write(Level level, std::FILE* stream, fmt::format_string<Args...> format, Args&&... args) {
  if (!enabled(level)) return;
  fmt::memory_buffer line;
  fmt::format_to(std::back_inserter(line), format, std::forward<Args>(args)...);
  std::fwrite(line.data(), 1, line.size(), stream);
}

template <typename... Args>
void error(fmt::format_string<Args...> format, Args&&... args) {
  write(Level::kError, stderr, format, std::forward<Args>(args)...);
}
template <typename... Args>
void warn(fmt::format_string<Args...> format, Args&&... args) {
  write(Level::kWarning, stderr, format, std::forward<Args>(args)...);
}
/// Information on stderr: progress and what a program chose, beside data it writes on stdout.
template <typename... Args>
void note(fmt::format_string<Args...> format, Args&&... args) {
  write(Level::kInfo, stderr, format, std::forward<Args>(args)...);
}
template <typename... Args>
void info(fmt::format_string<Args...> format, Args&&... args) {
  write(Level::kInfo, stdout, format, std::forward<Args>(args)...);
}
template <typename... Args>
void debug(fmt::format_string<Args...> format, Args&&... args) {
  write(Level::kDebug, stdout, format, std::forward<Args>(args)...);
}

}  // namespace hq::log
