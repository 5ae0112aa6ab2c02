// The operator console against a real simulated flight: hq-sim-flight --link and
// hq-ground (console window, --device sim with the scripted hand) on loopback in a private DDS
// domain, under a private Xvfb display. Asserts on the console's own state (--state-json), keeps
// its screenshot in the build directory, reports the recording with hq-report and replays a
// truncated copy of it.
#include "hq/testing/loopback_dds.hpp"
#include "hq/testing/process.hpp"

#include "console_fixture.hpp"
#include "state_json.hpp"
#include <gtest/gtest.h>

#include <X11/Xlib.h>
#include <X11/keysym.h>
#include <algorithm>
#include <chrono>
#include <cstring>
#include <dlfcn.h>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <memory>
#include <signal.h>
#include <sstream>
#include <string>
#include <string_view>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;

using hq::console_test::parse_state;
using hq::console_test::state_flag;
using hq::console_test::state_number;
using hq::console_test::state_text;

using hq::console_test::fresh_artefact_dir;
using hq::console_test::kXvfb;
using hq::console_test::slurp;
using hq::console_test::XvfbDisplay;
using hq::testing::Process;

// Real key presses into a window found by its title, through the XTest extension (what
// xdotool does): the console sees them as a user's keys. libXtst is opened at run time.
class Keyboard {
 public:
  Keyboard() {
    display_ = XOpenDisplay(nullptr);
    xtst_ = dlopen("libXtst.so.6", RTLD_NOW);
    if (xtst_ != nullptr) {
      fake_key_ = reinterpret_cast<FakeKey>(dlsym(xtst_, "XTestFakeKeyEvent"));
    }
  }
  ~Keyboard() {
    if (display_ != nullptr) XCloseDisplay(display_);
    if (xtst_ != nullptr) dlclose(xtst_);
  }
  [[nodiscard]] bool usable() const { return display_ != nullptr && fake_key_ != nullptr; }

  // Waits up to timeout_s for a top-level window whose title starts with `title`, focuses it.
  bool focus(const char* title, double timeout_s) {
    for (int i = 0; i < static_cast<int>(timeout_s * 10); ++i) {
      if (const Window w = find(DefaultRootWindow(display_), title); w != 0) {
        XSetInputFocus(display_, w, RevertToParent, CurrentTime);
        XSync(display_, False);
        return true;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    return false;
  }
  void press(KeySym key) { send(key, True); }
  void release(KeySym key) { send(key, False); }
  void tap(KeySym key) {
    press(key);
    std::this_thread::sleep_for(std::chrono::milliseconds(80));
    release(key);
  }

 private:
  using FakeKey = int (*)(::Display*, unsigned int, int, unsigned long);
  void send(KeySym key, int down) {
    fake_key_(display_, XKeysymToKeycode(display_, key), down, 0);
    XFlush(display_);
  }
  Window find(Window w, const char* title) {
    char* name = nullptr;
    if (XFetchName(display_, w, &name) != 0 && name != nullptr) {
      const bool match = std::strncmp(name, title, std::strlen(title)) == 0;
      XFree(name);
      if (match) return w;
    }
    Window root = 0;
    Window parent = 0;
    Window* children = nullptr;
    unsigned int n = 0;
    Window found = 0;
    if (XQueryTree(display_, w, &root, &parent, &children, &n) != 0) {
      for (unsigned int i = 0; i < n && found == 0; ++i) found = find(children[i], title);
      if (children != nullptr) XFree(children);
    }
    return found;
  }
  ::Display* display_ = nullptr;
  void* xtst_ = nullptr;
  FakeKey fake_key_ = nullptr;
};

using hq::testing::use_loopback_dds;

// The console drew the flight: frames decoded, plots filled, the vehicle's mode shown.
void expect_console_drew_the_flight(const std::string& json) {
  const nlohmann::json parsed = parse_state(json);
  EXPECT_GT(state_number(parsed, "/window/camera_frames_decoded"), 20) << json;  // ~10 Hz over ~7 s
  EXPECT_GT(state_number(parsed, "/window/plot_samples_drawn"), 100)
      << json;  // frame rate over ~7 s
  EXPECT_GT(state_number(parsed, "/window/frames"), 50) << json;
  EXPECT_EQ(state_text(parsed, "/window/mode_shown"), "teleop")
      << json;  // the scripted hand's request
  EXPECT_GT(state_number(parsed, "/window/camera_width_px"), 0) << json;
  // The state's position, marker and truth fields reach the console: the flags are shown, a
  // position flag agrees with the count of states that carried one, and a marker count of the
  // latest state within the link's bound.
  const int from_vehicle = state_flag(parsed, "/position_from_vehicle");
  ASSERT_GE(from_vehicle, 0) << json;
  if (from_vehicle == 1) {
    EXPECT_GT(state_number(parsed, "/position_states"), 0) << json;
  }
  EXPECT_GE(state_number(parsed, "/position_states"), 0) << json;
  // The vehicle is the simulator: its truth trace must reach the velocity plots.
  EXPECT_EQ(state_flag(parsed, "/truth"), 1) << json;
  EXPECT_GE(state_number(parsed, "/markers_latest"), 0) << json;
  EXPECT_LE(state_number(parsed, "/markers_latest"), 16) << json;
  EXPECT_GE(state_number(parsed, "/marker_detections"), 0) << json;
}

// hq-report on the recording writes the figures and the page.
void expect_report_written(const fs::path& dir, const fs::path& recording) {
  const fs::path report = dir / "report";
  Process reporter({HQ_REPORT_EXE, recording.string(), "--out", report.string()},
                   dir / "report.out");
  ASSERT_EQ(reporter.wait_exit(30.0), 0) << slurp(dir / "report.out");
  for (const char* f :
       {"report.md", "velocity_H.png", "v_obs.png", "yaw_rate.png", "top_view.png"}) {
    ASSERT_TRUE(fs::exists(report / f)) << f;
    // A page with its table, figures with curves (gnuplot's empty frame is ~3 KB).
    EXPECT_GT(fs::file_size(report / f), std::string_view(f) == "report.md" ? 300U : 5000U) << f;
  }
  EXPECT_NE(slurp(report / "report.md").find("tracking error RMS"), std::string::npos);
}

// A truncated copy of the CSV files (an older recording: no flight.mcap) replays what is
// readable and names the cut line.
void expect_truncated_csv_replay(const fs::path& dir, const fs::path& recording) {
  const fs::path cut = dir / "truncated";
  fs::copy(recording, cut, fs::copy_options::recursive);
  fs::remove(cut / "flight.mcap");
  const std::string telemetry = slurp(cut / "telemetry.csv");
  std::ofstream(cut / "telemetry.csv") << telemetry.substr(0, telemetry.size() - 25);
  const std::size_t lines =
      static_cast<std::size_t>(std::count(telemetry.begin(), telemetry.end(), '\n'));
  const fs::path replay_state = dir / "replay.json";
  Process replay({HQ_GROUND_EXE, "--replay", cut.string(), "--speed", "8", "--headless",
                  "--state-json", replay_state.string()},
                 dir / "replay.out");
  ASSERT_EQ(replay.wait_exit(30.0), 0) << slurp(dir / "replay.out");
  const std::string replay_out = slurp(dir / "replay.out");
  // The cut line is named, whatever the recording's column count (it grows with the state).
  const std::size_t named =
      replay_out.find("telemetry.csv:" + std::to_string(lines) + ": expected ");
  ASSERT_NE(named, std::string::npos) << replay_out;
  EXPECT_NE(replay_out.find("(truncated last line)", named), std::string::npos) << replay_out;
  const std::string rjson = slurp(replay_state);
  const nlohmann::json replay_parsed = parse_state(rjson);
  EXPECT_GT(state_number(replay_parsed, "/plot_samples"), 100) << rjson;
  EXPECT_GT(state_number(replay_parsed, "/camera_frames_received"), 20) << rjson;
  EXPECT_EQ(state_number(replay_parsed, "/replay_problems"), 1) << rjson;
}

TEST(ConsoleProcesses, ConsoleShowsSimulatedFlightThenReportAndTruncatedReplay) {
  if (!fs::exists(kXvfb)) GTEST_SKIP() << kXvfb << " not installed (apt-get install xvfb)";
  use_loopback_dds();
  const std::string domain = std::to_string(hq::testing::private_domain_id(101));
  const fs::path dir = fresh_artefact_dir("console_test");
  const XvfbDisplay display(dir, "1600x1000x24", 90);

  // GIVEN a simulated flight flown through the console window and recorded.
  Process onboard({HQ_SIM_FLIGHT_EXE, "--link", "--world", "onboard/sim/worlds/arena.yaml",
                   "--duration-s", "11", "--domain-id", domain, "--insecure"},
                  dir / "onboard.out");
  const fs::path shot = dir / "console.png";
  const fs::path state = dir / "state.json";
  const fs::path recording = dir / "recording";
  Process ground(
      {HQ_GROUND_EXE, "--device", "sim", "--haptics-config", "ground/config/demo_hand.yaml",
       "--domain-id", domain, "--insecure", "--duration-s", "8", "--record", recording.string(),
       "--screenshot", shot.string(), "--state-json", state.string()},
      dir / "ground.out");
  ASSERT_EQ(ground.wait_exit(30.0), 0) << slurp(dir / "ground.out");
  ASSERT_EQ(onboard.wait_exit(20.0), 0) << slurp(dir / "onboard.out");

  // THEN the console drew it, hq-report reports it, a truncated old-layout copy replays.
  const std::string json = slurp(state);
  ASSERT_FALSE(json.empty()) << slurp(dir / "ground.out");
  expect_console_drew_the_flight(json);
  // The shipped config has no marker stage: the console greyed marker and explore before any
  // refusal, and said why and how to turn them on under the buttons.
  const nlohmann::json parsed = parse_state(json);
  EXPECT_EQ(state_flag(parsed, "/window/marker_button_enabled"), 0) << json;
  EXPECT_EQ(state_flag(parsed, "/window/explore_button_enabled"), 0) << json;
  EXPECT_EQ(state_text(parsed, "/window/modes_off_note"),
            "marker, explore: off on this vehicle (markers.enabled: false in its config; fly "
            "with --config config/markers.yaml)")
      << json;
  ASSERT_TRUE(fs::exists(shot));
  EXPECT_GT(fs::file_size(shot), 20'000U);  // a PNG of a 1600x960 console, not a blank
  fmt::print("console screenshot: {}, {:.1f} fps\n", shot.c_str(),
             state_number(parse_state(json), "/window/fps"));
  expect_report_written(dir, recording);
  expect_truncated_csv_replay(dir, recording);
}

TEST(ConsoleProcesses, TakeOffKeyThenVehicleKilledShowsAirborneHeightAndLinkLossBanner) {
  if (!fs::exists(kXvfb)) GTEST_SKIP() << kXvfb << " not installed (apt-get install xvfb)";
  use_loopback_dds();
  const std::string domain = std::to_string(hq::testing::private_domain_id(57));
  const fs::path dir = fresh_artefact_dir("console_takeoff_test");
  // GIVEN a 1280x720 display, the simulated vehicle on the floor and the console flown from
  // the keyboard
  const XvfbDisplay display(dir, "1280x720x24", 90);
  Keyboard keys;
  if (!keys.usable()) GTEST_SKIP() << "no XTest (libXtst.so.6) on this display";
  Process onboard({HQ_SIM_FLIGHT_EXE, "--link", "--world", "onboard/sim/worlds/arena.yaml",
                   "--duration-s", "60", "--domain-id", domain, "--insecure"},
                  dir / "onboard.out");
  const fs::path shot = dir / "link_lost.png";
  const fs::path state = dir / "state.json";
  const fs::path recording = dir / "recording";
  Process ground({HQ_GROUND_EXE, "--device", "keyboard", "--domain-id", domain, "--insecure",
                  "--duration-s", "60", "--record", recording.string(), "--screenshot",
                  shot.string(), "--state-json", state.string()},
                 dir / "ground.out");
  ASSERT_TRUE(keys.focus("hq-ground", 10.0)) << slurp(dir / "ground.out");
  // WHEN the operator presses U once the vehicle is up, flies forward a little with W, ...
  // (pressed twice: a request sent before the vehicle's reader matched would be lost, and a
  // second take-off request while climbing or at the height changes nothing)
  std::this_thread::sleep_for(std::chrono::seconds(3));
  keys.tap(XK_u);
  std::this_thread::sleep_for(std::chrono::seconds(2));
  keys.tap(XK_u);
  std::this_thread::sleep_for(std::chrono::seconds(5));
  keys.press(XK_w);
  std::this_thread::sleep_for(std::chrono::milliseconds(800));
  keys.release(XK_w);
  std::this_thread::sleep_for(std::chrono::seconds(1));
  // ... and the vehicle dies (kill -9: no last word on the link)
  onboard.signal(SIGKILL);
  // ... and the operator closes the console 3 s later (SIGTERM: the exit path, JSON and
  // screenshot included)
  std::this_thread::sleep_for(std::chrono::seconds(3));
  ground.signal(SIGTERM);
  ASSERT_EQ(ground.wait_exit(30.0), 0) << slurp(dir / "ground.out");
  onboard.wait_exit(5.0);

  const std::string json = slurp(state);
  const std::string out = slurp(dir / "ground.out");
  ASSERT_FALSE(json.empty()) << out;
  const nlohmann::json parsed = parse_state(json);
  // THEN the console showed the take-off: the last state before the loss says airborne, motors
  // on, at the take-off height (1.0 m in config/onboard.yaml) within 0.15 m, from a source named
  EXPECT_EQ(state_text(parsed, "/flight_state"), "airborne") << json;
  EXPECT_EQ(state_flag(parsed, "/motors_armed"), 1) << json;
  EXPECT_EQ(state_flag(parsed, "/height_valid"), 1) << json;
  EXPECT_NEAR(state_number(parsed, "/height_m"), 1.0, 0.15) << json;
  EXPECT_NE(state_text(parsed, "/height_source"), "-") << json;
  // and the loss: the banner drawn, the state stale for more than 2 s, one loss counted, said
  // on stdout and recorded as an event for the replay
  EXPECT_EQ(state_flag(parsed, "/link_lost"), 1) << json;
  EXPECT_GT(state_number(parsed, "/stale_s"), 2.0) << json;
  EXPECT_EQ(state_number(parsed, "/link_losses"), 1) << json;
  EXPECT_GT(state_number(parsed, "/window/link_lost_banner_frames"), 3) << json;
  EXPECT_NE(out.find("VEHICLE LINK LOST"), std::string::npos) << out;
  EXPECT_NE(slurp(recording / "events.csv").find("VEHICLE LINK LOST"), std::string::npos);
  ASSERT_TRUE(fs::exists(shot));
  EXPECT_GT(fs::file_size(shot), 20'000U);
  // and the window fits the 1280x720 display, inside it
  ASSERT_TRUE(parsed.contains("window") && parsed["window"].is_object()) << json;
  EXPECT_GE(state_number(parsed, "/window/x_px"), 0) << json;
  EXPECT_GE(state_number(parsed, "/window/y_px"), 0) << json;
  EXPECT_LE(state_number(parsed, "/window/x_px") + state_number(parsed, "/window/width_px"), 1280)
      << json;
  EXPECT_LE(state_number(parsed, "/window/y_px") + state_number(parsed, "/window/height_px"), 720)
      << json;
  EXPECT_GT(state_number(parsed, "/window/take_off_hint_frames"), 0) << json;
  // and its placement is remembered for the next run, in XDG_CONFIG_HOME (here the test's)
  EXPECT_EQ(slurp(dir / "config" / "haptiquad" / "console.ini"),
            "window " + std::to_string(static_cast<int>(state_number(parsed, "/window/x_px"))) +
                " " + std::to_string(static_cast<int>(state_number(parsed, "/window/y_px"))) + " " +
                std::to_string(static_cast<int>(state_number(parsed, "/window/width_px"))) + " " +
                std::to_string(static_cast<int>(state_number(parsed, "/window/height_px"))) + "\n");
  fmt::print("console take-off: height {:.2f} m ({}), stale {:.1f} s, {:.1f} fps; screenshot {}\n",
             state_number(parsed, "/height_m"), state_text(parsed, "/height_source").c_str(),
             state_number(parsed, "/stale_s"), state_number(parsed, "/window/fps"), shot.string());
}

TEST(ConsoleProcesses, VehicleStoppedMidFlightSaysGoodbyeThenARestartStartsAfresh) {
  if (!fs::exists(kXvfb)) GTEST_SKIP() << kXvfb << " not installed (apt-get install xvfb)";
  use_loopback_dds();
  const std::string domain = std::to_string(hq::testing::private_domain_id(83));
  const fs::path dir = fresh_artefact_dir("console_goodbye_test");
  const XvfbDisplay display(dir, "1280x800x24", 90);
  // GIVEN a simulated vehicle with no run length (it flies until stopped) and the console with
  // the scripted hand, which takes off at 1 s and climbs until 4 s
  const std::vector<std::string> vehicle = {
      HQ_SIM_FLIGHT_EXE, "--link", "--world",   "onboard/sim/worlds/arena.yaml",
      "--domain-id",     domain,   "--insecure"};
  auto first = std::make_unique<Process>(vehicle, dir / "onboard1.out");
  const fs::path state = dir / "state.json";
  const fs::path recording = dir / "recording";
  Process ground(
      {HQ_GROUND_EXE, "--device", "sim", "--haptics-config", "ground/config/demo_hand.yaml",
       "--domain-id", domain, "--insecure", "--duration-s", "120", "--record", recording.string(),
       "--screenshot", (dir / "console.png").string(), "--state-json", state.string()},
      dir / "ground.out");
  // WHEN it is stopped by SIGTERM mid-flight (7 s in: airborne, flying forward)
  std::this_thread::sleep_for(std::chrono::seconds(7));
  first->signal(SIGTERM);
  ASSERT_EQ(first->wait_exit(40.0), 0) << slurp(dir / "onboard1.out");
  // THEN it landed and said goodbye, acknowledged by the console
  const std::string out1 = slurp(dir / "onboard1.out");
  EXPECT_NE(out1.find("vehicle stopping: landing"), std::string::npos) << out1;
  EXPECT_NE(out1.find("vehicle ended: stopped by SIGTERM; landed (goodbye acknowledged"),
            std::string::npos)
      << out1;
  // ... and the console, 3 s into the silence, raised no link loss: a calm "vehicle ended".
  std::this_thread::sleep_for(std::chrono::seconds(3));
  // WHEN a new vehicle process (a new session), this one with its marker stage on, starts and
  // flies a few seconds
  std::vector<std::string> with_markers = vehicle;
  with_markers.insert(with_markers.end(), {"--config", "config/markers.yaml"});
  auto second = std::make_unique<Process>(with_markers, dir / "onboard2.out");
  std::this_thread::sleep_for(std::chrono::seconds(6));
  ground.signal(SIGTERM);
  ASSERT_EQ(ground.wait_exit(30.0), 0) << slurp(dir / "ground.out");
  second->signal(SIGTERM);
  EXPECT_EQ(second->wait_exit(40.0), 0) << slurp(dir / "onboard2.out");

  const std::string json = slurp(state);
  const std::string ground_out = slurp(dir / "ground.out");
  ASSERT_FALSE(json.empty()) << ground_out;
  const nlohmann::json parsed = parse_state(json);
  // THEN the goodbye was shown as its own banner, and never as a link loss
  EXPECT_EQ(state_number(parsed, "/link_losses"), 0) << json;
  EXPECT_EQ(state_number(parsed, "/window/link_lost_banner_frames"), 0) << json;
  EXPECT_GT(state_number(parsed, "/window/vehicle_ended_banner_frames"), 3) << json;
  EXPECT_EQ(ground_out.find("VEHICLE LINK LOST"), std::string::npos) << ground_out;
  const std::string events = slurp(recording / "events.csv");
  EXPECT_NE(events.find("vehicle ended: stopped by SIGTERM; landed"), std::string::npos) << events;
  // ... and the new session replaced the ended one at once: its own track from W's origin,
  // the old one kept greyed, its own plots, the banner gone with the new session
  EXPECT_EQ(state_number(parsed, "/sessions"), 2) << json;
  EXPECT_EQ(state_flag(parsed, "/vehicle_ended"), 0) << json;
  EXPECT_GT(state_number(parsed, "/previous_track_points"), 100) << json;
  EXPECT_GT(state_number(parsed, "/track_points"), 10) << json;
  // 6 s of the new session at ~30 states/s: its plot holds no more than that
  EXPECT_LT(state_number(parsed, "/plot_samples"), 8 * 40) << json;
  EXPECT_GT(state_number(parsed, "/plot_samples"), 30) << json;
  // ... and the new vehicle offers marker and explore (config/markers.yaml): their buttons
  // are on, with no note, where the first vehicle's had them greyed
  EXPECT_EQ(state_flag(parsed, "/window/marker_button_enabled"), 1) << json;
  EXPECT_EQ(state_flag(parsed, "/window/explore_button_enabled"), 1) << json;
  EXPECT_EQ(state_text(parsed, "/window/modes_off_note"), "") << json;
  fmt::print(
      "goodbye: {:g} vehicle-ended banner frames, {:g} link losses; after the restart {:g} plot "
      "samples, {:g} previous track points\n",
      state_number(parsed, "/window/vehicle_ended_banner_frames"),
      state_number(parsed, "/link_losses"), state_number(parsed, "/plot_samples"),
      state_number(parsed, "/previous_track_points"));
}

TEST(ConsoleProcesses, WindowedGroundWithoutADisplaySaysUseHeadlessAndExits2) {
  const fs::path dir = fs::path(HQ_CONSOLE_ARTEFACT_DIR) / "console_no_display_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  unsetenv("DISPLAY");
  unsetenv("WAYLAND_DISPLAY");
  unsetenv("SDL_VIDEODRIVER");
  const auto start = std::chrono::steady_clock::now();
  Process ground({HQ_GROUND_EXE, "--device", "keyboard", "--duration-s", "5"}, dir / "ground.out");
  EXPECT_EQ(ground.wait_exit(10.0), 2);
  const double took_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const std::string out = slurp(dir / "ground.out");
  EXPECT_NE(out.find("no display (DISPLAY unset): use --headless"), std::string::npos) << out;
  EXPECT_LT(took_s, 2.0) << "said at once, not after waiting for a window";
}

}  // namespace
