#pragma once
/// The operator console's window: Dear ImGui (Debian's libimgui, with its SDL2 and OpenGL3
/// backends) on an SDL2 window with an OpenGL 3 context. Draws a Snapshot of ConsoleModel on
/// the UI thread only; it never touches the link or the haptic loop, it returns what the
/// operator asked for.
///
/// Panels: camera (decoded JPEG, depth preview, overlays of v_obs, commanded and estimated
/// velocity), time plots in the manner of Fig. 6-8 of the core paper, haptic device, top view,
/// modes, vehicle selector, link health, event log, under a status bar (flight state, motors,
/// height, mode, estimator, link, what happens to the operator's input) and, when no vehicle
/// state came for link_lost_after_s, a red link-loss banner with every vehicle field greyed
/// and marked STALE. Panels are laid out from the window's size on every frame, so a resize
/// re-lays them out. Shortcuts (when no text field has focus): U take off, T teleop, H hover,
/// L land, M marker, X explore, B mute the alarm, Esc quit; with set_flight_keys(), the flying
/// keys of flight_keys.hpp (W/S, Q/E, A/D, arrows, page up/down) are held into FlightKeys.

#include "hq/console/console_model.hpp"
#include "hq/console/flight_keys.hpp"
#include "hq/console/replay_player.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <string>

namespace hq::console {

struct UiActions {
  const char* mode_request = nullptr;  ///< "teleop", "hover", "land", "marker", "explore".
  /// With mode_request "marker": "hold", "goto" or "land" on marker marker_id; null: none.
  const char* marker_task = nullptr;
  int marker_id = 0;
  bool take_off = false;  ///< The take-off button or U: take off, then teleop.
  bool select_vehicle = false;
  std::uint32_t vehicle_id = 0;
  bool quit = false;  ///< Window closed or Esc.
  /// Replay controls (with set_replay()): play/pause, speed steps (+ faster), seek to a time
  /// (< 0: none) or by an offset.
  bool replay_toggle = false;
  int replay_speed_step = 0;
  double replay_seek_to_s = -1;
  double replay_seek_by_s = 0;
};

struct WindowStats {
  std::uint64_t frames = 0;
  double fps = 0;            ///< Frames shown per second since the first frame.
  double render_ms_p50 = 0;  ///< Time to build and draw one frame (without the frame cap).
  double render_ms_max = 0;
  std::uint64_t camera_frames_decoded = 0;
  std::uint64_t camera_decode_failures = 0;
  int camera_width_px = 0;
  int camera_height_px = 0;
  std::uint64_t depth_frames_decoded = 0;
  /// Video latency, camera exposure to the frame's first display, and where it goes: exposure
  /// to receipt (vehicle encode and link), receipt to decoded (the UI's pick-up and the JPEG
  /// decode), decoded to display (upload on the next UI frame). ms over the session; -1 none.
  double video_p50_ms = -1;
  double video_p99_ms = -1;
  double video_last_ms = -1;
  double video_link_p50_ms = -1;
  double video_decode_p50_ms = -1;
  double video_display_p50_ms = -1;
  std::size_t plot_samples_drawn = 0;
  std::string mode_shown = "-";
  std::string gl_renderer;
  /// The window on the screen at the last frame, and the display's usable area.
  int x_px = 0;
  int y_px = 0;
  int width_px = 0;
  int height_px = 0;
  int display_width_px = 0;
  int display_height_px = 0;
  std::uint64_t link_lost_banner_frames = 0;  ///< Frames drawn with the link-loss banner.
  /// Frames drawn with the banner of a vehicle that said goodbye ("vehicle ended: ...").
  std::uint64_t vehicle_ended_banner_frames = 0;
  std::uint64_t take_off_hint_frames = 0;  ///< Frames drawn with the landed take-off hint.
  /// The camera image as last drawn: its size on screen and whether all of it was visible.
  int camera_shown_x_px = 0;
  int camera_shown_y_px = 0;
  int camera_shown_width_px = 0;
  int camera_shown_height_px = 0;
  bool camera_image_whole = false;
  bool force_bars_whole = false;  ///< The haptic force bars (Fz last) all visible.
  /// Every line of the status bar, the controls and the link panel within its panel.
  bool status_bar_whole = false;
  bool control_panel_whole = false;
  bool link_panel_whole = false;
  /// The marker and explore mode buttons as last drawn (greyed when the vehicle does not offer
  /// them), and the note drawn under them saying why ("" when none).
  bool marker_button_enabled = true;
  bool explore_button_enabled = true;
  std::string modes_off_note;
  /// The highest and lowest climb (m/s, up positive) the status bar showed.
  double climb_shown_max_mps = 0;
  double climb_shown_min_mps = 0;
  /// The alarm: its cause at the last frame ("none", "link lost", "fail-safe"), muted, the
  /// audio driver or why there is none, samples of tone played, frames drawn with an alarm.
  std::string alarm_cause = "none";
  bool alarm_muted = false;
  std::string alarm_audio;
  std::uint64_t alarm_tone_samples = 0;
  std::uint64_t alarm_frames = 0;
};

struct WindowOptions {
  /// Initial size; 0: from the display's usable area (at most 1600 x 960), or the remembered
  /// size when it fits. Always clamped to the display and placed inside it.
  int width_px = 0;
  int height_px = 0;
  double max_fps = 60.0;
  /// Remembers the window's size and position between runs ("x y width height"); empty: off.
  std::string ini_path;
  /// Top view: the camera's heading in the body (core paper's alpha, geometry::
  /// camera_heading_rad), its horizontal field of view, and R_QC row-major to place markers.
  double camera_heading_rad = 0.0;
  double camera_hfov_rad = 1.01;  ///< 58 deg, the Xtion's.
  std::array<float, 9> R_B_C{0, 0, 1, 1, 0, 0, 0, 1, 0};
  std::array<float, 3> p_B_C_m{};
  /// Measurement only: draw no panel (an empty ImGui frame on the cleared window), the floor
  /// against which the console's own frame cost is read.
  bool bare = false;
};

/// $XDG_CONFIG_HOME/haptiquad/console.ini, else $HOME/.config/haptiquad/console.ini; empty when
/// neither variable is set.
std::string default_window_ini_path();

/// The FlightKey bit of an SDL scancode (SDL_Scancode, by physical position, so WASD stays put
/// on other layouts), 0 for keys that do not fly.
std::uint32_t flight_key_for_scancode(int sdl_scancode);

class ConsoleWindow {
 public:
  /// Opens the window. @throws hq::InputError naming the SDL call that failed (no display...).
  ConsoleWindow(const std::string& title, const WindowOptions& options);
  ~ConsoleWindow();
  ConsoleWindow(const ConsoleWindow&) = delete;
  ConsoleWindow& operator=(const ConsoleWindow&) = delete;

  /// Handles input and draws `s`; waits to hold the frame rate at max_fps.
  UiActions frame(const Snapshot& s);
  /// Draws `s` once more and writes that frame (glReadPixels of the back buffer before the
  /// swap) as PNG. @throws hq::InputError if the file cannot be written.
  void save_screenshot(const Snapshot& s, const std::string& path);
  [[nodiscard]] WindowStats stats() const;
  /// Holds the flying keys into `keys` (not owned; null stops), marks it open until this
  /// window closes, and releases every key when the window loses the focus.
  void set_flight_keys(FlightKeys* keys);
  /// Replay: draws `timeline` (not owned; null: live) as a strip below the panels, takes
  /// Space, [ ], Left/Right as replay controls and greys out the mode requests.
  void set_replay(const Timeline* timeline);
  /// Queues a key press and release (an SDL key name: "Space", "Right", "[") as if typed, for
  /// scripted runs (hq-ground --keys). @throws hq::InputError for an unknown name.
  void queue_key(const std::string& name);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hq::console
