#pragma once
// What every console process test starts with: its own artefact folder (the window placement
// file goes there, never to the user's), a private Xvfb display of a given size, and the text
// of an output file. One copy for console_process_test, console_layout_test and
// replay_process_test.
#include "hq/testing/process.hpp"

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace hq::console_test {

inline constexpr const char* kXvfb = "/usr/bin/Xvfb";

/// The whole text of a file ("" if it cannot be read).
inline std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// HQ_CONSOLE_ARTEFACT_DIR/`name`, emptied and created; XDG_CONFIG_HOME points into it.
inline std::filesystem::path fresh_artefact_dir(const std::string& name) {
  std::filesystem::path dir = std::filesystem::path(HQ_CONSOLE_ARTEFACT_DIR) / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  setenv("XDG_CONFIG_HOME", (dir / "config").c_str(), 1);
  return dir;
}

/// A private Xvfb of `screen` ("1280x800x24") on the first free display from `first_number`
/// plus this process's id modulo 50 (each test file its own range); sets DISPLAY. Its output
/// goes to dir/xvfb.out; the display ends with this object.
class XvfbDisplay {
 public:
  XvfbDisplay(const std::filesystem::path& dir, const std::string& screen, int first_number) {
    namespace fs = std::filesystem;
    number_ = first_number + getpid() % 50;
    while (fs::exists("/tmp/.X" + std::to_string(number_) + "-lock")) ++number_;
    name_ = ":";  // appended: GCC 12 -Wrestrict false positive on "+"
    name_.append(std::to_string(number_));
    xvfb_ = std::make_unique<hq::testing::Process>(
        std::vector<std::string>{kXvfb, name_, "-screen", "0", screen, "-nolisten", "tcp"},
        dir / "xvfb.out");
    for (int i = 0; i < 50 && !fs::exists("/tmp/.X11-unix/X" + std::to_string(number_)); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    setenv("DISPLAY", name_.c_str(), 1);
  }

 private:
  int number_ = 0;
  std::string name_;
  std::unique_ptr<hq::testing::Process> xvfb_;
};

}  // namespace hq::console_test
