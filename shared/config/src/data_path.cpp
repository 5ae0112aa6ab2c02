#include "hq/config/data_path.hpp"

#include <cstdlib>
#include <string_view>
#include <system_error>

namespace hq::config {

namespace fs = std::filesystem;

std::vector<fs::path> data_dirs() {
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
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) dirs.push_back(exe.parent_path().parent_path() / HQ_INSTALL_DATADIR);
  dirs.emplace_back(HQ_SOURCE_DIR);
  return dirs;
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
