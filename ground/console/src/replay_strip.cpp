#include "replay_strip.hpp"

#include <SDL.h>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <imgui.h>
#include <string_view>

namespace hq::console {

namespace {

constexpr double kSeekStepS = 5.0;

ImU32 mode_colour(std::string_view mode) {
  if (mode == "teleop") return IM_COL32(60, 160, 80, 255);
  if (mode == "hover") return IM_COL32(60, 110, 190, 255);
  if (mode == "land") return IM_COL32(210, 130, 40, 255);
  if (mode == "marker") return IM_COL32(150, 80, 180, 255);
  if (mode == "explore") return IM_COL32(40, 160, 160, 255);
  return IM_COL32(90, 90, 90, 255);
}

ImU32 severity_colour(int severity) {
  return severity >= 2   ? IM_COL32(255, 90, 90, 255)
         : severity == 1 ? IM_COL32(255, 200, 70, 255)
                         : IM_COL32(220, 220, 220, 255);
}

}  // namespace

bool replay_key(int sdl_keycode, UiActions& actions) {
  switch (sdl_keycode) {
    case SDLK_SPACE:
      actions.replay_toggle = true;
      return true;
    case SDLK_LEFTBRACKET:
      --actions.replay_speed_step;
      return true;
    case SDLK_RIGHTBRACKET:
      ++actions.replay_speed_step;
      return true;
    case SDLK_LEFT:
      actions.replay_seek_by_s -= kSeekStepS;
      return true;
    case SDLK_RIGHT:
      actions.replay_seek_by_s += kSeekStepS;
      return true;
    default:
      return false;
  }
}

void draw_replay_strip(const Timeline& timeline, const Snapshot& s, UiActions& actions, float x,
                       float y, float w) {
  const ReplayStatus& r = s.replay;
  ImGui::SetNextWindowPos(ImVec2(x, y), ImGuiCond_Always);
  ImGui::SetNextWindowSize(ImVec2(w, kReplayStripHeightPx), ImGuiCond_Always);
  ImGui::Begin("Replay", nullptr,
               ImGuiWindowFlags_NoResize | ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoCollapse |
                   ImGuiWindowFlags_NoTitleBar | ImGuiWindowFlags_NoScrollbar);
  if (ImGui::Button(r.playing ? "Pause (Space)" : "Play (Space)", ImVec2(120, 0))) {
    actions.replay_toggle = true;
  }
  ImGui::SameLine();
  if (ImGui::Button("slower [")) --actions.replay_speed_step;
  ImGui::SameLine();
  ImGui::Text("%.2gx", r.speed);
  ImGui::SameLine();
  if (ImGui::Button("faster ]")) ++actions.replay_speed_step;
  ImGui::SameLine();
  if (ImGui::Button("-5 s (Left)")) actions.replay_seek_by_s -= kSeekStepS;
  ImGui::SameLine();
  if (ImGui::Button("+5 s (Right)")) actions.replay_seek_by_s += kSeekStepS;
  ImGui::SameLine();
  char now[16];
  char total[16];
  format_clock(r.position_s, now, sizeof now);
  format_clock(r.duration_s, total, sizeof total);
  ImGui::Text("  %s / %s", now, total);
  ImGui::SameLine();
  if (r.at_end) {
    ImGui::TextColored(ImVec4(1, 0.45F, 0.3F, 1), "  END OF RECORDING");
  } else {
    ImGui::TextColored(r.playing ? ImVec4(0.5F, 0.9F, 0.5F, 1) : ImVec4(1, 0.85F, 0.3F, 1),
                       "  REPLAY %s", r.playing ? "PLAYING" : "PAUSED");
  }
  ImGui::SameLine();
  ImGui::Text("  vehicle sessions %zu/%zu", r.sessions, timeline.sessions.size());

  // The scrub bar: mode bands, event ticks below, restarts as red bars, the playhead.
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  const float bar_w = std::max(ImGui::GetContentRegionAvail().x, 10.0F);
  const float bar_h = 26.0F;
  ImGui::InvisibleButton("scrub", ImVec2(bar_w, bar_h + 10.0F));
  const double duration_s = std::max(timeline.duration_s, 1e-9);
  if (ImGui::IsItemActive() && ImGui::IsMouseDown(ImGuiMouseButton_Left)) {
    const float f = std::clamp((ImGui::GetIO().MousePos.x - origin.x) / bar_w, 0.0F, 1.0F);
    actions.replay_seek_to_s = static_cast<double>(f) * timeline.duration_s;
  }
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const auto x_of = [&](double t_s) {
    return origin.x + static_cast<float>(std::clamp(t_s / duration_s, 0.0, 1.0)) * bar_w;
  };
  draw->AddRectFilled(origin, ImVec2(origin.x + bar_w, origin.y + bar_h),
                      IM_COL32(40, 40, 48, 255));
  for (const ModeBand& b : timeline.bands) {
    draw->AddRectFilled(ImVec2(x_of(b.start_s), origin.y + 3),
                        ImVec2(std::max(x_of(b.end_s), x_of(b.start_s) + 1), origin.y + bar_h - 3),
                        mode_colour(b.mode));
    if (x_of(b.end_s) - x_of(b.start_s) > 50) {
      draw->AddText(ImVec2(x_of(b.start_s) + 3, origin.y + 6), IM_COL32(255, 255, 255, 220),
                    b.mode);
    }
  }
  for (const EventMark& e : timeline.marks) {
    const float ex = x_of(e.t_s);
    draw->AddLine(ImVec2(ex, origin.y + bar_h), ImVec2(ex, origin.y + bar_h + 9),
                  severity_colour(e.severity), 2.0F);
  }
  for (std::size_t i = 1; i < timeline.sessions.size(); ++i) {
    const float sx = x_of(timeline.sessions[i].t_s);
    draw->AddRectFilled(ImVec2(sx - 2, origin.y), ImVec2(sx + 2, origin.y + bar_h),
                        IM_COL32(255, 60, 60, 255));
  }
  const float px = x_of(r.position_s);
  draw->AddRectFilled(ImVec2(origin.x, origin.y + bar_h - 3), ImVec2(px, origin.y + bar_h),
                      IM_COL32(230, 230, 230, 160));
  draw->AddLine(ImVec2(px, origin.y - 2), ImVec2(px, origin.y + bar_h + 2),
                IM_COL32(255, 255, 255, 255), 2.0F);
  ImGui::End();
}

}  // namespace hq::console
