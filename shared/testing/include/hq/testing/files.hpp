#pragma once
/// Files of a test: a fresh folder of its own under the temporary directory and a whole file read
/// back as text (what a program under test wrote).

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>

namespace hq::testing {

/// TMPDIR/<prefix>_<pid>_<name>, removed if it exists (not created): one per test and process,
/// so parallel test binaries never share one.
inline std::filesystem::path fresh_dir(const std::string& prefix, const std::string& name) {
  std::filesystem::path dir = std::filesystem::temp_directory_path() /
                              (prefix + "_" + std::to_string(getpid()) + "_" + name);
  std::filesystem::remove_all(dir);
  return dir;
}

/// The whole file as text; empty if it cannot be read.
inline std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace hq::testing
