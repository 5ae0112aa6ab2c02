#pragma once
/// What the tests that run hq-onboard, hq-ground and hq-sim as processes share (with
/// loopback_dds.hpp): the programs' summaries read back by pattern, and the scripted operator
/// station (hq-ground with the simulated hand) they fly against.

#include "hq/testing/files.hpp"

#include <chrono>
#include <filesystem>
#include <optional>
#include <regex>
#include <string>
#include <thread>
#include <vector>

namespace hq::testing {

/// The number captured by the first group of `pattern` at its last match in `text`, if any.
inline std::optional<double> number_after(const std::string& text, const std::string& pattern) {
  const std::regex re(pattern);
  std::optional<double> value;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator();
       ++it) {
    value = std::stod((*it)[1].str());
  }
  return value;
}

/// Waits until `file` contains `needle`; false after timeout_s.
inline bool wait_for_text(const std::filesystem::path& file, const std::string& needle,
                          double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    if (slurp(file).find(needle) != std::string::npos) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

/// hq-ground (at ground_exe) as the scripted operator: the simulated device moved by
/// ground/config/demo_hand.yaml, headless, plain DDS in `domain`, for duration_s.
inline std::vector<std::string> scripted_ground_args(const std::string& ground_exe,
                                                     const std::string& domain, double duration_s) {
  return {ground_exe,
          "--device",
          "sim",
          "--headless",
          "--haptics-config",
          "ground/config/demo_hand.yaml",
          "--domain-id",
          domain,
          "--insecure",
          "--duration-s",
          std::to_string(duration_s)};
}

}  // namespace hq::testing
