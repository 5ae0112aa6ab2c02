#include "camera_panel.hpp"

#include "hq/base/format_into.hpp"

#include "draw_arrow.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <imgui.h>

namespace hq::console {

namespace {

constexpr ImU32 kEstimated = IM_COL32(60, 160, 255, 255);
constexpr ImU32 kCommanded = IM_COL32(255, 170, 40, 255);
constexpr ImU32 kObstacle = IM_COL32(255, 70, 70, 255);
constexpr ImU32 kMarker = IM_COL32(255, 230, 0, 255);

ImTextureID texture_id(unsigned int id) {
  return reinterpret_cast<ImTextureID>(static_cast<std::intptr_t>(id));
}

void draw_image(const ImageTexture& t, const PixelRect& r) {
  ImGui::GetWindowDrawList()->AddImage(texture_id(t.id), ImVec2(r.x, r.y),
                                       ImVec2(r.x + r.width, r.y + r.height));
}

// Overlays: velocities in H seen from behind the camera: H's y (right) to image x and H's z
// (down) to image y, and H's x (forward) as a ring whose size grows with it; then the detected
// markers, projected with a pinhole whose focal length fits the frame's width to a 60 deg
// field of view (the state carries poses, not the camera's intrinsics).
void draw_overlays(const Snapshot& s, const PixelRect& r) {
  ImDrawList* draw = ImGui::GetWindowDrawList();
  draw->PushClipRect(ImVec2(r.x, r.y), ImVec2(r.x + r.width, r.y + r.height), true);
  const ImVec2 centre(r.x + r.width / 2, r.y + r.height / 2);
  const float px_per_mps = r.height / 3.0F;
  const auto overlay = [&](const std::array<float, 3>& v, ImU32 colour) {
    draw_arrow(draw, centre, ImVec2(v[1] * px_per_mps, v[2] * px_per_mps), colour);
    draw->AddCircle(centre, std::abs(v[0]) * px_per_mps * 0.5F + 2, colour, 32,
                    v[0] >= 0 ? 2.0F : 1.0F);
  };
  overlay(s.latest.v_cmd_H_mps, kCommanded);
  overlay(s.latest.v_est_H_mps, kEstimated);
  overlay(s.latest.v_obs_H_mps, kObstacle);
  const float f_px = r.width / (2.0F * std::tan(0.5236F));
  for (std::size_t i = 0; i < s.marker_count; ++i) {
    const MarkerView& mk = s.markers[i];
    if (!(mk.p_camera_marker_m[2] > 0.05F)) continue;
    const ImVec2 c(centre.x + f_px * mk.p_camera_marker_m[0] / mk.p_camera_marker_m[2],
                   centre.y + f_px * mk.p_camera_marker_m[1] / mk.p_camera_marker_m[2]);
    const float half = std::clamp(f_px * 0.08F / mk.p_camera_marker_m[2], 6.0F, 80.0F);
    draw->AddRect(ImVec2(c.x - half, c.y - half), ImVec2(c.x + half, c.y + half), kMarker, 0, 0,
                  2.0F);
    char label[48];
    hq::format_into(label, "id {}  {:.2f} m", mk.id, static_cast<double>(mk.p_camera_marker_m[2]));
    draw->AddText(ImVec2(c.x - half, c.y - half - 16), kMarker, label);
  }
  draw->PopClipRect();
}

}  // namespace

void draw_arrow(ImDrawList* draw, ImVec2 from, ImVec2 v, ImU32 colour) {
  const ImVec2 to(from.x + v.x, from.y + v.y);
  draw->AddLine(from, to, colour, 3.0F);
  const float length = std::hypot(v.x, v.y);
  if (length < 4.0F) return;
  const ImVec2 u(v.x / length, v.y / length);
  const ImVec2 n(-u.y, u.x);
  draw->AddTriangleFilled(to, ImVec2(to.x - 10 * u.x + 5 * n.x, to.y - 10 * u.y + 5 * n.y),
                          ImVec2(to.x - 10 * u.x - 5 * n.x, to.y - 10 * u.y - 5 * n.y), colour);
}

PixelRect fit_image(const PixelRect& area, int image_width_px, int image_height_px) {
  if (area.width <= 0 || area.height <= 0 || image_width_px <= 0 || image_height_px <= 0) {
    return PixelRect{area.x, area.y, 0, 0};
  }
  const float scale = std::min(area.width / static_cast<float>(image_width_px),
                               area.height / static_cast<float>(image_height_px));
  const float w = std::floor(scale * static_cast<float>(image_width_px));
  const float h = std::floor(scale * static_cast<float>(image_height_px));
  return PixelRect{std::floor(area.x + (area.width - w) / 2),
                   std::floor(area.y + (area.height - h) / 2), w, h};
}

CameraPanelResult draw_camera_panel(const Snapshot& s, const ImageTexture& camera,
                                    const ImageTexture& depth, const char* video_line,
                                    const char* size_line) {
  CameraPanelResult result;
  const float line_px = ImGui::GetTextLineHeightWithSpacing();
  // Below the image: the legend line and the video line, always visible.
  const int footer_lines = 2;
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  const ImVec2 avail = ImGui::GetContentRegionAvail();
  const PixelRect area{origin.x, origin.y, avail.x,
                       std::max(avail.y - static_cast<float>(footer_lines) * line_px, 0.0F)};
  if (camera.id == 0) {
    ImGui::TextUnformatted("no camera frame yet");
  } else {
    // The depth preview takes a third of the width when there is one.
    const bool with_depth = depth.id != 0;
    PixelRect camera_area = area;
    if (with_depth) camera_area.width = std::floor(area.width * 0.66F);
    result.image = fit_image(camera_area, camera.width_px, camera.height_px);
    draw_image(camera, result.image);
    if (with_depth) {
      const PixelRect depth_area{area.x + camera_area.width + 6, area.y,
                                 area.width - camera_area.width - 6, area.height};
      draw_image(depth, fit_image(depth_area, depth.width_px, depth.height_px));
    }
    draw_overlays(s, result.image);
    const ImVec2 clip_min = ImGui::GetWindowDrawList()->GetClipRectMin();
    const ImVec2 clip_max = ImGui::GetWindowDrawList()->GetClipRectMax();
    result.image_whole = result.image.width > 0 && result.image.x >= clip_min.x &&
                         result.image.y >= clip_min.y &&
                         result.image.x + result.image.width <= clip_max.x + 0.5F &&
                         result.image.y + result.image.height <= clip_max.y + 0.5F;
    ImGui::GetWindowDrawList()->AddText(ImVec2(result.image.x + 6, result.image.y + 4),
                                        IM_COL32(255, 255, 255, 255),
                                        "arrows: lateral/vertical in H; rings: forward speed");
  }
  ImGui::SetCursorScreenPos(ImVec2(origin.x, origin.y + area.height));
  ImGui::TextColored(ImColor(kCommanded), "commanded");
  ImGui::SameLine();
  ImGui::TextColored(ImColor(kEstimated), "estimated");
  ImGui::SameLine();
  ImGui::TextColored(ImColor(kObstacle), "v_obs");
  ImGui::SameLine();
  ImGui::TextUnformatted(size_line);
  ImGui::TextUnformatted(video_line);
  return result;
}

}  // namespace hq::console
