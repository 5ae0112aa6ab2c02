// hq-ground: the operator's station. Runs the 1 kHz haptic loop on a device, publishes its
// velocity command (eq. 6-10) and heartbeats over DDS, feeds the force feedback with the vehicle
// state it receives, toggles modes from the device's buttons (button 0: teleop <-> hover,
// button 1: land) and shows link and vehicle status in the operator console (a Dear ImGui
// window; --headless: status lines in the terminal). --replay plays a recording back into the
// console instead of flying.
//   hq-ground --device sim|keyboard|joystick|forcedim [--headless] [--duration-s N]
//             [--haptics-config config/haptics.yaml] [--vehicle calib/vehicle_core_paper.yaml]
//             [--link-config F] [--domain-id N] [--vehicle-id N] [--station-id N]
//             [--station-strength N] [--command-rate-hz 50] [--record DIR]
//             [--screenshot PNG] [--state-json PATH] [--max-fps 60]
//             [--marker-task hold|goto|land --marker-id N]  (marker mode on that tag)
//   hq-ground --replay DIR [--speed X] [--seek S] [--paused] [--headless] [--duration-s N]
//             [--screenshot PNG] [--state-json PATH] [--keys "T:KEY,..."]
//             (replay window: Space play/pause, [ ] speed, Left/Right -/+5 s, click the bar)
// Exit status: 0 a good run, 2 bad input, 3 a secured run that never heard from its vehicle
// (keys that fail the handshake), 5 a flight whose --record failed on the way (disk full; the
// flight went on without it).
#include "hq/base/error.hpp"
#include "hq/base/log.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/console/console_model.hpp"
#include "hq/console/console_window.hpp"
#include "hq/console/recording.hpp"
#include "hq/console/replay_player.hpp"
#include "hq/console/state_feed.hpp"
#include "hq/geometry/camera_mount.hpp"
#include "hq/ground/ground_station.hpp"
#include "hq/ground/operator_station.hpp"
#include "hq/ground/window_keyboard.hpp"
#include "hq/haptics/haptic_device.hpp"
#include "hq/haptics/haptic_loop.hpp"
#include "hq/haptics/haptics_config.hpp"
#include "hq/link/config.hpp"
#include "hq/link/link.hpp"
#include "hq/mcap_recorder/flight_recorder.hpp"
#include "hq/security/keys.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fmt/format.h>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <thread>
#include <unistd.h>
#include <utility>

namespace {

std::atomic<bool> g_stop{false};
void request_stop(int /*signal*/) { g_stop = true; }

struct Options {
  std::string device = "sim";
  bool headless = false;
  double duration_s = 0.0;
  std::string haptics_path = "config/haptics.yaml";
  std::string vehicle_path = "calib/vehicle_core_paper.yaml";
  std::string link_config_path;
  hq::link::LinkOverrides link_overrides;
  double command_rate_hz = 50.0;
  std::string record_dir;
  std::string replay_dir;
  double speed = 1.0;
  double seek_s = 0.0;  ///< Replay: start here (s from the recording's start).
  bool paused = false;  ///< Replay: start paused.
  std::string keys;     ///< "T:KEY,...": keys typed into the window T s after it opens.
  std::string screenshot_path;
  std::string state_json_path;
  double max_fps = 60.0;
  std::string marker_task;  ///< "hold", "goto", "land"; empty: no marker request.
  int marker_id = 0;
  bool take_off = false;  ///< Ask the vehicle to take off (then teleop) once it is heard from.
  double link_lost_after_s = 0.5;  ///< Link-loss alarm: no vehicle state for longer.
  std::string window_size;         ///< "WxH"; empty: from the display.
  std::string window_ini;          ///< Window size/position file; empty: the default, "none": off.
  bool bare_window = false;  ///< Measurement: an empty window, the console's frame-rate floor.
};

// The console needs a display; without one SDL fails after a long X connection timeout or
// waits, so say it at once (exit 2), before the link is up.
void require_display(const char* what) {
  const char* display = std::getenv("DISPLAY");
  const char* wayland = std::getenv("WAYLAND_DISPLAY");
  const char* driver = std::getenv("SDL_VIDEODRIVER");
  const auto set = [](const char* v) { return v != nullptr && v[0] != '\0'; };
  if (!set(display) && !set(wayland) && !set(driver)) {
    throw hq::InputError(std::string("no display (DISPLAY unset): use --headless (") + what +
                         " opens the console window)");
  }
}

int mode_of(const char* name) {
  static constexpr std::array<std::pair<const char*, int>, 5> kModes = {
      {{"teleop", hq_msgs_MODE_TELEOP},
       {"hover", hq_msgs_MODE_HOVER},
       {"land", hq_msgs_MODE_LAND},
       {"marker", hq_msgs_MODE_MARKER},
       {"explore", hq_msgs_MODE_EXPLORE}}};
  for (const auto& [text, mode] : kModes) {
    if (std::string_view(name) == text) return mode;
  }
  return -1;
}

// The link's view of the selected vehicle, into the console's model (on the flying thread).
class ModelFeed : public hq::ground::LinkObserver {
 public:
  ModelFeed(hq::console::ConsoleModel& model, const hq::ground::GroundStation& ground)
      : model_(model), ground_(ground) {}
  void on_state(std::int64_t receipt_ns, std::int64_t latency_ns,
                const hq::link::VehicleState& s) override {
    // The replay's path too (state_feed.hpp): a replayed frame derives what this one does.
    const hq::ground::LinkStatus& link = ground_.status();
    hq::console::LinkFigures figures;
    figures.state_age_ms = static_cast<float>(
        1e-6 * static_cast<double>(std::max<std::int64_t>(link.last_state_age_ns, 0)));
    figures.round_trip_ms = static_cast<float>(
        1e-6 * static_cast<double>(std::max<std::int64_t>(link.round_trip_ns, 0)));
    feed_.on_state(model_, receipt_ns, 1e-6 * static_cast<double>(latency_ns), s, figures);
  }
  void on_camera(std::int64_t receipt_ns, const hq::link::CameraFrame& f) override {
    // The exposure on our clock through the heartbeat clock offset (video latency).
    const hq::ground::LinkStatus& link = ground_.status();
    const std::int64_t now_ns = hq::haptics::monotonic_now_ns();
    const std::int64_t exposure_ns = link.have_clock_offset ? f.t_ns - link.clock_offset_ns : -1;
    model_.on_camera(receipt_ns, f.rgb_jpeg._buffer, f.rgb_jpeg._length, f.depth_preview._buffer,
                     f.depth_preview._length, exposure_ns, now_ns);
  }
  void on_event(std::int64_t receipt_ns, const hq::link::Event& e) override {
    model_.on_event(receipt_ns, static_cast<int>(e.severity), e.text);
    // The station's notice of a new session comes before that session's first state: the
    // top view and the plots start afresh for it (as a replay does).
    if (e.code == hq::ground::kGroundEventVehicleRestarted) model_.start_new_track();
  }

 private:
  hq::console::ConsoleModel& model_;
  const hq::ground::GroundStation& ground_;
  hq::console::LiveStateFeed feed_;
};

// A figure with the decimals the state JSON has always shown (printf's %.3f before it was
// written with nlohmann), still a JSON number: readers parse it, they need not see the noise of
// a double's last digits. NaN and infinity stay so and are written as null (JSON has neither).
double decimals(double v, int places) {
  const double scale = std::pow(10.0, places);
  return std::round(v * scale) / scale;
}

// The window's figures in the state JSON (null without a window: --headless).
nlohmann::ordered_json window_json(const hq::console::WindowStats* window) {
  if (window == nullptr) return nullptr;
  const hq::console::WindowStats& w = *window;
  return {{"frames", w.frames},
          {"fps", decimals(w.fps, 2)},
          {"render_ms_p50", decimals(w.render_ms_p50, 3)},
          {"render_ms_max", decimals(w.render_ms_max, 3)},
          {"camera_frames_decoded", w.camera_frames_decoded},
          {"camera_decode_failures", w.camera_decode_failures},
          {"camera_width_px", w.camera_width_px},
          {"camera_height_px", w.camera_height_px},
          {"plot_samples_drawn", w.plot_samples_drawn},
          {"mode_shown", w.mode_shown},
          {"gl_renderer", w.gl_renderer},
          {"video_p50_ms", decimals(w.video_p50_ms, 1)},
          {"video_p99_ms", decimals(w.video_p99_ms, 1)},
          {"video_link_p50_ms", decimals(w.video_link_p50_ms, 1)},
          {"video_decode_p50_ms", decimals(w.video_decode_p50_ms, 1)},
          {"video_display_p50_ms", decimals(w.video_display_p50_ms, 1)},
          {"x_px", w.x_px},
          {"y_px", w.y_px},
          {"width_px", w.width_px},
          {"height_px", w.height_px},
          {"display_width_px", w.display_width_px},
          {"display_height_px", w.display_height_px},
          {"link_lost_banner_frames", w.link_lost_banner_frames},
          {"vehicle_ended_banner_frames", w.vehicle_ended_banner_frames},
          {"take_off_hint_frames", w.take_off_hint_frames},
          {"camera_shown_x_px", w.camera_shown_x_px},
          {"camera_shown_y_px", w.camera_shown_y_px},
          {"camera_shown_width_px", w.camera_shown_width_px},
          {"camera_shown_height_px", w.camera_shown_height_px},
          {"camera_image_whole", w.camera_image_whole},
          {"force_bars_whole", w.force_bars_whole},
          {"status_bar_whole", w.status_bar_whole},
          {"control_panel_whole", w.control_panel_whole},
          {"link_panel_whole", w.link_panel_whole},
          {"marker_button_enabled", w.marker_button_enabled},
          {"explore_button_enabled", w.explore_button_enabled},
          {"modes_off_note", w.modes_off_note},
          {"climb_shown_max_mps", decimals(w.climb_shown_max_mps, 3)},
          {"climb_shown_min_mps", decimals(w.climb_shown_min_mps, 3)},
          {"alarm_cause", w.alarm_cause},
          {"alarm_muted", w.alarm_muted},
          {"alarm_audio", w.alarm_audio},
          {"alarm_tone_samples", w.alarm_tone_samples},
          {"alarm_frames", w.alarm_frames}};
}

// Ownership and the checks on what the vehicle sends, in the state JSON.
void add_ownership_json(nlohmann::ordered_json& j, const hq::console::LinkHealth& link) {
  j["control_lost"] = link.control_lost;
  j["commanding_station_id"] = link.commanding_station;
  j["own_station_id"] = link.own_station;
  j["intrusion_reports"] = link.intrusion_reports;
  j["last_intrusion"] = link.last_intrusion.data();
  j["vehicle_session"] = fmt::format("{:016x}", link.vehicle_session);
  j["waiting_for_vehicle"] = link.waiting_for_vehicle;
  j["states_rejected"] = link.states_rejected;
  j["states_implausible"] = link.states_implausible;
  j["states_wrong_session"] = link.states_wrong_session;
  j["events_rejected"] = link.events_rejected;
}

// The console's own state at exit, for tests and scripts (--state-json). Keys in this order,
// one top-level key a line (tests that only search the text rely on `"key": value`).
void write_state_json(const std::string& path, const hq::console::Snapshot& s,
                      const hq::console::WindowStats* window, std::uint64_t replay_problems,
                      std::uint64_t replay_frames_missing, double max_force_n = -1.0,
                      double min_passivity_energy_j = 0.0) {
  nlohmann::ordered_json j;
  j["source"] = s.source.data();
  j["have_state"] = s.have_state;
  j["mode"] = s.mode;
  j["states_received"] = s.link.states;
  j["camera_frames_received"] = s.link.camera_frames;
  j["plot_samples"] = s.plot_count;
  j["plot_samples_total"] = s.plot_total;
  j["track_points"] = s.track_count;
  j["events"] = s.event_count;
  j["position_W_m"] = {decimals(s.position_W.x_W_m, 3), decimals(s.position_W.y_W_m, 3)};
  j["position_from_vehicle"] = s.position_from_vehicle;
  j["position_states"] = s.position_states;
  j["truth"] = s.have_truth;
  j["markers_latest"] = s.marker_count;
  j["marker_detections"] = s.marker_detections;
  j["flight_state"] = s.flight_state;
  j["flight_time_s"] = decimals(s.flight_time_s, 2);
  j["marker_target_id"] = s.marker_target_id;
  j["explore_phase"] = s.explore_phase;
  j["motors_armed"] = s.motors_armed;
  j["height_valid"] = s.height_valid;
  j["height_m"] = decimals(s.height_m, 3);
  j["height_source"] = s.height_source;
  j["operator_input"] = s.operator_input;
  j["clearance_m"] = decimals(s.clearance_m, 3);
  j["obstacle_points"] = s.cloud_count;  // the cloud standing in the top view
  j["yaw_W_rad"] = decimals(s.yaw_W_rad, 3);
  j["hover_thrust_gain"] = decimals(s.hover_thrust_gain, 3);
  j["link_lost"] = s.link.link_lost;
  j["vehicle_ended"] = s.link.vehicle_ended;
  j["vehicle_ended_text"] = s.link.vehicle_ended_text.data();
  j["sessions"] = s.sessions;
  j["previous_track_points"] = s.previous_track_count;
  j["stale_s"] = decimals(s.link.state_age_s, 3);
  j["link_losses"] = s.link.link_losses;
  j["longest_link_loss_s"] = decimals(s.link.longest_loss_s, 3);
  j["vehicle_ids"] = std::span(s.link.vehicle_ids.data(), s.link.vehicle_id_count);
  j["latency_p50_ms"] = decimals(s.link.latency_p50_ms, 3);
  j["state_rate_hz"] = decimals(s.link.state_rate_hz, 2);
  j["camera_rate_hz"] = decimals(s.link.camera_rate_hz, 2);
  j["link_events"] = s.link.events;
  if (s.replay.active) {
    j["replay"] = {{"position_s", decimals(s.replay.position_s, 3)},
                   {"duration_s", decimals(s.replay.duration_s, 3)},
                   {"speed", decimals(s.replay.speed, 2)},
                   {"playing", s.replay.playing},
                   {"at_end", s.replay.at_end},
                   {"sessions", s.replay.sessions}};
  }
  add_ownership_json(j, s.link);
  if (max_force_n >= 0.0) {
    j["max_force_n"] = decimals(max_force_n, 4);
    j["passivity_min_energy_j"] = decimals(min_passivity_energy_j, 5);
  }
  j["replay_problems"] = replay_problems;
  j["replay_frames_missing"] = replay_frames_missing;
  j["window"] = window_json(window);

  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) throw hq::InputError(path + ": cannot open for writing (--state-json)");
  // Texts from the link (mode, events) are not trusted to be UTF-8: replaced, never thrown on.
  fmt::print(f, "{}\n", j.dump(2, ' ', false, nlohmann::ordered_json::error_handler_t::replace));
  std::fclose(f);
}

// The console window's options from the command line: size (checked), placement file, and the
// camera mount the top view draws (heading, field of view) from the vehicle file.
hq::console::WindowOptions window_options(const Options& o) {
  hq::console::WindowOptions window_options;
  window_options.max_fps = o.max_fps;
  window_options.bare = o.bare_window;
  if (!o.window_size.empty()) {
    char x = 0;
    char rest = 0;
    if (std::sscanf(o.window_size.c_str(), "%d%c%d%c", &window_options.width_px, &x,
                    &window_options.height_px, &rest) != 3 ||
        x != 'x' || window_options.width_px < 320 || window_options.height_px < 240 ||
        window_options.width_px > 8192 || window_options.height_px > 8192) {
      throw hq::InputError("--window-size " + o.window_size +
                           ": expected WxH in pixels, 320x240 to 8192x8192 (e.g. 1280x800)");
    }
  }
  window_options.ini_path = o.window_ini == "none" ? std::string()
                            : o.window_ini.empty() ? hq::console::default_window_ini_path()
                                                   : o.window_ini;
  const hq::VehicleConfig vehicle = hq::load_vehicle_config(o.vehicle_path);
  window_options.camera_heading_rad = vehicle.camera.heading_rad();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      window_options.R_B_C[static_cast<std::size_t>(3 * r + c)] =
          static_cast<float>(vehicle.camera.R_B_C()(r, c));
    }
    window_options.p_B_C_m[static_cast<std::size_t>(r)] =
        static_cast<float>(vehicle.camera.p_B_C_m()[r]);
  }
  return window_options;
}

// The window's last frame: the screenshot if asked for, and its statistics on stdout.
hq::console::WindowStats close_window(const Options& o, hq::console::ConsoleWindow& window,
                                      hq::console::ConsoleModel& model,
                                      hq::console::Snapshot& snap) {
  model.snapshot(snap);
  if (!o.screenshot_path.empty()) {
    window.save_screenshot(snap, o.screenshot_path);
    hq::log::note("hq-ground: screenshot {}\n", o.screenshot_path.c_str());
  }
  const hq::console::WindowStats st = window.stats();
  hq::log::info("  {:<40} {:.1f} fps over {} frames (render p50 {:.2f} ms, max {:.2f} ms; GL {})\n",
                "console", st.fps, st.frames, st.render_ms_p50, st.render_ms_max, st.gl_renderer);
  return st;
}

// Runs the console window on this (the main) thread until `done`, the duration or a quit;
// returns its statistics. Requests go to `requests` for the flying thread.
hq::console::WindowStats run_window(const Options& o, const std::string& title,
                                    hq::console::ConsoleModel& model,
                                    hq::ground::OperatorRequests& requests,
                                    const std::atomic<bool>& done, hq::console::Snapshot& snap,
                                    hq::console::FlightKeys* flight_keys = nullptr) {
  hq::console::ConsoleWindow window(title, window_options(o));
  window.set_flight_keys(flight_keys);
  const auto start = std::chrono::steady_clock::now();
  auto next_print = start + std::chrono::seconds(1);
  while (!g_stop && !done) {
    model.snapshot(snap);
    const hq::console::UiActions actions = window.frame(snap);
    if (actions.quit) break;
    if (actions.marker_task != nullptr) {
      requests.marker_task =
          hq::ground::marker_task_of(actions.marker_task).value_or(hq_msgs_MARKER_TASK_NONE);
      requests.marker_id = actions.marker_id;
    }
    if (actions.mode_request != nullptr) requests.mode = mode_of(actions.mode_request);
    if (actions.select_vehicle) requests.vehicle = actions.vehicle_id;
    if (actions.take_off) requests.take_off = true;
    const auto now = std::chrono::steady_clock::now();
    if (now >= next_print) {
      const hq::console::WindowStats st = window.stats();
      hq::log::note(
          "hq-ground: console {:.1f} fps (render p50 {:.2f} ms), {} frames decoded, video "
          "exposure->display p50 {:.0f} ms p99 {:.0f} ms (vehicle+link {:.0f}, decode "
          "{:.0f}, display {:.0f})\n",
          st.fps, st.render_ms_p50, st.camera_frames_decoded, st.video_p50_ms, st.video_p99_ms,
          st.video_link_p50_ms, st.video_decode_p50_ms, st.video_display_p50_ms);
      next_print += std::chrono::seconds(1);
    }
    if (o.duration_s > 0 && std::chrono::duration<double>(now - start).count() >= o.duration_s) {
      break;
    }
  }
  return close_window(o, window, model, snap);
}

// "T:KEY,..." of --keys: each key typed T seconds after the window opens, in time order.
std::vector<std::pair<double, std::string>> parse_keys(const std::string& text) {
  std::vector<std::pair<double, std::string>> keys;
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find(',', start);
    if (end == std::string::npos) end = text.size();
    const std::string item = text.substr(start, end - start);
    const std::size_t colon = item.find(':');
    char* number_end = nullptr;
    const double t_s = colon == std::string::npos ? -1 : std::strtod(item.c_str(), &number_end);
    if (colon == std::string::npos || number_end != item.c_str() + colon || !(t_s >= 0) ||
        colon + 1 >= item.size()) {
      throw hq::InputError("--keys '" + text + "': item '" + item +
                           "', expected SECONDS:KEY (e.g. 1.5:Space)");
    }
    keys.emplace_back(t_s, item.substr(colon + 1));
    start = end + 1;
  }
  std::stable_sort(keys.begin(), keys.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  return keys;
}

// The replay's window on this (the main) thread until quit or --duration-s: the timeline
// strip's requests go to `control` for the player's thread.
hq::console::WindowStats run_replay_window(const Options& o, hq::console::ConsoleModel& model,
                                           const hq::console::Timeline& timeline,
                                           hq::console::ReplayControl& control,
                                           hq::console::Snapshot& snap) {
  hq::console::ConsoleWindow window("hq-ground replay " + o.replay_dir, window_options(o));
  window.set_replay(&timeline);
  const std::vector<std::pair<double, std::string>> keys = parse_keys(o.keys);
  std::size_t next_key = 0;
  const std::int64_t start_ns = hq::monotonic_now_ns();
  while (!g_stop) {
    const double elapsed_s = hq::to_seconds(hq::monotonic_now_ns() - start_ns);
    for (; next_key < keys.size() && keys[next_key].first <= elapsed_s; ++next_key) {
      window.queue_key(keys[next_key].second);
    }
    model.snapshot(snap);
    const hq::console::UiActions actions = window.frame(snap);
    if (actions.quit) break;
    if (actions.replay_toggle) control.toggles.fetch_add(1);
    if (actions.replay_speed_step != 0) control.speed_steps.fetch_add(actions.replay_speed_step);
    if (actions.replay_seek_to_s >= 0) control.seek_to_s = actions.replay_seek_to_s;
    if (actions.replay_seek_by_s != 0) control.seek_by_s.fetch_add(actions.replay_seek_by_s);
    if (o.duration_s > 0 && elapsed_s >= o.duration_s) break;
  }
  return close_window(o, window, model, snap);
}

int run_replay(const Options& o) {
  const hq::console::Recording recording = hq::console::load_recording(o.replay_dir);
  hq::log::note("hq-ground: replay {}: {} states, {} commands, {} events, {} frames\n",
                o.replay_dir.c_str(), recording.states.size(), recording.commands.size(),
                recording.events.size(), recording.rgb.size());
  if (recording.problem_count > 0) {
    hq::log::note("hq-ground: replay: {} problem(s) in {}; showing what is readable:\n",
                  recording.problem_count, o.replay_dir.c_str());
    for (const std::string& p : recording.problems) hq::log::note("  {}\n", p.c_str());
  }
  for (const std::string& c : recording.absent_columns) {
    hq::log::note("hq-ground: replay: not in this (older) recording, shown as missing: {}\n",
                  c.c_str());
  }
  hq::console::ConsoleModel model;
  model.set_source("replay " + o.replay_dir);
  hq::console::ReplayPlayer player(recording);
  if (o.seek_s > player.duration_s()) {
    throw hq::InputError("--seek " + std::to_string(o.seek_s) + ": beyond the recording's " +
                         std::to_string(player.duration_s()) + " s");
  }
  for (const hq::console::SessionStart& session : player.timeline().sessions) {
    if (session.first_state > 0) {
      hq::log::note("hq-ground: replay: vehicle restarted at {:.1f} s ({})\n", session.t_s,
                    session.why);
    }
  }
  player.set_speed(o.speed);
  player.seek(o.seek_s);
  if (!o.paused) player.play();
  hq::console::ReplayControl control;
  std::atomic<bool> stop{false};
  std::atomic<bool> at_end{false};
  std::atomic<std::uint64_t> frames_missing{0};
  // The player's thread: reads the frames on show from disk, never the window's.
  std::thread player_thread([&] {
    std::uint64_t missing = 0;
    auto last = std::chrono::steady_clock::now();
    auto next = last;
    while (!stop) {
      control.apply(player);
      const auto now = std::chrono::steady_clock::now();
      player.advance(std::chrono::duration<double>(now - last).count());
      last = now;
      player.feed(model, missing);
      frames_missing = missing;
      at_end = player.at_end();
      next += std::chrono::milliseconds(20);
      std::this_thread::sleep_until(next);
    }
  });
  hq::console::Snapshot snap = model.make_snapshot();
  std::optional<hq::console::WindowStats> window;
  hq::log::info("hq-ground replay summary\n");
  if (o.headless) {
    const std::int64_t start_ns = hq::monotonic_now_ns();
    while (
        !g_stop && !at_end &&
        (o.duration_s <= 0 || hq::to_seconds(hq::monotonic_now_ns() - start_ns) < o.duration_s)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  } else {
    // The window stays open at the end of the recording (shown as such) until closed or
    // --duration-s.
    window = run_replay_window(o, model, player.timeline(), control, snap);
  }
  stop = true;
  player_thread.join();
  model.snapshot(snap);
  char clock[16];
  hq::console::format_clock(snap.replay.position_s, clock, sizeof clock);
  hq::log::info(
      "  {:<40} {} states, {} camera frames ({} missing), {} problems, at {} of {:.1f} s{}\n",
      "replayed", snap.plot_total, snap.link.camera_frames, frames_missing.load(),
      recording.problem_count, clock, snap.replay.duration_s,
      snap.replay.at_end ? " (end of recording)" : "");
  if (!o.state_json_path.empty()) {
    write_state_json(o.state_json_path, snap, window ? &*window : nullptr, recording.problem_count,
                     frames_missing.load());
  }
  return 0;
}

// The command line; an exit status when it is told to stop (--help, a parse error).
std::optional<int> parse_options(int argc, char** argv, Options& o) {
  CLI::App app{"hq-ground: haptic teleoperation of a vehicle over the DDS link"};
  app.add_option("--device", o.device, "haptic device")
      ->check(CLI::IsMember({"sim", "keyboard", "joystick", "forcedim"}));
  app.add_flag("--headless", o.headless, "no live status line: one status line per second");
  app.add_option("--duration-s", o.duration_s, "stop after this long (0: until Ctrl-C)")
      ->check(CLI::Range(0.0, 86400.0));
  app.add_option("--haptics-config", o.haptics_path, "mapping, feedback, loop and device config");
  app.add_option("--vehicle", o.vehicle_path, "vehicle file (R_QC gives eq. 9's alpha)");
  app.add_option("--link-config", o.link_config_path, "YAML with a link: section");
  hq::link::add_link_options(app, o.link_overrides, hq::link::LinkSide::kStation);
  app.add_option("--command-rate-hz", o.command_rate_hz, "velocity commands sent per second")
      ->check(CLI::Range(5.0, 1000.0));
  app.add_option("--record", o.record_dir,
                 "record the flight here (telemetry, commands, events CSV; camera as TUM rgb/; "
                 "everything also in flight.mcap)");
  app.add_option("--replay", o.replay_dir, "play a recording back into the console; no link");
  app.add_option("--speed", o.speed, "replay speed factor")->check(CLI::Range(0.25, 8.0));
  app.add_option("--seek", o.seek_s, "replay: start this many seconds into the recording")
      ->check(CLI::Range(0.0, 86400.0));
  app.add_flag("--paused", o.paused, "replay: start paused (Space plays)");
  app.add_option("--keys", o.keys,
                 "replay window: keys typed as SECONDS:KEY,... after it opens (scripted runs)");
  app.add_option("--screenshot", o.screenshot_path, "write the console's last frame as PNG");
  app.add_option("--state-json", o.state_json_path, "write the console's state at exit as JSON");
  app.add_option("--max-fps", o.max_fps, "console frame-rate cap")->check(CLI::Range(1.0, 500.0));
  app.add_option("--marker-task", o.marker_task,
                 "request marker mode with this task once the vehicle is heard from")
      ->check(CLI::IsMember({"hold", "goto", "land"}));
  app.add_option("--marker-id", o.marker_id, "target marker (AprilTag id) of --marker-task")
      ->check(CLI::Range(0, 1 << 30));
  app.add_flag("--take-off", o.take_off,
               "ask the vehicle to take off (then teleop) once it is heard from");
  app.add_option("--link-lost-after-s", o.link_lost_after_s,
                 "link-loss alarm: no vehicle state for longer than this")
      ->check(CLI::Range(0.05, 60.0));
  app.add_option("--window-size", o.window_size,
                 "console window size WxH (default: fits the display, at most 1600x960)");
  app.add_option("--window-ini", o.window_ini,
                 "file remembering the window's size and position (default "
                 "$XDG_CONFIG_HOME/haptiquad/console.ini; \"none\": neither read nor written)");
  app.add_flag("--bare-window", o.bare_window,
               "measurement: draw an empty window (the frame-rate floor of the console)");
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  return std::nullopt;
}

hq::link::LinkConfig load_link(const Options& o) {
  hq::link::LinkConfig link = o.link_config_path.empty()
                                  ? hq::link::LinkConfig{}
                                  : hq::link::load_link_config(o.link_config_path);
  hq::link::apply_overrides(o.link_overrides, link);
  hq::log::note("hq-ground: link on domain {} as station {} for vehicle {}, {}\n", link.domain_id,
                link.station_id, link.vehicle_id,
                hq::link::describe_security(link, hq::security::Role::kStation).c_str());
  if (link.impairment.active()) {
    hq::log::note("hq-ground: received samples impaired: {}\n",
                  hq::link::describe(link.impairment).c_str());
  }
  return link;
}

// The MCAP flight record: a DDS subscriber on its own thread, so the command path only pushes
// one GroundSample per tick into a lock-free queue. A folder it cannot write to is told (in
// `off`) and the flight goes on without it.
std::unique_ptr<hq::mcap_recorder::FlightRecorder> open_mcap(const Options& o,
                                                             const hq::link::LinkConfig& link,
                                                             std::string& off) {
  if (o.record_dir.empty()) return nullptr;
  hq::mcap_recorder::FlightRecorderOptions mo;
  mo.path = o.record_dir + "/flight.mcap";
  mo.link = link;
  mo.camera_mount = hq::load_vehicle_config(o.vehicle_path).camera;
  for (const std::string& path : {o.haptics_path, o.vehicle_path, o.link_config_path}) {
    if (!path.empty()) mo.attachments.push_back({path, ""});
  }
  try {
    auto mcap = std::make_unique<hq::mcap_recorder::FlightRecorder>(mo);
    for (const std::string& skipped : mcap->attachments_skipped()) {
      hq::log::note("hq-ground: mcap: attachment skipped: {}\n", skipped.c_str());
    }
    return mcap;
  } catch (const hq::InputError& e) {
    off = std::string("mcap recording off: ") + e.what();
    hq::log::note("hq-ground: {}\n", off.c_str());
    return nullptr;
  }
}

hq::ground::OperatorStationOptions station_options(const Options& o,
                                                   const hq::link::LinkConfig& link) {
  hq::ground::OperatorStationOptions so;
  so.command_rate_hz = o.command_rate_hz;
  so.duration_s = o.duration_s;
  so.headless = o.headless;
  so.take_off = o.take_off;
  if (!o.marker_task.empty()) {
    so.marker.task = hq::ground::marker_task_of(o.marker_task).value_or(hq_msgs_MARKER_TASK_NONE);
    so.marker.target_id = o.marker_id;
  }
  so.link_lost_after_s = o.link_lost_after_s;
  so.station_id = link.station_id;
  return so;
}

// Link figures of the summary.
void print_link_summary(const hq::ground::GroundStation& ground,
                        const hq::ground::OperatorStation& station) {
  const hq::ground::LinkStatus& s = ground.status();
  hq::log::info("  {:<40} {} commands, {} mode requests, {} heartbeats, {} failed\n", "sent",
                s.commands_sent, s.mode_requests_sent, s.heartbeats_sent, s.write_failures);
  hq::log::info("  {:<40} {} states, {} events, {} camera frames ({:.1f} KB)\n", "received",
                s.states, s.events, s.camera_frames, 1e-3 * static_cast<double>(s.camera_bytes));
  hq::log::info("  {:<40} p50 {:.2f} ms, p99 {:.2f} ms over {}\n",
                "vehicle state latency (one way)", ground.latency().quantile_ms(0.5),
                ground.latency().quantile_ms(0.99), ground.latency().count());
  hq::log::info("  {:<40} p50 {:.0f} ms, p99 {:.0f} ms over {}\n", "heartbeat round trip",
                ground.round_trip().quantile_ms(0.5), ground.round_trip().quantile_ms(0.99),
                ground.round_trip().count());
  hq::log::info("  {:<40} p50 {:.0f} ms, p99 {:.0f} ms over {}\n", "vehicle state age (one way)",
                ground.state_age().quantile_ms(0.5), ground.state_age().quantile_ms(0.99),
                ground.state_age().count());
  hq::log::info("  {:<40} {:.1f} % ({} reordered, dropped as older)\n", "vehicle state loss",
                100.0 * ground.state_loss(), s.states_reordered);
  hq::log::info("  {:<40} {:.1f} ms\n", "largest gap between vehicle states",
                1e3 * station.stats().max_state_gap_s);
  const hq::console::LinkLossMonitor& link_loss = station.link_loss();
  hq::log::info("  {:<40} {}, longest {:.1f} s (alarm after {:.1f} s without a state)\n",
                "vehicle link losses", link_loss.losses(), link_loss.longest_s(),
                link_loss.lost_after_s());
  hq::log::info("  {:<40} {}\n", "last vehicle mode",
                s.have_state ? hq::ground::to_string(s.state.mode) : "-");
  hq::log::info("  {:<40} {}\n", "last event", s.last_event.data());
}

// Haptic loop, checks and ownership figures of the summary.
void print_hand_summary(const hq::ground::GroundStation& ground,
                        const hq::ground::OperatorStation& station,
                        const hq::haptics::HapticLoop& loop, std::uint32_t station_id) {
  const hq::ground::LinkStatus& s = ground.status();
  const hq::haptics::LoopTimingReport& timing = loop.timing();
  hq::log::info("  {:<40} p50 {:.1f} us, p99 {:.1f} us, max {:.1f} us, {} missed\n",
                "haptic loop period jitter", timing.period.quantile_us(0.5),
                timing.period.quantile_us(0.99), timing.period.max_us(), timing.missed_deadlines);
  hq::log::info("  {:<40} {:.4f} J (>= 0: passive), min {:.4f} J\n", "passivity observer energy",
                loop.passivity().energy_j(), loop.passivity().min_energy_j());
  hq::log::info("  {:<40} {:.4f} J dissipated ({})\n", "passivity controller",
                loop.passivity_controller().dissipated_j(),
                loop.passivity_controller().enabled() ? "on" : "off");
  hq::log::info("  {:<40} {}\n", "device losses", station.stats().device_losses);
  hq::log::info(
      "  {:<40} {} missing, {} rejected ({} invalid, {} implausible, {} of another session, {} "
      "sequence jumps), {} out of order, {} sequence resyncs\n",
      "vehicle states lost", s.state_sequence_gaps, s.states_rejected, s.states_invalid,
      s.states_implausible, s.states_wrong_session, s.states_sequence_jump, s.states_reordered,
      s.states_resynced);
  hq::log::info("  {:<40} {} rejected (not of session {:016x}); {} vehicle restarts\n",
                "vehicle events", s.events_rejected, s.vehicle_session, s.vehicle_restarts);
  hq::log::info("  {:<40} {} (commander: station {}, this station {}, {} losses)\n", "control",
                s.control_lost ? "LOST" : "held", s.commanding_station_id, station_id,
                s.control_losses);
  hq::log::info("  {:<40} {}{}{}\n", "intrusions the vehicle reported", s.intrusion_reports,
                s.intrusion_reports > 0 ? "; last: " : "", s.last_intrusion.data());
  hq::log::info("  {:<40} {:.3f} N\n", "largest force on the hand", station.stats().max_force_n);
}

// --state-json of a flight: the station's final word, not the console's last 4 Hz copy.
void write_flight_state_json(const Options& o, const hq::ground::GroundStation& ground,
                             const hq::ground::OperatorStation& station,
                             const hq::haptics::HapticLoop& loop, std::uint32_t station_id,
                             hq::console::ConsoleModel& model, hq::console::Snapshot& snap,
                             const std::optional<hq::console::WindowStats>& window) {
  const hq::ground::LinkStatus& s = ground.status();
  model.snapshot(snap);
  snap.link.control_lost = s.control_lost;
  snap.link.commanding_station = s.commanding_station_id;
  snap.link.own_station = station_id;
  snap.link.intrusion_reports = s.intrusion_reports;
  snap.link.last_intrusion = s.last_intrusion;
  snap.link.vehicle_session = s.vehicle_session;
  snap.link.waiting_for_vehicle = s.waiting_for_vehicle;
  snap.link.states_rejected = s.states_rejected;
  snap.link.states_implausible = s.states_implausible;
  snap.link.states_wrong_session = s.states_wrong_session;
  snap.link.events_rejected = s.events_rejected;
  write_state_json(o.state_json_path, snap, window ? &*window : nullptr, 0, 0,
                   station.stats().max_force_n, loop.passivity().min_energy_j());
}

// Exit status of a secured run that never heard from its vehicle: DDS Security drops a peer
// whose keys fail the handshake with only Cyclone's "handshake failed" log line, so a station
// with keys of another CA would otherwise wait the whole run and exit 0.
constexpr int kVehicleNeverReachedExitStatus = 3;

// Whether anything of the vehicle arrived: a state (even one rejected), an event, a camera
// frame or a heartbeat.
bool heard_from_vehicle(const hq::ground::LinkStatus& s) {
  return s.states > 0 || s.states_rejected > 0 || s.events > 0 || s.camera_frames > 0 ||
         s.have_vehicle_heartbeat;
}

// Names both ends and how to check their keys. Cyclone 0.10 reports a failed handshake through
// no status of its API, so silence for the whole run is the evidence, and said as such.
void report_vehicle_never_reached(const hq::link::LinkConfig& link, double waited_s) {
  const hq::security::IdentityFiles files =
      hq::link::security_files(link, hq::security::Role::kStation);
  const std::string station =
      link.security.identity.empty()
          ? hq::security::identity_name(hq::security::Role::kStation, link.station_id)
          : link.security.identity;
  const std::string vehicle =
      hq::security::identity_name(hq::security::Role::kVehicle, link.vehicle_id);
  const std::string keys = link.security.keys_dir.empty() ? "KEYS" : link.security.keys_dir;
  hq::log::error(
      "hq-ground: error: station {} (certificate {}) never reached vehicle {} ({}): "
      "nothing of it arrived in {:.1f} s on domain {}. Either the vehicle is not "
      "running there, or the DDS Security handshake failed (Cyclone logs only "
      "\"handshake failed\"), e.g. with keys of another CA. Check both ends' keys "
      "with `hq-keys check {} --identity {} --peer VEHICLE_KEYS/{}`; exit status "
      "{}\n",
      station.c_str(), files.certificate.c_str(), link.vehicle_id, vehicle.c_str(), waited_s,
      link.domain_id, keys.c_str(), station.c_str(), vehicle.c_str(),
      kVehicleNeverReachedExitStatus);
}

// Exit status of a flight that went well but whose record failed (disk full): the record is
// not flight-critical, so the flight went on, but whoever started it must learn that its
// record is incomplete.
constexpr int kRecordFailedExitStatus = 5;

// Closes the MCAP record with the flight's summary and prints what it wrote; false if the
// record failed at any time in the flight or at close.
bool close_mcap(hq::mcap_recorder::FlightRecorder& mcap, const hq::ground::GroundStation& ground,
                const hq::ground::OperatorStation& station, const hq::haptics::HapticLoop& loop) {
  const hq::ground::LinkStatus& s = ground.status();
  hq::mcap::KeyValues summary;
  const auto put = [&](const char* key, double v) { summary[key] = fmt::format("{:.6g}", v); };
  put("duration_s", hq::to_seconds(hq::haptics::monotonic_now_ns() - station.start_ns()));
  put("commands_sent", static_cast<double>(s.commands_sent));
  put("mode_requests_sent", static_cast<double>(s.mode_requests_sent));
  put("states_received", static_cast<double>(s.states));
  put("events_received", static_cast<double>(s.events));
  put("camera_frames_received", static_cast<double>(s.camera_frames));
  put("state_latency_p50_ms", ground.latency().quantile_ms(0.5));
  put("state_latency_p99_ms", ground.latency().quantile_ms(0.99));
  put("state_loss_percent", 100.0 * ground.state_loss());
  put("haptic_period_jitter_p99_us", loop.timing().period.quantile_us(0.99));
  put("device_losses", static_cast<double>(station.stats().device_losses));
  summary["last_vehicle_mode"] = s.have_state ? hq::ground::to_string(s.state.mode) : "-";
  summary["last_event"] = s.last_event.data();
  const hq::mcap_recorder::RecorderReport& r = mcap.close(summary);
  hq::log::info(
      "  {:<40} {} messages, {} channels, {} bytes, {} attachments, {} ground samples dropped\n",
      "mcap", r.messages, r.channels, r.bytes, r.attachments, r.ground_samples_dropped);
  for (const hq::mcap_recorder::ChannelReport& c : r.per_channel) {
    hq::log::info("  mcap channel {} {} {} {}\n", c.topic, c.messages, c.first_log_time_ns,
                  c.last_log_time_ns);
  }
  if (r.error.empty()) return true;
  hq::log::info("  {:<40} {}\n", "mcap error", r.error.c_str());
  hq::log::error("hq-ground: the flight record failed: {}\n", r.error.c_str());
  return false;
}

// The flight: the operator station on its own thread when the console is up, so that drawing
// never delays a command or the feedback's vehicle state; on this thread when headless.
std::optional<hq::console::WindowStats> fly(const Options& o, hq::ground::OperatorStation& station,
                                            hq::console::ConsoleModel& model,
                                            hq::console::Snapshot& snap,
                                            hq::console::FlightKeys* flight_keys) {
  std::atomic<bool> flying_done{false};
  if (o.headless) {
    station.run(g_stop, flying_done);
    return std::nullopt;
  }
  std::thread flying([&] {
    station.run(g_stop, flying_done);
    flying_done = true;
  });
  std::optional<hq::console::WindowStats> window;
  try {
    window = run_window(o, "hq-ground: operator console", model, station.requests(), flying_done,
                        snap, flight_keys);
  } catch (...) {
    flying_done = true;
    flying.join();
    throw;
  }
  flying_done = true;
  flying.join();
  return window;
}

int run_live(const Options& o) {
  const hq::link::LinkConfig link = load_link(o);
  const hq::haptics::HapticsConfig haptics = hq::haptics::load_haptics_config(o.haptics_path);
  const hq::VehicleConfig vehicle = hq::load_vehicle_config(o.vehicle_path);
  hq::haptics::DeviceOptions device_options;
  device_options.config = haptics;
  device_options.terminal_fd = STDIN_FILENO;
  // Keyboard flying: from the console window's key events when it is open, from the terminal
  // in raw mode when --headless.
  hq::console::FlightKeys flight_keys;
  const bool window_keyboard = o.device == "keyboard" && !o.headless;
  std::unique_ptr<hq::haptics::HapticDevice> device =
      window_keyboard
          ? std::make_unique<hq::ground::WindowKeyboardDevice>(haptics.keyboard, flight_keys)
          : hq::haptics::open_device(o.device, device_options);

  std::unique_ptr<hq::ground::TelemetryRecorder> recorder;
  if (!o.record_dir.empty())
    recorder = std::make_unique<hq::ground::TelemetryRecorder>(o.record_dir);
  std::string mcap_off;  // why there is no MCAP record despite --record
  std::unique_ptr<hq::mcap_recorder::FlightRecorder> mcap = open_mcap(o, link, mcap_off);
  hq::ground::GroundStation ground(link, recorder.get());
  ground.set_log(stdout);  // control lost / vehicle restarted: said once each, on stdout
  hq::console::ConsoleModel model;
  ModelFeed feed(model, ground);
  ground.set_observer(&feed);
  if (!mcap_off.empty()) model.on_event(dds_time(), 2, mcap_off.c_str());
  model.set_source("live: domain " + std::to_string(link.domain_id) + ", device " + o.device);
  hq::haptics::HapticLoop loop(*device, haptics, vehicle.camera.R_B_C());
  const hq::haptics::RealtimeGrant grant = loop.start();
  hq::log::note(
      "hq-ground: device {}, domain {}, vehicle {}, station {} (strength {}); haptic "
      "loop: {}\n",
      device->name(), link.domain_id, link.vehicle_id, link.station_id, link.station_strength,
      grant.summary.c_str());

  hq::ground::SystemClock clock;
  hq::ground::OperatorOutputs outputs;
  outputs.recorder = recorder.get();
  outputs.mcap = mcap.get();
  hq::ground::OperatorStation station(station_options(o, link), ground, loop, model, clock,
                                      outputs);
  hq::log::info("hq-ground summary\n");
  hq::console::Snapshot snap = model.make_snapshot();
  const std::optional<hq::console::WindowStats> window =
      fly(o, station, model, snap, window_keyboard ? &flight_keys : nullptr);
  loop.stop();

  print_link_summary(ground, station);
  print_hand_summary(ground, station, loop, link.station_id);
  if (!o.state_json_path.empty()) {
    write_flight_state_json(o, ground, station, loop, link.station_id, model, snap, window);
  }
  bool record_ok = !mcap || close_mcap(*mcap, ground, station, loop);
  // A flight.mcap that could not be made at the start (one already there) was told then, and
  // the CSV recording holds the flight: that is no failure of the record made.
  if (!mcap_off.empty()) hq::log::info("  {:<40} {}\n", "mcap", mcap_off.c_str());
  if (recorder && !recorder->close()) {
    hq::log::error("hq-ground: the flight record failed: recording: {}\n",
                   recorder->error().c_str());
    record_ok = false;
  }
  if (link.security.enabled && !heard_from_vehicle(ground.status())) {
    report_vehicle_never_reached(
        link, hq::to_seconds(hq::haptics::monotonic_now_ns() - station.start_ns()));
    return kVehicleNeverReachedExitStatus;
  }
  if (record_ok) return 0;
  hq::log::note(
      "hq-ground: the flight record is incomplete; exit status {}, the flight itself "
      "went on\n",
      kRecordFailedExitStatus);
  return kRecordFailedExitStatus;
}

int run(int argc, char** argv) {
  Options o;
  if (const std::optional<int> status = parse_options(argc, argv, o)) return *status;
  std::signal(SIGINT, request_stop);
  std::signal(SIGTERM, request_stop);
  if (!o.headless) require_display(o.replay_dir.empty() ? "--device" : "--replay");
  if (!o.replay_dir.empty()) return run_replay(o);
  if (o.headless && !o.screenshot_path.empty()) {
    throw hq::InputError("--screenshot " + o.screenshot_path +
                         ": needs the console (no --headless)");
  }
  return run_live(o);
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-ground", argc, argv, run); }
