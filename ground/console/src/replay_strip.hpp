#pragma once
// The console's replay controls (hq-ground --replay): a timeline strip with the clock,
// play/pause, speed, a scrub bar with the recording's mode bands, event marks and vehicle
// restarts, and the end-of-recording state. Kept apart from the live panels of
// console_window.cpp; drawn inside its ImGui frame.

#include "hq/console/console_window.hpp"
#include "hq/console/replay_player.hpp"

namespace hq::console {

/// Height of the strip in pixels (the live panels are laid out above it).
inline constexpr float kReplayStripHeightPx = 96.0F;

/// Draws the strip at (x, y) of width w and kReplayStripHeightPx; clicks become `actions`.
void draw_replay_strip(const Timeline& timeline, const Snapshot& s, UiActions& actions, float x,
                       float y, float w);

/// A key pressed in replay (SDL keycode): Space play/pause, [ ] slower/faster, Left/Right
/// seek -/+ 5 s. Returns true if it was one of them.
bool replay_key(int sdl_keycode, UiActions& actions);

}  // namespace hq::console
