// A recorded simulated flight (hq-ground --record started before hq-onboard --source sim --link,
// so it holds the vehicle's whole session), then:
//   - hq-report's figures against the vehicle's own flight summary and link log where both
//     measure the same thing (session duration on the vehicle's clock, mode changes, closest
//     clearance);
//   - the replay window under a private Xvfb, driven by typed keys (--keys): Space pauses, Left
//     seeks back 5 s; its clock and rates through --state-json;
//   - a headless replay to the end: the end-of-recording state, counts of the replayed data.
#include <gtest/gtest.h>

#include "hq/testing/process.hpp"

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

namespace fs = std::filesystem;
using hq::testing::Process;

std::string slurp(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The first number after `pattern` (a regex ending where the number starts); NaN if none.
double number_after(const std::string& text, const std::string& pattern) {
  std::string re = pattern;  // appended, not concatenated: GCC 12 -Wrestrict false positive
  re.append("(-?[0-9]+(\\.[0-9]+)?)");
  std::smatch m;
  return std::regex_search(text, m, std::regex(re)) ? std::stod(m[1]) : std::nan("");
}

double json_number(const std::string& json, const std::string& key) {
  std::string pattern = "\"";
  pattern.append(key).append("\": ");
  return number_after(json, pattern);
}

int json_bool(const std::string& json, const std::string& key) {
  std::string pattern = "\"";
  pattern.append(key).append("\": (true|false)");
  std::smatch m;
  return std::regex_search(json, m, std::regex(pattern)) ? (m[1] == "true" ? 1 : 0) : -1;
}

// Mode transitions in the vehicle's own link log (hq-onboard --link-log: t_s,mode,...).
int vehicle_mode_changes(const fs::path& link_log) {
  std::ifstream in(link_log);
  std::string line;
  std::getline(in, line);  // header
  std::string previous;
  int changes = 0;
  while (std::getline(in, line)) {
    const std::size_t a = line.find(',');
    const std::size_t b = line.find(',', a + 1);
    if (a == std::string::npos || b == std::string::npos) continue;
    const std::string mode = line.substr(a + 1, b - a - 1);
    if (!previous.empty() && mode != previous) ++changes;
    previous = mode;
  }
  return changes;
}

const char* const kXvfb = "/usr/bin/Xvfb";

TEST(ReplayProcesses, ReportMatchesTheVehicleAndTheReplayPausesSeeksAndEnds) {
  if (!fs::exists(kXvfb)) GTEST_SKIP() << kXvfb << " not installed (apt-get install xvfb)";
  setenv("CYCLONEDDS_URI",
         "<CycloneDDS><Domain><General><Interfaces><NetworkInterface name=\"lo\"/>"
         "</Interfaces></General></Domain></CycloneDDS>",
         1);
  const std::string domain = std::to_string(1 + (getpid() + 57) % 200);
  const fs::path dir = fs::path(HQ_CONSOLE_ARTEFACT_DIR) / "replay_test";
  fs::remove_all(dir);
  fs::create_directories(dir);

  // GIVEN a flight recorded from before the vehicle's first state to after its last.
  const fs::path recording = dir / "recording";
  {
    Process ground({HQ_GROUND_EXE, "--device", "sim", "--haptics-config",
                    "ground/config/demo_hand.yaml", "--domain-id", domain, "--insecure", "--duration-s", "9",
                    "--headless", "--record", recording.string()},
                   (dir / "ground.out").string());
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    Process onboard({HQ_ONBOARD_EXE, "--source", "sim", "--link", "--world",
                     "onboard/sim/worlds/arena.yaml", "--duration-s", "5", "--domain-id", domain,
                     "--insecure", "--link-log", (dir / "link.csv").string()},
                    (dir / "onboard.out").string());
    ASSERT_EQ(onboard.wait_exit(40.0), 0) << slurp(dir / "onboard.out");
    ASSERT_EQ(ground.wait_exit(30.0), 0) << slurp(dir / "ground.out");
  }
  const std::string vehicle = slurp(dir / "onboard.out");

  // WHEN reported, THEN its figures are the vehicle's where both measure the same thing.
  const fs::path report = dir / "report";
  {
    Process reporter({HQ_REPORT_EXE, recording.string(), "--out", report.string()},
                     (dir / "report.out").string());
    ASSERT_EQ(reporter.wait_exit(30.0), 0) << slurp(dir / "report.out");
  }
  const std::string page = slurp(report / "report.md");
  for (const char* f : {"height.png", "clearance.png", "latency.png", "report.html"}) {
    EXPECT_TRUE(fs::exists(report / f)) << f;
  }
  // One vehicle session whose span on the vehicle's clock is the vehicle's flight (its first
  // state may go out a frame or two before the ground has discovered it).
  const double vehicle_flight_s = number_after(vehicle, "flight +");
  ASSERT_FALSE(std::isnan(vehicle_flight_s)) << vehicle;
  EXPECT_NE(page.find("| vehicle sessions (restarts) | 1: "), std::string::npos) << page;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(page, m, std::regex("([0-9.]+) s on the vehicle's clock"))) << page;
  const double session_s = std::stod(m[1]);
  EXPECT_NEAR(session_s, vehicle_flight_s, 0.5) << page;
  // Mode changes: the count is the list, and the vehicle's own log has as many.
  const double changes = number_after(page, "\\| mode changes \\| ");
  EXPECT_EQ(changes, vehicle_mode_changes(dir / "link.csv")) << page;
  // Closest obstacle: the vehicle's clearance when it sends one (its summary's figure), and
  // never the nearest cloud point passed off as a clearance.
  const double vehicle_clearance_m = number_after(vehicle, "closest distance \\(clearance\\) +");
  const double report_clearance_m =
      number_after(page, "\\| closest obstacle \\(vehicle's clearance\\) \\| ");
  if (std::isnan(report_clearance_m)) {
    EXPECT_NE(page.find("| closest obstacle (vehicle's clearance) | not recorded"),
              std::string::npos)
        << page;
  } else {
    EXPECT_NEAR(report_clearance_m, vehicle_clearance_m, 0.05) << page << vehicle;
  }

  // The replay window under a private display: 1280x800.
  int display = 120 + getpid() % 50;
  while (fs::exists("/tmp/.X" + std::to_string(display) + "-lock")) ++display;
  std::string display_name = ":";
  display_name.append(std::to_string(display));
  Process xvfb({kXvfb, display_name, "-screen", "0", "1280x800x24", "-nolisten", "tcp"},
               (dir / "xvfb.out").string());
  for (int i = 0; i < 50 && !fs::exists("/tmp/.X11-unix/X" + std::to_string(display)); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  setenv("DISPLAY", display_name.c_str(), 1);

  // WHEN it plays from 2 s, THEN the rates are those of the replayed data (non-zero).
  const fs::path playing = dir / "playing.json";
  {
    Process replay({HQ_GROUND_EXE, "--replay", recording.string(), "--seek", "2",
                    "--window-size", "1280x800", "--duration-s", "2", "--state-json",
                    playing.string()},
                   (dir / "replay_playing.out").string());
    ASSERT_EQ(replay.wait_exit(30.0), 0) << slurp(dir / "replay_playing.out");
  }
  std::string json = slurp(playing);
  EXPECT_EQ(json_bool(json, "playing"), 1) << json;
  EXPECT_GT(json_number(json, "position_s"), 3.5) << json;
  EXPECT_GT(json_number(json, "state_rate_hz"), 15) << json;  // ~30 Hz recorded
  EXPECT_GT(json_number(json, "camera_rate_hz"), 3) << json;  // ~10 Hz recorded
  EXPECT_GT(json_number(json, "states_received"), 30) << json;

  // WHEN Space pauses it and Left seeks 5 s back, THEN it stays paused there, showing only the
  // states up to the new position (the model was rebuilt, not left with the later ones).
  const fs::path paused = dir / "paused.json";
  const fs::path shot = dir / "replay_paused.png";
  {
    Process replay({HQ_GROUND_EXE, "--replay", recording.string(), "--seek", "6",
                    "--window-size", "1280x800", "--duration-s", "3", "--keys",
                    "1.0:Space,1.5:Left", "--screenshot", shot.string(), "--state-json",
                    paused.string()},
                   (dir / "replay_paused.out").string());
    ASSERT_EQ(replay.wait_exit(30.0), 0) << slurp(dir / "replay_paused.out");
  }
  json = slurp(paused);
  EXPECT_EQ(json_bool(json, "playing"), 0) << json;
  EXPECT_EQ(json_bool(json, "at_end"), 0) << json;
  const double position_s = json_number(json, "position_s");
  // Paused after 1 s of the window (plus its start-up), then 5 s back from 6 + that.
  EXPECT_GT(position_s, 1.9) << json;
  EXPECT_LT(position_s, 4.5) << json;
  EXPECT_GT(json_number(json, "state_rate_hz"), 15) << json;
  // ~30 states/s up to the position; never the ~180 of the vehicle's whole flight.
  EXPECT_LT(json_number(json, "states_received"), 32 * position_s + 5) << json;
  EXPECT_GT(fs::file_size(shot), 20'000U);

  // WHEN a headless replay plays to the end, THEN it says so, with every event counted.
  const fs::path end = dir / "end.json";
  {
    Process replay({HQ_GROUND_EXE, "--replay", recording.string(), "--speed", "8", "--headless",
                    "--state-json", end.string()},
                   (dir / "replay_end.out").string());
    ASSERT_EQ(replay.wait_exit(30.0), 0) << slurp(dir / "replay_end.out");
  }
  json = slurp(end);
  EXPECT_EQ(json_bool(json, "at_end"), 1) << json;
  EXPECT_NEAR(json_number(json, "position_s"), json_number(json, "duration_s"), 1e-3) << json;
  EXPECT_EQ(json_number(json, "link_events"), json_number(json, "events")) << json;
  EXPECT_NE(slurp(dir / "replay_end.out").find("(end of recording)"), std::string::npos);
}

}  // namespace
