// hq-bench-console: the operator console's frame rate under a private Xvfb at 1280x800 and
// 1920x1080 while a simulated flight runs, beside an empty ImGui window's (hq-ground
// --bare-window) measured in the same run on the same display: the floor the renderer (here
// usually Mesa's llvmpipe) sets. Built, not run by ctest (timings depend on the machine).
//   hq-bench-console [--seconds 12] [--max-fps 60] [--sizes 1280x800,1920x1080]
#include "hq/base/format_into.hpp"
#include "hq/base/log.hpp"
#include "hq/testing/loopback_dds.hpp"
#include "hq/testing/process.hpp"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
using hq::testing::Process;

struct Figures {
  double fps = -1;
  double render_p50_ms = -1;
  double render_max_ms = -1;
  std::string renderer;
};

Figures read_figures(const fs::path& state) {
  std::ifstream in(state);
  std::stringstream ss;
  ss << in.rdbuf();
  const nlohmann::json j = nlohmann::json::parse(ss.str(), nullptr, false);
  Figures f;
  if (!j.is_object() || !j.contains("window")) return f;
  const nlohmann::json& w = j["window"];
  f.fps = w.value("fps", -1.0);
  f.render_p50_ms = w.value("render_ms_p50", -1.0);
  f.render_max_ms = w.value("render_ms_max", -1.0);
  f.renderer = w.value("gl_renderer", std::string("?"));
  return f;
}

// A private Xvfb; sets DISPLAY while it lives.
class Xvfb {
 public:
  Xvfb(const fs::path& dir, const std::string& size) {
    int number = 170 + getpid() % 40;
    while (fs::exists("/tmp/.X" + std::to_string(number) + "-lock")) ++number;
    const std::string name = ":" + std::to_string(number);
    process_ =
        std::make_unique<Process>(std::vector<std::string>{"/usr/bin/Xvfb", name, "-screen", "0",
                                                           size + "x24", "-nolisten", "tcp"},
                                  dir / "xvfb.out");
    for (int i = 0; i < 50 && !fs::exists("/tmp/.X11-unix/X" + std::to_string(number)); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    setenv("DISPLAY", name.c_str(), 1);
  }

 private:
  std::unique_ptr<Process> process_;
};

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  for (std::string item; std::getline(ss, item, ',');) out.push_back(item);
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"hq-bench-console: the console's frame rate beside an empty window's"};
  double seconds = 12;
  double max_fps = 60;
  std::string sizes = "1280x800,1920x1080";
  std::string out_dir = "bench-console";
  app.add_option("--seconds", seconds, "console run per size")->check(CLI::Range(4.0, 600.0));
  app.add_option("--max-fps", max_fps, "hq-ground --max-fps (60 as shipped)");
  app.add_option("--sizes", sizes, "display sizes WxH,...");
  app.add_option("--out", out_dir, "logs, states and screenshots");
  CLI11_PARSE(app, argc, argv);
  if (!fs::exists("/usr/bin/Xvfb")) {
    hq::log::error("hq-bench-console: /usr/bin/Xvfb not installed\n");
    return 2;
  }
  hq::testing::use_loopback_dds();
  char fps_cap_text[32];
  hq::format_into(fps_cap_text, "{:g}", max_fps);
  const std::string fps_cap = fps_cap_text;
  fmt::print(
      "hq-bench-console: {:.0f} s per run, --max-fps {}, simulated flight "
      "(ground/config/demo_hand.yaml)\n",
      seconds, fps_cap);
  fmt::print("{:<10} {:<22} {:>8} {:>16} {:>14}  {}\n", "size", "window", "fps", "render p50 ms",
             "render max ms", "renderer");
  int failures = 0;
  for (const std::string& size : split(sizes)) {
    const fs::path dir = fs::path(out_dir) / size;
    fs::remove_all(dir);
    fs::create_directories(dir);
    const Xvfb display(dir, size);
    const std::string duration = std::to_string(seconds);
    // The empty window first (no vehicle needed), then the console during a flight.
    {
      Process bare(
          {HQ_GROUND_EXE, "--device", "sim", "--bare-window", "--duration-s", duration,
           "--window-size", size, "--window-ini", "none", "--max-fps", fps_cap, "--domain-id",
           "231", "--insecure", "--state-json", (dir / "bare.json").string()},
          dir / "bare.out");
      if (bare.wait_exit(seconds + 30) != 0) ++failures;
    }
    const std::string domain = std::to_string(hq::testing::private_domain_id(71));
    Process onboard(
        {HQ_SIM_FLIGHT_EXE, "--link", "--world", "onboard/sim/worlds/arena.yaml", "--duration-s",
         std::to_string(seconds + 6), "--domain-id", domain, "--insecure"},
        dir / "onboard.out");
    {
      Process console({HQ_GROUND_EXE,
                       "--device",
                       "sim",
                       "--haptics-config",
                       "ground/config/demo_hand.yaml",
                       "--duration-s",
                       duration,
                       "--window-size",
                       size,
                       "--window-ini",
                       "none",
                       "--max-fps",
                       fps_cap,
                       "--domain-id",
                       domain,
                       "--insecure",
                       "--state-json",
                       (dir / "console.json").string(),
                       "--screenshot",
                       (dir / "console.png").string()},
                      dir / "console.out");
      if (console.wait_exit(seconds + 30) != 0) ++failures;
    }
    onboard.wait_exit(15);
    for (const char* which : {"bare", "console"}) {
      const Figures f = read_figures(dir / (std::string(which) + ".json"));
      fmt::print("{:<10} {:<22} {:8.1f} {:16.1f} {:14.1f}  {}\n", size,
                 std::string(which) == "bare" ? "empty ImGui window" : "console, flying", f.fps,
                 f.render_p50_ms, f.render_max_ms, f.renderer);
    }
  }
  fmt::print("logs, states and screenshots in {}/\n", out_dir);
  return failures == 0 ? 0 : 1;
}
