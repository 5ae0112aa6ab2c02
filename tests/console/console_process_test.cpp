// The operator console against a real simulated flight: hq-onboard --source sim --link and
// hq-ground (console window, --device sim with the scripted hand) on loopback in a private DDS
// domain, under a private Xvfb display. Asserts on the console's own state (--state-json), keeps
// its screenshot in the build directory, reports the recording with hq-report and replays a
// truncated copy of it.
#include <gtest/gtest.h>

#include "hq/testing/process.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <string_view>
#include <thread>
#include <vector>


namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A number in the state JSON, -1 if absent.
double json_number(const std::string& json, const std::string& key) {
  std::string pattern = "\"";  // appended, not concatenated: GCC 12 -Wrestrict false positive
  pattern.append(key).append("\": (-?[0-9.]+)");
  const std::regex re(pattern);
  std::smatch m;
  return std::regex_search(json, m, re) ? std::stod(m[1]) : -1;
}

std::string json_text(const std::string& json, const std::string& key) {
  std::string pattern = "\"";
  pattern.append(key).append("\": \"([^\"]*)\"");
  const std::regex re(pattern);
  std::smatch m;
  return std::regex_search(json, m, re) ? std::string(m[1]) : "";
}

// A boolean in the state JSON: 1 true, 0 false, -1 absent.
int json_bool(const std::string& json, const std::string& key) {
  std::string pattern = "\"";
  pattern.append(key).append("\": (true|false)");
  const std::regex re(pattern);
  std::smatch m;
  return std::regex_search(json, m, re) ? (m[1] == "true" ? 1 : 0) : -1;
}

using hq::testing::Process;

const char* const kXvfb = "/usr/bin/Xvfb";

TEST(ConsoleProcesses, ConsoleShowsSimulatedFlightThenReportAndTruncatedReplay) {
  if (!fs::exists(kXvfb)) GTEST_SKIP() << kXvfb << " not installed (apt-get install xvfb)";
  setenv("CYCLONEDDS_URI",
         "<CycloneDDS><Domain><General><Interfaces><NetworkInterface name=\"lo\"/>"
         "</Interfaces></General></Domain></CycloneDDS>",
         1);
  const std::string domain = std::to_string(1 + (getpid() + 101) % 200);
  const fs::path dir = fs::path(HQ_CONSOLE_ARTEFACT_DIR) / "console_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  // A display of our own: the first free number from 90 (a lock file marks a used one).
  int display = 90 + getpid() % 50;
  while (fs::exists("/tmp/.X" + std::to_string(display) + "-lock")) ++display;
  std::string display_name = ":";  // appended: GCC 12 -Wrestrict false positive on "+"
  display_name.append(std::to_string(display));
  Process xvfb({kXvfb, display_name, "-screen", "0", "1600x1000x24", "-nolisten", "tcp"},
               dir / "xvfb.out");
  for (int i = 0; i < 50 && !fs::exists("/tmp/.X11-unix/X" + std::to_string(display)); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  setenv("DISPLAY", display_name.c_str(), 1);

  Process onboard({HQ_ONBOARD_EXE, "--source", "sim", "--link", "--world",
                   "onboard/sim/worlds/arena.yaml", "--duration-s", "11", "--domain-id", domain,
                   "--insecure"},
                  dir / "onboard.out");
  const fs::path shot = dir / "console.png";
  const fs::path state = dir / "state.json";
  const fs::path recording = dir / "recording";
  Process ground({HQ_GROUND_EXE, "--device", "sim", "--haptics-config",
                  "ground/config/demo_hand.yaml", "--domain-id", domain, "--insecure", "--duration-s", "8",
                  "--record", recording.string(), "--screenshot", shot.string(), "--state-json",
                  state.string()},
                 dir / "ground.out");
  ASSERT_EQ(ground.wait_exit(30.0), 0) << slurp(dir / "ground.out");
  ASSERT_EQ(onboard.wait_exit(20.0), 0) << slurp(dir / "onboard.out");

  // THEN the console drew the flight: frames decoded, plots filled, the vehicle's mode shown.
  const std::string json = slurp(state);
  ASSERT_FALSE(json.empty()) << slurp(dir / "ground.out");
  EXPECT_GT(json_number(json, "camera_frames_decoded"), 20) << json;  // ~10 Hz over ~7 s
  EXPECT_GT(json_number(json, "plot_samples_drawn"), 100) << json;   // frame rate over ~7 s
  EXPECT_GT(json_number(json, "frames"), 50) << json;
  EXPECT_EQ(json_text(json, "mode_shown"), "teleop") << json;  // the scripted hand's request
  EXPECT_GT(json_number(json, "camera_width_px"), 0) << json;
  // The state's position, marker and truth fields reach the console: the flags are shown, a
  // position flag agrees with the count of states that carried one, and a marker count of the
  // latest state within the link's bound.
  const int from_vehicle = json_bool(json, "position_from_vehicle");
  ASSERT_GE(from_vehicle, 0) << json;
  if (from_vehicle == 1) {
    EXPECT_GT(json_number(json, "position_states"), 0) << json;
  }
  EXPECT_GE(json_number(json, "position_states"), 0) << json;
  // The vehicle is the simulator: its truth trace must reach the velocity plots.
  EXPECT_EQ(json_bool(json, "truth"), 1) << json;
  EXPECT_GE(json_number(json, "markers_latest"), 0) << json;
  EXPECT_LE(json_number(json, "markers_latest"), 16) << json;
  EXPECT_GE(json_number(json, "marker_detections"), 0) << json;
  ASSERT_TRUE(fs::exists(shot));
  EXPECT_GT(fs::file_size(shot), 20'000U);  // a PNG of a 1600x960 console, not a blank
  std::printf("console screenshot: %s, %.1f fps\n", shot.c_str(), json_number(json, "fps"));

  // hq-report on the recording writes the figures and the page.
  const fs::path report = dir / "report";
  Process reporter({HQ_REPORT_EXE, recording.string(), "--out", report.string()},
                   dir / "report.out");
  ASSERT_EQ(reporter.wait_exit(30.0), 0) << slurp(dir / "report.out");
  for (const char* f : {"report.md", "velocity_H.png", "v_obs.png", "yaw_rate.png",
                        "top_view.png"}) {
    ASSERT_TRUE(fs::exists(report / f)) << f;
    // A page with its table, figures with curves (gnuplot's empty frame is ~3 KB).
    EXPECT_GT(fs::file_size(report / f), std::string_view(f) == "report.md" ? 300U : 5000U) << f;
  }
  EXPECT_NE(slurp(report / "report.md").find("tracking error RMS"), std::string::npos);

  // A truncated copy replays what is readable and names the cut line.
  const fs::path cut = dir / "truncated";
  fs::copy(recording, cut, fs::copy_options::recursive);
  const std::string telemetry = slurp(cut / "telemetry.csv");
  std::ofstream(cut / "telemetry.csv") << telemetry.substr(0, telemetry.size() - 25);
  const std::size_t lines = static_cast<std::size_t>(
      std::count(telemetry.begin(), telemetry.end(), '\n'));
  const fs::path replay_state = dir / "replay.json";
  Process replay({HQ_GROUND_EXE, "--replay", cut.string(), "--speed", "8", "--headless",
                  "--state-json", replay_state.string()},
                 dir / "replay.out");
  ASSERT_EQ(replay.wait_exit(30.0), 0) << slurp(dir / "replay.out");
  const std::string replay_out = slurp(dir / "replay.out");
  // The cut line is named, whatever the recording's column count (it grows with the state).
  const std::size_t named = replay_out.find("telemetry.csv:" + std::to_string(lines) + ": expected ");
  ASSERT_NE(named, std::string::npos) << replay_out;
  EXPECT_NE(replay_out.find("(truncated last line)", named), std::string::npos) << replay_out;
  const std::string rjson = slurp(replay_state);
  EXPECT_GT(json_number(rjson, "plot_samples"), 100) << rjson;
  EXPECT_GT(json_number(rjson, "camera_frames_received"), 20) << rjson;
  EXPECT_EQ(json_number(rjson, "replay_problems"), 1) << rjson;
}

}  // namespace
