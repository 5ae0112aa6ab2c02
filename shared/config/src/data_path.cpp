#include "hq/config/data_path.hpp"

#include <algorithm>
#include <cstdlib>
#include <string_view>
#include <system_error>

namespace hq::config {

namespace fs = std::filesystem;

namespace {

/// Whether `path` is `dir` or lies below it, component by component ("/a/bc" is not in "/a/b").
bool is_within(const fs::path& path, const fs::path& dir) {
  return std::mismatch(dir.begin(), dir.end(), path.begin(), path.end()).first == dir.end();
}

}  // namespace

std::vector<fs::path> data_dirs_for_executable(const fs::path& executable) {
  std::vector<fs::path> dirs;
  if (const char* env = std::getenv("HQ_DATA_DIRS"); env != nullptr) {
    std::string_view rest(env);
    while (!rest.empty()) {
      const auto colon = rest.find(':');
      const std::string_view dir = rest.substr(0, colon);
      if (!dir.empty()) dirs.emplace_back(dir);
      if (colon == std::string_view::npos) break;
      rest.remove_prefix(colon + 1);
    }
  }
  if (executable.empty()) return dirs;
  dirs.push_back(executable.parent_path().parent_path() / HQ_INSTALL_DATADIR);
  // The source tree serves only a program run from the build tree it was built in. An installed
  // program is the same file (`cmake --install` copies it and only rewrites its RPATH), so no
  // compile definition can tell the two apart; where the executable lives can. Installed, a
  // file missing from share/haptiquad is then an error naming it, not a silent read of the build
  // machine's sources.
  // HQ_BUILD_DIR is already symlink-free (CMake's REAL_PATH): compared by name, without a look
  // at the build tree, which an installed program must not touch even to stat it.
  if (is_within(executable.lexically_normal(), fs::path(HQ_BUILD_DIR))) {
    dirs.emplace_back(HQ_SOURCE_DIR);
  }
  return dirs;
}

std::vector<fs::path> data_dirs() {
  std::error_code ec;
  // Resolved by the kernel: the real file, whatever symlink or relative name started it.
  const fs::path executable = fs::read_symlink("/proc/self/exe", ec);
  return data_dirs_for_executable(ec ? fs::path() : executable);
}

std::string resolve_data_path(const std::string& path) {
  const fs::path given(path);
  std::error_code ec;
  if (path.empty() || given.is_absolute() || fs::exists(given, ec)) return path;
  for (const fs::path& dir : data_dirs()) {
    fs::path candidate = dir / given;
    if (fs::exists(candidate, ec)) return candidate.lexically_normal().string();
  }
  return path;
}

std::string data_dirs_text() {
  std::string text = "looked in the current folder";
  for (const fs::path& dir : data_dirs()) text += ", " + dir.string();
  return text;
}

}  // namespace hq::config
