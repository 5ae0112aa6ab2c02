// What the operator sees, checked by content on the console's screenshot and state under a
// private Xvfb: the whole camera image in its panel and every panel's last line (force bars,
// status bar, link figures) at 1280x800 and at 1024x640, the climb up positive, the flight
// timer, and the link-loss alarm played (SDL's dummy audio driver stands for a sound card, as
// on CI).
#include "hq/testing/loopback_dds.hpp"
#include "hq/testing/process.hpp"

#include "console_fixture.hpp"
#include "state_json.hpp"
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <memory>
#include <signal.h>
#include <sstream>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
using hq::console_test::fresh_artefact_dir;
using hq::console_test::kXvfb;
using hq::console_test::parse_state;
using hq::console_test::slurp;
using hq::console_test::state_flag;
using hq::console_test::state_number;
using hq::console_test::state_text;
using hq::console_test::XvfbDisplay;
using hq::testing::Process;

// The last camera frame of a recording (TUM rgb.txt: "timestamp rgb/NAME.jpg" lines).
cv::Mat last_recorded_frame(const fs::path& recording) {
  std::ifstream list(recording / "rgb.txt");
  std::string line;
  std::string last;
  while (std::getline(list, line)) {
    if (!line.empty() && line[0] != '#') last = line;
  }
  const std::size_t space = last.find(' ');
  if (space == std::string::npos) return {};
  return cv::imread((recording / last.substr(space + 1)).string(), cv::IMREAD_COLOR);
}

// Mean colour of a square patch.
cv::Scalar patch_mean(const cv::Mat& image, int x, int y, int size) {
  return cv::mean(image(cv::Rect(x, y, size, size)));
}

double colour_distance(const cv::Scalar& a, const cv::Scalar& b) {
  return std::max({std::abs(a[0] - b[0]), std::abs(a[1] - b[1]), std::abs(a[2] - b[2])});
}

// Every panel's content whole in the console's state (the force bars, Fz last; the status
// bar's columns and lines; the controls' and link panel's last lines; the camera image), and
// the screenshot showing the recorded frame's own bottom corners and middle-row ends where the
// console says it drew it (the top may be under a banner): a cropped or shifted image puts
// other parts of the scene there.
void expect_every_panel_whole(const std::string& json, const nlohmann::json& parsed,
                              const fs::path& shot, const fs::path& recording, int min_width_px,
                              int min_height_px) {
  EXPECT_EQ(state_flag(parsed, "/window/force_bars_whole"), 1) << json;
  EXPECT_EQ(state_flag(parsed, "/window/status_bar_whole"), 1) << json;
  EXPECT_EQ(state_flag(parsed, "/window/control_panel_whole"), 1) << json;
  EXPECT_EQ(state_flag(parsed, "/window/link_panel_whole"), 1) << json;
  EXPECT_EQ(state_flag(parsed, "/window/camera_image_whole"), 1) << json;
  const int x = static_cast<int>(state_number(parsed, "/window/camera_shown_x_px"));
  const int y = static_cast<int>(state_number(parsed, "/window/camera_shown_y_px"));
  const int w = static_cast<int>(state_number(parsed, "/window/camera_shown_width_px"));
  const int h = static_cast<int>(state_number(parsed, "/window/camera_shown_height_px"));
  ASSERT_GT(w, min_width_px) << json;
  ASSERT_GT(h, min_height_px) << json;
  // kept its aspect
  EXPECT_NEAR(static_cast<double>(w) / h,
              state_number(parsed, "/window/camera_width_px") /
                  state_number(parsed, "/window/camera_height_px"),
              0.02)
      << json;
  const cv::Mat screen = cv::imread(shot.string(), cv::IMREAD_COLOR);
  const cv::Mat frame = last_recorded_frame(recording);
  ASSERT_FALSE(screen.empty()) << shot;
  ASSERT_FALSE(frame.empty()) << recording / "rgb.txt";
  ASSERT_LE(x + w, screen.cols);
  ASSERT_LE(y + h, screen.rows);
  cv::Mat scaled;
  cv::resize(frame, scaled, cv::Size(w, h), 0, 0, cv::INTER_AREA);
  const cv::Mat shown = screen(cv::Rect(x, y, w, h));
  constexpr int kPatch = 10;
  const std::vector<cv::Point> corners = {{1, h - kPatch - 1},
                                          {w - kPatch - 1, h - kPatch - 1},
                                          {1, h / 2 - kPatch / 2},
                                          {w - kPatch - 1, h / 2 - kPatch / 2}};
  for (const cv::Point& c : corners) {
    const double d =
        colour_distance(patch_mean(shown, c.x, c.y, kPatch), patch_mean(scaled, c.x, c.y, kPatch));
    EXPECT_LT(d, 25.0) << "patch at " << c.x << "," << c.y << " of the shown image";
  }
  // (the same patches a third of the image away differ: the check can tell places apart)
  const double elsewhere = colour_distance(patch_mean(shown, 1, h - kPatch - 1, kPatch),
                                           patch_mean(scaled, w / 3, h / 3, kPatch));
  fmt::print(
      "console layout {}x{}: image {}x{} at {},{}; corner vs elsewhere {:.0f}; {:.1f} fps; {}\n",
      screen.cols, screen.rows, w, h, x, y, elsewhere, state_number(parsed, "/window/fps"),
      shot.string());
}

TEST(ConsoleLayout, At1280x800WholeCameraForceBarsClimbUpAndLinkLossAlarmSounds) {
  if (!fs::exists(kXvfb)) GTEST_SKIP() << kXvfb << " not installed (apt-get install xvfb)";
  hq::testing::use_loopback_dds();
  const std::string domain = std::to_string(hq::testing::private_domain_id(83));
  const fs::path dir = fresh_artefact_dir("console_layout_test");
  // SDL's dummy audio driver consumes the tone in real time, as a sound card would.
  setenv("SDL_AUDIODRIVER", "dummy", 1);
  // GIVEN a 1280x800 display, a simulated vehicle and the console flown by the scripted hand
  // (take off, climb for 2 s, forward, ...)
  const XvfbDisplay display(dir, "1280x800x24", 140);
  Process onboard({HQ_SIM_FLIGHT_EXE, "--link", "--world", "onboard/sim/worlds/arena.yaml",
                   "--duration-s", "60", "--domain-id", domain, "--insecure"},
                  dir / "onboard.out");
  const fs::path shot = dir / "console.png";
  const fs::path state = dir / "state.json";
  const fs::path recording = dir / "recording";
  Process ground({HQ_GROUND_EXE,
                  "--device",
                  "sim",
                  "--haptics-config",
                  "ground/config/demo_hand.yaml",
                  "--domain-id",
                  domain,
                  "--insecure",
                  "--duration-s",
                  "60",
                  "--window-size",
                  "1280x800",
                  "--window-ini",
                  "none",
                  "--record",
                  recording.string(),
                  "--screenshot",
                  shot.string(),
                  "--state-json",
                  state.string()},
                 dir / "ground.out");
  // WHEN the vehicle dies in flight (kill -9: no last word) and the operator closes the
  // console 3 s later
  std::this_thread::sleep_for(std::chrono::seconds(10));
  onboard.signal(SIGKILL);
  std::this_thread::sleep_for(std::chrono::seconds(3));
  ground.signal(SIGTERM);
  ASSERT_EQ(ground.wait_exit(30.0), 0) << slurp(dir / "ground.out");
  onboard.wait_exit(5.0);
  unsetenv("SDL_AUDIODRIVER");

  const std::string json = slurp(state);
  ASSERT_FALSE(json.empty()) << slurp(dir / "ground.out");
  const nlohmann::json parsed = parse_state(json);
  // THEN the link-loss alarm sounded: its cause, the dummy device, and more than a second of
  // tone in the ~2.5 s of the loss
  EXPECT_EQ(state_text(parsed, "/window/alarm_cause"), "link lost") << json;
  EXPECT_EQ(state_text(parsed, "/window/alarm_audio"), "dummy") << json;
  EXPECT_EQ(state_flag(parsed, "/window/alarm_muted"), 0) << json;
  EXPECT_GT(state_number(parsed, "/window/alarm_tone_samples"), 48000 * 1.0) << json;
  EXPECT_GT(state_number(parsed, "/window/alarm_frames"), 10) << json;
  // and the flight's figures: the climb up positive (the hand climbed for 2 s), the flight
  // timer running from the take-off
  EXPECT_GT(state_number(parsed, "/window/climb_shown_max_mps"), 0.15) << json;
  EXPECT_GT(state_number(parsed, "/flight_time_s"), 4.0) << json;
  EXPECT_LT(state_number(parsed, "/flight_time_s"), 12.0) << json;
  // and every panel whole at 1280x800, the camera showing the recorded frame
  expect_every_panel_whole(json, parsed, shot, recording, 200, 150);
}

TEST(ConsoleLayout, At1024x640EveryPanelWhole) {
  if (!fs::exists(kXvfb)) GTEST_SKIP() << kXvfb << " not installed (apt-get install xvfb)";
  hq::testing::use_loopback_dds();
  const std::string domain = std::to_string(hq::testing::private_domain_id(84));
  const fs::path dir = fresh_artefact_dir("console_layout_1024_test");
  // GIVEN the smallest display the console is made for, a simulated vehicle (the shipped
  // config: the note under the greyed marker and explore buttons is drawn too) and the console
  // flown by the scripted hand
  const XvfbDisplay display(dir, "1024x640x24", 140);
  Process onboard({HQ_SIM_FLIGHT_EXE, "--link", "--world", "onboard/sim/worlds/arena.yaml",
                   "--duration-s", "30", "--domain-id", domain, "--insecure"},
                  dir / "onboard.out");
  const fs::path shot = dir / "console.png";
  const fs::path state = dir / "state.json";
  const fs::path recording = dir / "recording";
  Process ground({HQ_GROUND_EXE,
                  "--device",
                  "sim",
                  "--haptics-config",
                  "ground/config/demo_hand.yaml",
                  "--domain-id",
                  domain,
                  "--insecure",
                  "--duration-s",
                  "8",
                  "--window-size",
                  "1024x640",
                  "--window-ini",
                  "none",
                  "--record",
                  recording.string(),
                  "--screenshot",
                  shot.string(),
                  "--state-json",
                  state.string()},
                 dir / "ground.out");
  ASSERT_EQ(ground.wait_exit(30.0), 0) << slurp(dir / "ground.out");
  onboard.signal(SIGTERM);
  onboard.wait_exit(40.0);
  const std::string json = slurp(state);
  ASSERT_FALSE(json.empty()) << slurp(dir / "ground.out");
  const nlohmann::json parsed = parse_state(json);
  // THEN at 1024x640 too every panel's content is whole and the camera shows the frame
  EXPECT_EQ(state_number(parsed, "/window/width_px"), 1024) << json;
  EXPECT_EQ(state_number(parsed, "/window/height_px"), 640) << json;
  EXPECT_NE(state_text(parsed, "/window/modes_off_note"), "") << json;
  // (the camera gets what the controls and link figures leave: 120x90 here, still enough for
  // the content check's 10 px patches a third of the image apart)
  expect_every_panel_whole(json, parsed, shot, recording, 100, 75);
}

}  // namespace
