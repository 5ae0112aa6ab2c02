#include "status_bar.hpp"

#include "hq/base/format_into.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <imgui.h>

namespace hq::console {

namespace {

constexpr ImU32 kStale = IM_COL32(120, 120, 120, 255);
constexpr ImU32 kText = IM_COL32(230, 230, 230, 255);
constexpr ImU32 kOk = IM_COL32(90, 220, 110, 255);
constexpr ImU32 kWarn = IM_COL32(255, 170, 40, 255);
constexpr ImU32 kAlarm = IM_COL32(255, 70, 70, 255);
constexpr const char* kKeyHint =
    "keys: U take off | W/S fwd/back | A/D Q/E yaw | PgUp/PgDn climb/descend | T teleop | "
    "H hover | L land | M marker | X explore | B mute alarm | Esc quit";

// One "name: value" field in a column `chars` characters wide (the default font is monospaced),
// clipped to it: the next field starts at the same place whatever this one says. A column that
// would pass the window's right edge starts a new line at the row's first column.
class Row {
 public:
  /// `new_line`: the row starts a line (else it carries on the line of the item before).
  Row(float x0, bool new_line, bool& columns_inside)
      : x_(x0), first_x_(x0), new_line_(new_line), columns_inside_(columns_inside) {}
  void field(const char* name, const char* value, ImU32 colour, bool greyed, int chars) {
    char text[128];
    hq::format_into(text, "{}: {}", name, value);
    put(text, greyed ? kStale : colour, chars);
  }
  void put(const char* text, ImU32 colour, int chars) {
    // Two characters more than the widest text: a gap between the columns.
    const float column = static_cast<float>(chars + 2) * ImGui::CalcTextSize("0").x;
    const float right = ImGui::GetWindowContentRegionMax().x;
    if (!new_line_ && x_ > first_x_ && x_ + column - 6 > right) {
      new_line_ = true;
      x_ = first_x_;
    }
    if (x_ + column - 6 > right) columns_inside_ = false;  // one column wider than the window
    if (new_line_) {
      ImGui::SetCursorPosX(x_);
      new_line_ = false;
    } else {
      ImGui::SameLine(x_);
    }
    const ImVec2 p = ImGui::GetCursorScreenPos();
    ImGui::PushClipRect(p, ImVec2(p.x + column - 6, p.y + ImGui::GetTextLineHeightWithSpacing()),
                        true);
    ImGui::TextColored(ImColor(colour), "%s", text);
    ImGui::PopClipRect();
    x_ += column;
  }

 private:
  float x_;
  float first_x_;
  bool new_line_;
  bool& columns_inside_;
};

// mm:ss of flight.
void clock_text(double t_s, char* out, std::size_t size) {
  if (t_s < 0) {
    hq::format_into(out, size, "-");
    return;
  }
  const int s = static_cast<int>(t_s);
  hq::format_into(out, size, "{:02}:{:02}", s / 60, s % 60);
}

// Rows 1 and 2: what the vehicle is doing, how it moves and what limits it.
void draw_vehicle_rows(const Snapshot& s, bool grey, bool landed, float x0, bool& inside) {
  ImGui::TextUnformatted("VEHICLE");
  Row row1(x0 + 9 * ImGui::CalcTextSize("0").x, false, inside);
  const ImU32 flight_colour = landed ? IM_COL32(230, 200, 80, 255)
                              : std::strcmp(s.flight_state, "airborne") == 0
                                  ? kOk
                                  : IM_COL32(120, 200, 255, 255);
  row1.field("flight", s.flight_state, flight_colour, grey, 19);
  row1.field("motors", s.motors_armed ? "ARMED" : "idle",
             s.motors_armed ? IM_COL32(255, 140, 60, 255) : IM_COL32(200, 200, 200, 255), grey, 14);
  char text[64];
  if (s.height_valid) {
    hq::format_into(text, "{:.2f} m ({})", static_cast<double>(s.height_m), s.height_source);
  } else {
    hq::format_into(text, "unknown");
  }
  row1.field("height", text, kText, grey, 26);
  const int link_class = link_state_text(s, text, sizeof text);
  row1.field("link", text,
             link_class == 0   ? kOk
             : link_class == 1 ? kWarn
             : link_class == 2 ? kAlarm
                               : kText,
             false, 28);

  // The mode with what an autonomous one is at: its marker, the exploration's phase.
  if (s.explore_phase[0] != '\0') {
    hq::format_into(text, "{} ({}, marker {})", s.mode, s.explore_phase, s.marker_target_id);
  } else if (s.marker_target_id >= 0) {
    hq::format_into(text, "{} (to {})", s.mode, s.marker_target_id);
  } else {
    hq::format_into(text, "{}", s.mode);
  }
  row1.field("mode", text, kText, grey, 36);
  clock_text(s.flight_time_s, text, sizeof text);
  row1.field("flight time", text, kText, false, 18);

  // Row 2: how it moves and what limits it.
  Row row2(x0, true, inside);
  const auto& v = s.latest.v_est_H_mps;
  hq::format_into(text, "{:.2f} m/s",
                  std::hypot(static_cast<double>(v[0]), static_cast<double>(v[1])));
  row2.field("ground speed", s.have_state ? text : "-", kText, grey, 24);
  // H is NED: z points down, a climb is -v_z.
  hq::format_into(text, "{:+.2f} m/s", -static_cast<double>(v[2]));
  row2.field("climb", s.have_state ? text : "-", kText, grey, 18);
  row2.field("estimator", s.estimator_health.c_str(), s.estimator_health == "ok" ? kOk : kWarn,
             grey, 21);
  if (s.clearance_m >= 0) {
    hq::format_into(text, "{:.2f} m", static_cast<double>(s.clearance_m));
  } else {
    // The vehicle saw no obstacle within its depth range: news too, not a missing figure.
    hq::format_into(text, "none in view or memory");
  }
  row2.field("clearance", text, kText, grey, 33);
  // What the rotors really give for the thrust commanded: far from 100 % means the vehicle
  // file's mass or the FC's maximum thrust is off (the vehicle flies on the learnt value).
  const double thrust_pct = 100.0 * static_cast<double>(s.hover_thrust_gain);
  if (s.hover_thrust_converged) {
    hq::format_into(text, "{:.0f} % (learnt)", thrust_pct);
  } else {
    hq::format_into(text, "{}", s.hover_thrust_gain > 0 ? "learning" : "-");
  }
  const bool thrust_off = s.hover_thrust_converged && std::abs(thrust_pct - 100.0) > 15.0;
  row2.field("thrust given", text, thrust_off ? kWarn : kText, grey, 30);
  if (s.operator_input[0] != '\0') {
    const bool slowed = std::strncmp(s.operator_input, "slowed", 6) == 0;
    row2.put(s.operator_input, grey ? kStale : slowed ? IM_COL32(255, 200, 60, 255) : kAlarm, 40);
  }
}

}  // namespace

float status_bar_height() {
  const ImGuiStyle& style = ImGui::GetStyle();
  return 2 * ImGui::GetTextLineHeightWithSpacing() + ImGui::GetFrameHeight() +
         2 * style.WindowPadding.y + style.ItemSpacing.y;
}

int link_state_text(const Snapshot& s, char* out, std::size_t size) {
  const LinkHealth& l = s.link;
  if (s.replay.active) {
    hq::format_into(out, size, "{}", s.replay.at_end ? "end of recording" : "replayed");
    return 3;
  }
  if (!s.have_state || l.state_age_s < 0) {
    hq::format_into(out, size, "waiting for the vehicle");
    return 3;
  }
  if (l.link_lost) {
    hq::format_into(out, size, "LOST {:.1f} s", l.state_age_s);
    return 2;
  }
  if (l.vehicle_ended) {
    // It said goodbye: silent on purpose, as the vehicle-ended banner says.
    hq::format_into(out, size, "vehicle ended");
    return 3;
  }
  if (l.state_age_s > 0.5) {
    hq::format_into(out, size, "STALE {:.1f} s", l.state_age_s);
    return 1;
  }
  if (s.link_health != "ok") {
    hq::format_into(out, size, "vehicle says {}", s.link_health);
    return 1;
  }
  hq::format_into(out, size, "ok");
  return 0;
}

StatusBarActions draw_status_bar(const Snapshot& s, const StatusBarInput& in, float width,
                                 float height) {
  StatusBarActions actions;
  ImGui::SetNextWindowPos(ImVec2(0, 0), ImGuiCond_Always);
  ImGui::SetNextWindowSize(ImVec2(width, std::max(height, status_bar_height())), ImGuiCond_Always);
  ImGui::Begin("Status", nullptr,
               ImGuiWindowFlags_NoTitleBar | ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize |
                   ImGuiWindowFlags_NoCollapse | ImGuiWindowFlags_NoSavedSettings |
                   ImGuiWindowFlags_NoScrollbar | ImGuiWindowFlags_NoScrollWithMouse);
  const bool grey = in.stale_s >= 0;
  const bool landed = std::strcmp(s.flight_state, "landed") == 0;
  const float x0 = ImGui::GetCursorPosX();
  char text[64];

  if (!s.have_state) {
    // Before the first state: one line that says so, not two rows of dashes.
    char link[64];
    link_state_text(s, link, sizeof link);
    ImGui::TextColored(ImColor(IM_COL32(230, 200, 80, 255)), "VEHICLE: %s", link);
    ImGui::TextUnformatted("");
  } else {
    draw_vehicle_rows(s, grey, landed, x0, actions.columns_inside);
  }

  // Row 3: the actions (take off, mute) and the keys.
  if (landed && !grey) {
    ImGui::PushStyleColor(ImGuiCol_Button, IM_COL32(40, 130, 60, 255));
    if (ImGui::Button("Take off (U)")) actions.take_off = true;
    ImGui::PopStyleColor();
    actions.take_off_hint = true;
  } else if (ImGui::Button("Take off (U)")) {
    actions.take_off = true;
  }
  ImGui::SameLine(0, 18);
  if (in.alarm != AlarmCause::kNone) {
    hq::format_into(text, "ALARM: {}{}", to_string(in.alarm),
                    in.alarm_muted ? " (muted)"
                    : in.audio     ? ""
                                   : " (no sound)");
    ImGui::TextColored(ImColor(in.alarm_muted ? kWarn : kAlarm), "%s", text);
    ImGui::SameLine();
    if (ImGui::SmallButton(in.alarm_muted ? "Unmute (B)" : "Mute (B)")) actions.toggle_mute = true;
  } else {
    ImGui::TextColored(ImColor(IM_COL32(150, 150, 150, 255)), "alarm: %s",
                       in.audio ? "armed" : "no sound");
  }
  ImGui::SameLine(0, 18);
  if (landed && !grey) {
    ImGui::TextColored(ImColor(IM_COL32(230, 200, 80, 255)), "landed - press U to take off");
    ImGui::SameLine(0, 18);
  }
  // The hint wraps at the window's edge: its end (Esc quit) stays on screen when narrow.
  ImGui::PushTextWrapPos(0);
  ImGui::TextColored(ImColor(IM_COL32(170, 170, 190, 255)), "%s", kKeyHint);
  ImGui::PopTextWrapPos();
  const ImGuiStyle& style = ImGui::GetStyle();
  actions.needed_height_px = ImGui::GetCursorPosY() - style.ItemSpacing.y + style.WindowPadding.y;
  ImGui::End();
  return actions;
}

}  // namespace hq::console
