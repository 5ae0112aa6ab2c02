#pragma once
// The status bar across the top of the console: the flight at a glance in fixed columns on
// three rows, each value clipped to its column so that nothing moves as values change. A window
// too narrow for a row's columns continues them on the next line (and the key hint wraps)
// rather than cutting off its end: the bar then grows by those lines, which depend only on the
// width. The link's state is said once, in the same words as the link-loss banner.

#include "hq/console/console_model.hpp"

#include "alarm.hpp"

namespace hq::console {

struct StatusBarInput {
  double stale_s = -1;  ///< Age of the vehicle's state when stale (its fields greyed), else < 0.
  AlarmCause alarm = AlarmCause::kNone;
  bool alarm_muted = false;
  bool audio = false;  ///< An audio device plays the alarm.
  const char* audio_status = "";
};

struct StatusBarActions {
  bool take_off = false;
  bool toggle_mute = false;
  bool take_off_hint = false;  ///< The landed take-off hint was shown.
  /// The height its content took (lines wrapped at this width); the next frame's height.
  float needed_height_px = 0;
  /// Every column within the window's width.
  bool columns_inside = true;
};

/// The bar's least height for the current font: three rows and the window padding.
float status_bar_height();

/// The link's state in the banner's words: "waiting", "ok", "STALE 0.8 s", "LOST 6.1 s", or
/// the vehicle's own complaint about the link while states arrive ("vehicle: degraded").
/// Writes into `out`; returns its colour class: 0 ok, 1 warning, 2 alarm, 3 neutral.
int link_state_text(const Snapshot& s, char* out, std::size_t size);

/// Draws the bar at the window's top, `width` wide and `height` high (at least
/// status_bar_height(); the previous frame's needed_height_px shows it whole).
StatusBarActions draw_status_bar(const Snapshot& s, const StatusBarInput& in, float width,
                                 float height);

}  // namespace hq::console
