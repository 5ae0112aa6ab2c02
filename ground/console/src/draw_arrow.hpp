#pragma once
// One arrow for every panel that draws one (the camera overlay, the top view's heading).

#include <imgui.h>

namespace hq::console {

/// An arrow from `from` along `v` (in pixels), its head drawn once it is 4 px long.
void draw_arrow(ImDrawList* draw, ImVec2 from, ImVec2 v, ImU32 colour);

}  // namespace hq::console
