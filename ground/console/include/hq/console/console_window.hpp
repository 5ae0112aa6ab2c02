#pragma once
/// The operator console's window: Dear ImGui (Debian's libimgui, with its SDL2 and OpenGL3
/// backends) on an SDL2 window with an OpenGL 3 context. Draws a Snapshot of ConsoleModel on
/// the UI thread only; it never touches the link or the haptic loop, it returns what the
/// operator asked for.
///
/// Panels: camera (decoded JPEG, depth preview, overlays of v_obs, commanded and estimated
/// velocity), time plots in the manner of Fig. 6-8 of the core paper, haptic device, top view,
/// modes, vehicle selector, link health, event log. Shortcuts (when no text field has focus):
/// T teleop, H hover, L land, M marker, X explore, Esc quit; with set_flight_keys(), the flying
/// keys of flight_keys.hpp (W/S, Q/E, A/D, arrows, page up/down) are held into FlightKeys.

#include "hq/console/console_model.hpp"
#include "hq/console/flight_keys.hpp"
#include "hq/console/replay_player.hpp"

#include <cstdint>
#include <memory>
#include <string>

namespace hq::console {

struct UiActions {
  const char* mode_request = nullptr;  ///< "teleop", "hover", "land", "marker", "explore".
  /// With mode_request "marker": "hold", "goto" or "land" on marker marker_id; null: none.
  const char* marker_task = nullptr;
  int marker_id = 0;
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
  double fps = 0;               ///< Frames shown per second since the first frame.
  double render_ms_p50 = 0;     ///< Time to build and draw one frame (without the frame cap).
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
};

/// The FlightKey bit of an SDL scancode (SDL_Scancode, by physical position, so WASD stays put
/// on other layouts), 0 for keys that do not fly.
std::uint32_t flight_key_for_scancode(int sdl_scancode);

class ConsoleWindow {
 public:
  /// Opens the window. @throws hq::InputError naming the SDL call that failed (no display...).
  ConsoleWindow(const std::string& title, int width_px, int height_px, double max_fps = 60.0);
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
