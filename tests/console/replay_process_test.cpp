// A recorded simulated flight (hq-ground --record started before hq-sim-flight --link,
// so it holds the vehicle's whole session), then:
//   - hq-report's figures against the vehicle's own flight summary and link log where both
//     measure the same thing (session duration on the vehicle's clock, mode changes, closest
//     clearance);
//   - the replay window under a private Xvfb, driven by typed keys (--keys): Space pauses, Left
//     seeks back 5 s; its clock and rates through --state-json;
//   - a headless replay to the end: the end-of-recording state, counts of the replayed data.
// The recording folder holds flight.mcap, which replay and hq-report prefer; its CSV export
// (hq-report --csv) reports the same flight. And a disk that fills mid-flight: the record stops
// with a message, the flight does not. (A recorder killed with SIGKILL:
// mcap_recorder.flight_mcap_independent_readers.)
#include "hq/mcap/mcap.hpp"
#include "hq/testing/loopback_dds.hpp"
#include "hq/testing/process.hpp"

#include "console_fixture.hpp"
#include "state_json.hpp"
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <memory>
#include <regex>
#include <signal.h>
#include <sstream>
#include <string>
#include <sys/resource.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
using hq::console_test::fresh_artefact_dir;
using hq::console_test::kXvfb;
using hq::console_test::slurp;
using hq::console_test::XvfbDisplay;
using hq::testing::Process;

// The first number after `pattern` (a regex ending where the number starts); NaN if none.
double number_after(const std::string& text, const std::string& pattern) {
  std::string re = pattern;  // appended, not concatenated: GCC 12 -Wrestrict false positive
  re.append("(-?[0-9]+(\\.[0-9]+)?)");
  std::smatch m;
  return std::regex_search(text, m, std::regex(re)) ? std::stod(m[1]) : std::nan("");
}

using hq::console_test::parse_state;
using hq::console_test::state_flag;
using hq::console_test::state_number;
using hq::console_test::state_text;

// Mode transitions in the vehicle's own link log (hq-sim-flight --link-log: t_s,mode,...).
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

using hq::testing::use_loopback_dds;

// Runs hq-report with `args`; its output in dir/<name>.out.
std::string run_report(const fs::path& dir, const std::string& name,
                       const std::vector<std::string>& args, int expected_exit = 0) {
  std::vector<std::string> argv = {HQ_REPORT_EXE};
  argv.insert(argv.end(), args.begin(), args.end());
  Process reporter(argv, (dir / (name + ".out")).string());
  EXPECT_EQ(reporter.wait_exit(60.0), expected_exit) << slurp(dir / (name + ".out"));
  return slurp(dir / (name + ".out"));
}

// GIVEN a flight recorded from before the vehicle's first state to after its last.
void record_flight(const fs::path& dir, const fs::path& recording, const std::string& domain) {
  Process ground(
      {HQ_GROUND_EXE, "--device", "sim", "--haptics-config", "ground/config/demo_hand.yaml",
       "--domain-id", domain, "--insecure", "--duration-s", "9", "--headless", "--record",
       recording.string(), "--state-json", (dir / "live.json").string()},
      (dir / "ground.out").string());
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  Process onboard(
      {HQ_SIM_FLIGHT_EXE, "--link", "--world", "onboard/sim/worlds/arena.yaml", "--duration-s", "5",
       "--domain-id", domain, "--insecure", "--link-log", (dir / "link.csv").string()},
      (dir / "onboard.out").string());
  ASSERT_EQ(onboard.wait_exit(40.0), 0) << slurp(dir / "onboard.out");
  ASSERT_EQ(ground.wait_exit(30.0), 0) << slurp(dir / "ground.out");
}

// THEN the report's figures are the vehicle's where both measure the same thing.
void expect_report_matches_vehicle(const std::string& page, const fs::path& dir) {
  const std::string vehicle = slurp(dir / "onboard.out");
  // One vehicle session whose span on the vehicle's clock is the vehicle's flight (its first
  // state may go out a frame or two before the ground has discovered it).
  const double vehicle_flight_s = number_after(vehicle, "flight +");
  ASSERT_FALSE(std::isnan(vehicle_flight_s)) << vehicle;
  EXPECT_NE(page.find("| vehicle sessions (restarts) | 1: "), std::string::npos) << page;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(page, m, std::regex("([0-9.]+) s on the vehicle's clock"))) << page;
  EXPECT_NEAR(std::stod(m[1]), vehicle_flight_s, 0.5) << page;
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
}

// The folder's flight.mcap is what hq-report reads; its CSV export reports the same flight.
void expect_mcap_report_and_csv_export(const fs::path& dir, const fs::path& recording) {
  const fs::path report = dir / "report";
  const std::string said =
      run_report(dir, "report", {recording.string(), "--out", report.string()});
  EXPECT_NE(said.find("read from " + (recording / "flight.mcap").string()), std::string::npos)
      << said;
  const std::string page = slurp(report / "report.md");
  for (const char* f : {"height.png", "clearance.png", "latency.png", "report.html"}) {
    EXPECT_TRUE(fs::exists(report / f)) << f;
  }
  expect_report_matches_vehicle(page, dir);

  const fs::path csv = dir / "exported";
  const std::string exported =
      run_report(dir, "export", {(recording / "flight.mcap").string(), "--csv", csv.string()});
  const double states = number_after(exported, "-> [^:]+: ");
  EXPECT_GT(states, 100) << exported;                              // ~30 Hz over ~5 s
  EXPECT_GT(number_after(exported, "states, "), 100) << exported;  // commands at 50 Hz
  for (const char* f :
       {"telemetry.csv", "commands.csv", "events.csv", "mode_requests.csv", "rgb.txt"}) {
    EXPECT_TRUE(fs::exists(csv / f)) << f;
  }
  const fs::path csv_report = dir / "csv_report";
  run_report(dir, "csv_report", {csv.string(), "--out", csv_report.string()});
  const std::string csv_page = slurp(csv_report / "report.md");
  EXPECT_NE(csv_page.find("| vehicle sessions (restarts) | 1: "), std::string::npos) << csv_page;
  EXPECT_EQ(number_after(csv_page, "\\| mode changes \\| "),
            number_after(page, "\\| mode changes \\| "))
      << csv_page << page;
  EXPECT_EQ(number_after(csv_page, " s \\(ground receipt, first to last state\\), "), states)
      << csv_page;
}

// hq-ground --replay with `extra` arguments; returns its --state-json.
std::string replay(const fs::path& dir, const fs::path& recording, const std::string& name,
                   std::vector<std::string> extra) {
  const fs::path json = dir / (name + ".json");
  std::vector<std::string> args = {HQ_GROUND_EXE, "--replay", recording.string()};
  args.insert(args.end(), extra.begin(), extra.end());
  args.insert(args.end(), {"--state-json", json.string()});
  Process p(args, (dir / (name + ".out")).string());
  EXPECT_EQ(p.wait_exit(30.0), 0) << slurp(dir / (name + ".out"));
  return slurp(json);
}

// WHEN it plays from 2 s, THEN the rates are those of the replayed data (non-zero).
void expect_replay_plays(const fs::path& dir, const fs::path& recording) {
  const std::string json =
      replay(dir, recording, "replay_playing",
             {"--seek", "2", "--window-size", "1280x800", "--duration-s", "2"});
  const nlohmann::json parsed = parse_state(json);
  EXPECT_EQ(state_flag(parsed, "/replay/playing"), 1) << json;
  EXPECT_GT(state_number(parsed, "/replay/position_s"), 3.5) << json;
  EXPECT_GT(state_number(parsed, "/state_rate_hz"), 15) << json;  // ~30 Hz recorded
  EXPECT_GT(state_number(parsed, "/camera_rate_hz"), 3) << json;  // ~10 Hz recorded
  EXPECT_GT(state_number(parsed, "/states_received"), 30) << json;
}

// WHEN Space pauses it and Left seeks 5 s back, THEN it stays paused there, showing only the
// states up to the new position (the model was rebuilt, not left with the later ones).
void expect_replay_pauses_and_seeks(const fs::path& dir, const fs::path& recording) {
  const fs::path shot = dir / "replay_paused.png";
  const std::string json = replay(dir, recording, "replay_paused",
                                  {"--seek", "6", "--window-size", "1280x800", "--duration-s", "3",
                                   "--keys", "1.0:Space,1.5:Left", "--screenshot", shot.string()});
  const nlohmann::json parsed = parse_state(json);
  EXPECT_EQ(state_flag(parsed, "/replay/playing"), 0) << json;
  EXPECT_EQ(state_flag(parsed, "/replay/at_end"), 0) << json;
  const double position_s = state_number(parsed, "/replay/position_s");
  // Paused after 1 s of the window (plus its start-up), then 5 s back from 6 + that.
  EXPECT_GT(position_s, 1.9) << json;
  EXPECT_LT(position_s, 4.5) << json;
  EXPECT_GT(state_number(parsed, "/state_rate_hz"), 15) << json;
  // ~30 states/s up to the position; never the ~180 of the vehicle's whole flight.
  EXPECT_LT(state_number(parsed, "/states_received"), 32 * position_s + 5) << json;
  EXPECT_GT(fs::file_size(shot), 20'000U);
}

// WHEN a headless replay plays to the end, THEN it says so, with every event counted.
void expect_replay_ends(const fs::path& dir, const fs::path& recording) {
  const std::string json = replay(dir, recording, "replay_end", {"--speed", "8", "--headless"});
  const nlohmann::json parsed = parse_state(json);
  EXPECT_EQ(state_flag(parsed, "/replay/at_end"), 1) << json;
  EXPECT_NEAR(state_number(parsed, "/replay/position_s"),
              state_number(parsed, "/replay/duration_s"), 1e-3)
      << json;
  // Every recorded event, and the one the console adds of its own at the touchdown (with the
  // flight's length) when the recording holds it: the vehicle lands about 8 s in, near the end of
  // the 9 s the ground records, so some runs hold it and some do not.
  const bool touchdown_recorded = state_text(parsed, "/flight_state") == "landed" &&
                                  state_number(parsed, "/flight_time_s") >= 0.0;
  EXPECT_EQ(state_number(parsed, "/events"),
            state_number(parsed, "/link_events") + (touchdown_recorded ? 1.0 : 0.0))
      << json;
  EXPECT_GT(state_number(parsed, "/camera_frames_received"), 20) << json;  // from the MCAP
  EXPECT_NE(slurp(dir / "replay_end.out").find("(end of recording)"), std::string::npos);
  // The replay's last frame is the live console's last: what it derived from the vehicle's
  // last state (the flight record has the whole state; replay feeds it the live path).
  const nlohmann::json live = parse_state(slurp(dir / "live.json"));
  for (const char* key : {"/flight_state", "/height_source", "/operator_input", "/mode"}) {
    EXPECT_EQ(state_text(parsed, key), state_text(live, key))
        << key << "\nreplay: " << json << "\nlive: " << live.dump();
  }
  // The vehicle sends it: neither "-" (unknown) nor absent.
  EXPECT_NE(state_text(parsed, "/flight_state"), "-") << json;
  EXPECT_NE(state_text(parsed, "/flight_state"), "") << json;
  for (const char* key : {"/motors_armed", "/height_valid", "/position_from_vehicle"}) {
    EXPECT_EQ(state_flag(parsed, key), state_flag(live, key)) << key << "\n" << json;
  }
  for (const char* key :
       {"/height_m", "/clearance_m", "/hover_thrust_gain", "/obstacle_points", "/markers_latest"}) {
    EXPECT_NEAR(state_number(parsed, key), state_number(live, key), 1e-3)
        << key << "\nreplay: " << json << "\nlive: " << live.dump();
  }
  EXPECT_GT(state_number(live, "/obstacle_points"), 0) << live.dump();  // the arena's walls
  // The top view's pose: dead reckoned over the same states (the recorder's receipt stamps
  // differ from the link's by its thread's take).
  EXPECT_NEAR(state_number(parsed, "/yaw_W_rad"), state_number(live, "/yaw_W_rad"), 0.02);
  for (const char* key : {"/position_W_m/0", "/position_W_m/1"}) {
    EXPECT_NEAR(state_number(parsed, key), state_number(live, key), 0.1) << key;
  }
}

TEST(ReplayProcesses, ReportMatchesTheVehicleAndTheReplayPausesSeeksAndEnds) {
  if (!fs::exists(kXvfb)) GTEST_SKIP() << kXvfb << " not installed (apt-get install xvfb)";
  use_loopback_dds();
  const std::string domain = std::to_string(hq::testing::private_domain_id(57));
  const fs::path dir = fresh_artefact_dir("replay_test");
  const fs::path recording = dir / "recording";
  record_flight(dir, recording, domain);
  ASSERT_FALSE(HasFatalFailure());
  ASSERT_TRUE(fs::exists(recording / "flight.mcap"));
  expect_mcap_report_and_csv_export(dir, recording);
  const XvfbDisplay display(dir, "1280x800x24", 120);
  expect_replay_plays(dir, recording);
  expect_replay_pauses_and_seeks(dir, recording);
  expect_replay_ends(dir, recording);
}

// GIVEN hq-ground recording with a file size limit standing in for a full disk (write(2) fails
// with EFBIG once flight.mcap reaches it), WHEN it flies, THEN the flight record stops with a
// message naming the file and reason, the operator's event and exit summary say so, and the
// command stream never stalls (its rate is the configured one to the end).
TEST(RecordingProcesses, FullDiskStopsTheFlightRecordNotTheFlight) {
  use_loopback_dds();
  const std::string domain = std::to_string(hq::testing::private_domain_id(131));
  const fs::path dir = fresh_artefact_dir("full_disk_test");
  Process onboard({HQ_SIM_FLIGHT_EXE, "--link", "--world", "onboard/sim/worlds/arena.yaml",
                   "--duration-s", "10", "--domain-id", domain, "--insecure"},
                  (dir / "onboard.out").string());
  // The limit and the ignored SIGXFSZ are inherited through posix_spawn by hq-ground only.
  rlimit saved{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
  rlimit limited = saved;
  limited.rlim_cur = 256 * 1024;  // the MCAP passes it in ~3 s, the CSV files never do
  std::signal(SIGXFSZ, SIG_IGN);
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &limited), 0);
  Process ground({HQ_GROUND_EXE, "--device", "sim", "--haptics-config",
                  "ground/config/demo_hand.yaml", "--domain-id", domain, "--insecure",
                  "--duration-s", "7", "--headless", "--record", (dir / "flight").string()},
                 (dir / "ground.out").string());
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &saved), 0);
  std::signal(SIGXFSZ, SIG_DFL);
  // The flight went on to its end; the exit status says its record is incomplete.
  ASSERT_EQ(ground.wait_exit(40.0), 5) << slurp(dir / "ground.out");
  onboard.signal(SIGINT);
  const std::string out = slurp(dir / "ground.out");
  EXPECT_NE(out.find("hq-ground: the flight record is incomplete; exit status 5"),
            std::string::npos)
      << out;
  EXPECT_NE(out.find("flight.mcap: recording stopped: "), std::string::npos) << out;
  EXPECT_NE(out.find("File too large"), std::string::npos) << out;
  EXPECT_NE(out.find("  mcap error"), std::string::npos) << out;  // the exit summary
  // 50 Hz commands over 7 s, less start-up: no stall at the failure.
  EXPECT_GT(number_after(out, "sent +"), 300) << out;
  // What reached the disk before the limit still opens.
  const hq::mcap::McapReader reader((dir / "flight" / "flight.mcap").string());
  EXPECT_GT(reader.messages().size(), 10U);
}

}  // namespace
