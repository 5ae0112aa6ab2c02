#include "hq/recording/data_dir.hpp"

#include <cstdlib>
#include <filesystem>
#include <system_error>

namespace hq::recording {
namespace {

constexpr const char* kRelativeDataDir = "../shared/data";

bool is_directory(const std::string& path) {
  std::error_code ec;
  return std::filesystem::is_directory(path, ec);
}

}  // namespace

std::optional<std::string> find_data_dir() {
  // A set variable overrides the default: pointing it at nothing is how a user asks for the
  // real-data tests to be skipped.
  if (const char* env = std::getenv("HQ_DATA_DIR"); env != nullptr && *env != '\0') {
    if (is_directory(env)) return std::string(env);
    return std::nullopt;
  }
  if (is_directory(kRelativeDataDir)) return std::string(kRelativeDataDir);
  return std::nullopt;
}

std::string data_dir_search_description() {
  const char* env = std::getenv("HQ_DATA_DIR");
  std::string description = "$HQ_DATA_DIR (";
  description += (env != nullptr && *env != '\0') ? env : "unset";
  description += ") and ";
  std::error_code ec;
  description += std::filesystem::absolute(kRelativeDataDir, ec).lexically_normal().string();
  return description;
}

}  // namespace hq::recording
