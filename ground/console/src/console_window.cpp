#include "hq/console/console_window.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/base/log.hpp"
#include "hq/console/position_status.hpp"

#include "alarm.hpp"
#include "camera_panel.hpp"
#include "draw_arrow.hpp"
#include "replay_strip.hpp"
#include "status_bar.hpp"
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <GL/gl.h>
#include <SDL.h>
#include <algorithm>
#include <array>
#include <backends/imgui_impl_opengl3.h>
#include <backends/imgui_impl_sdl.h>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fmt/format.h>
#include <imgui.h>
#include <limits>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

namespace hq::console {

namespace {

using Clock = std::chrono::steady_clock;

constexpr ImU32 kEstimated = IM_COL32(60, 160, 255, 255);
constexpr ImU32 kCommanded = IM_COL32(255, 170, 40, 255);
constexpr ImU32 kObstacle = IM_COL32(255, 70, 70, 255);
constexpr ImU32 kGrid = IM_COL32(90, 90, 90, 255);
constexpr ImU32 kTruth = IM_COL32(120, 230, 120, 255);
constexpr ImU32 kMarker = IM_COL32(255, 230, 0, 255);
constexpr ImU32 kStale = IM_COL32(120, 120, 120, 255);
constexpr ImU32 kCameraAxis = IM_COL32(255, 200, 60, 255);
/// The newest vehicle state older than this: its fields are greyed and marked STALE.
constexpr double kStaleAfterS = 0.5;
/// The panels' background: the frame is cleared to it and the windows draw none, so that
/// the software renderer fills the screen once, not once more per panel.
constexpr float kBackground[3] = {0.06F, 0.06F, 0.07F};

// One GL texture holding a decoded image.
struct Texture {
  GLuint id = 0;
  int width_px = 0;
  int height_px = 0;
  void upload(const cv::Mat& rgb) {
    if (id == 0) glGenTextures(1, &id);
    glBindTexture(GL_TEXTURE_2D, id);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, static_cast<GLint>(rgb.step[0] / 3));
    if (rgb.cols != width_px || rgb.rows != height_px) {
      glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB, rgb.cols, rgb.rows, 0, GL_RGB, GL_UNSIGNED_BYTE,
                   rgb.data);
      width_px = rgb.cols;
      height_px = rgb.rows;
    } else {
      glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, rgb.cols, rgb.rows, GL_RGB, GL_UNSIGNED_BYTE,
                      rgb.data);
    }
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
  }
  ~Texture() {
    if (id != 0) glDeleteTextures(1, &id);
  }
};

// JPEG (and depth preview) decoding on its own thread into a double buffer: the UI thread
// submits the latest bytes (a copy into a buffer sized once) and uploads the newest finished
// image; the decoder writes only the buffer the UI is not allowed to read. A frame submitted
// while another decodes replaces any still waiting (the newest is the one worth showing).
// Milliseconds in 1 ms bins up to 5 s, sized once (the UI thread adds, allocation-free).
class MsHistogram {
 public:
  void add(std::int64_t ns) {
    const std::int64_t bin = std::clamp<std::int64_t>(ns / 1'000'000, 0, kBins - 1);
    ++bins_[static_cast<std::size_t>(bin)];
    ++count_;
  }
  [[nodiscard]] double quantile_ms(double q) const {
    if (count_ == 0) return -1.0;
    const auto target = std::max<std::int64_t>(
        static_cast<std::int64_t>(std::ceil(q * static_cast<double>(count_))), 1);
    std::int64_t seen = 0;
    for (std::size_t i = 0; i < bins_.size(); ++i) {
      seen += bins_[i];
      if (seen >= target) return static_cast<double>(i + 1);
    }
    return static_cast<double>(kBins);
  }

 private:
  static constexpr std::int64_t kBins = 5000;
  std::array<std::uint32_t, kBins> bins_{};
  std::int64_t count_ = 0;
};

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

class FrameDecoder {
 public:
  FrameDecoder() : worker_([this] { run(); }) {}
  ~FrameDecoder() {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_one();
    worker_.join();
  }
  FrameDecoder(const FrameDecoder&) = delete;
  FrameDecoder& operator=(const FrameDecoder&) = delete;

  void submit(std::uint64_t sequence, const std::uint8_t* jpeg, std::size_t jpeg_size,
              const std::uint8_t* depth, std::size_t depth_size, std::int64_t exposure_ns,
              std::int64_t receipt_ns) {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      pending_exposure_ns_ = exposure_ns;
      pending_receipt_ns_ = receipt_ns;
      if (pending_jpeg_.size() < jpeg_size) pending_jpeg_.resize(jpeg_size);  // first frames
      if (pending_depth_.size() < depth_size) pending_depth_.resize(depth_size);
      std::copy_n(jpeg, jpeg_size, pending_jpeg_.begin());
      std::copy_n(depth, depth_size, pending_depth_.begin());
      pending_jpeg_size_ = jpeg_size;
      pending_depth_size_ = depth_size;
      pending_sequence_ = sequence;
    }
    wake_.notify_one();
  }

  // UI thread (GL context): uploads the newest decoded frame if it is not `uploaded` yet.
  void upload_latest(std::uint64_t& uploaded, Texture& camera, Texture& depth, WindowStats& stats) {
    const std::lock_guard<std::mutex> lock(mutex_);
    stats.camera_frames_decoded = frames_decoded_;
    stats.camera_decode_failures = decode_failures_;
    stats.depth_frames_decoded = depth_decoded_;
    if (ready_ < 0 || ready_sequence_ == uploaded) return;
    uploaded = ready_sequence_;
    const Slot& slot = slots_[static_cast<std::size_t>(ready_)];
    camera.upload(slot.rgb);
    stats.camera_width_px = slot.rgb.cols;
    stats.camera_height_px = slot.rgb.rows;
    if (slot.has_depth) depth.upload(slot.depth_rgb);
    // Displayed from this UI frame on: the end of the video latency.
    const std::int64_t shown_ns = monotonic_ns();
    if (slot.exposure_ns >= 0 && slot.receipt_ns >= 0) {
      video_.add(shown_ns - slot.exposure_ns);
      link_.add(slot.receipt_ns - slot.exposure_ns);
      decode_.add(slot.decoded_ns - slot.receipt_ns);
      display_.add(shown_ns - slot.decoded_ns);
      stats.video_last_ms = 1e-6 * static_cast<double>(shown_ns - slot.exposure_ns);
      stats.video_p50_ms = video_.quantile_ms(0.5);
      stats.video_p99_ms = video_.quantile_ms(0.99);
      stats.video_link_p50_ms = link_.quantile_ms(0.5);
      stats.video_decode_p50_ms = decode_.quantile_ms(0.5);
      stats.video_display_p50_ms = display_.quantile_ms(0.5);
    }
  }

 private:
  struct Slot {
    cv::Mat rgb;
    cv::Mat depth_rgb;
    bool has_depth = false;
    std::int64_t exposure_ns = -1;
    std::int64_t receipt_ns = -1;
    std::int64_t decoded_ns = -1;
  };

  void run() {
    std::vector<std::uint8_t> jpeg;
    std::vector<std::uint8_t> depth;
    cv::Mat bgr;
    for (;;) {
      std::uint64_t sequence = 0;
      std::int64_t exposure_ns = -1;
      std::int64_t receipt_ns = -1;
      std::size_t jpeg_size = 0;
      std::size_t depth_size = 0;
      int back = 0;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [this] { return stop_ || pending_sequence_ != taken_sequence_; });
        if (stop_) return;
        taken_sequence_ = pending_sequence_;
        sequence = pending_sequence_;
        exposure_ns = pending_exposure_ns_;
        receipt_ns = pending_receipt_ns_;
        jpeg.swap(pending_jpeg_);
        depth.swap(pending_depth_);
        jpeg_size = pending_jpeg_size_;
        depth_size = pending_depth_size_;
        back = ready_ == 0 ? 1 : 0;
      }
      Slot& slot = slots_[static_cast<std::size_t>(back)];
      const cv::Mat bytes(1, static_cast<int>(jpeg_size), CV_8UC1, jpeg.data());
      cv::imdecode(bytes, cv::IMREAD_COLOR, &bgr);
      const bool ok = !bgr.empty();
      if (ok) cv::cvtColor(bgr, slot.rgb, cv::COLOR_BGR2RGB);
      slot.has_depth = false;
      if (ok && depth_size > 0) {
        const cv::Mat dbytes(1, static_cast<int>(depth_size), CV_8UC1, depth.data());
        cv::imdecode(dbytes, cv::IMREAD_COLOR, &bgr);
        if (!bgr.empty()) {
          cv::cvtColor(bgr, slot.depth_rgb, cv::COLOR_BGR2RGB);
          slot.has_depth = true;
        }
      }
      // The two byte buffers alternate between submit() and this thread; once both reached
      // the frame size nothing is allocated.
      const std::lock_guard<std::mutex> lock(mutex_);
      if (!ok) {
        ++decode_failures_;
        continue;
      }
      ++frames_decoded_;
      if (slot.has_depth) ++depth_decoded_;
      slot.exposure_ns = exposure_ns;
      slot.receipt_ns = receipt_ns;
      slot.decoded_ns = monotonic_ns();
      ready_ = back;
      ready_sequence_ = sequence;
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::vector<std::uint8_t> pending_jpeg_;
  std::vector<std::uint8_t> pending_depth_;
  std::size_t pending_jpeg_size_ = 0;
  std::size_t pending_depth_size_ = 0;
  std::uint64_t pending_sequence_ = 0;
  std::int64_t pending_exposure_ns_ = -1;
  std::int64_t pending_receipt_ns_ = -1;
  std::uint64_t taken_sequence_ = 0;
  std::array<Slot, 2> slots_;
  int ready_ = -1;
  std::uint64_t ready_sequence_ = 0;
  std::uint64_t frames_decoded_ = 0;
  std::uint64_t decode_failures_ = 0;
  std::uint64_t depth_decoded_ = 0;
  MsHistogram video_;  // UI thread only (upload_latest)
  MsHistogram link_;
  MsHistogram decode_;
  MsHistogram display_;
  std::thread worker_;  ///< Last: starts once everything above exists.
};

// Lines of several series over the plot's time window, in a framed box with a zero line.
struct Series {
  const char* label;
  ImU32 colour;
  float (*value)(const PlotSample&);
};

void draw_plot(const char* title, const Snapshot& s, const Series* series, int series_count,
               float window_s, float height_px, std::vector<ImVec2>& line) {
  ImGui::TextUnformatted(title);
  ImGui::SameLine();
  for (int k = 0; k < series_count; ++k) {
    ImGui::SameLine();
    ImGui::TextColored(ImColor(series[k].colour), " %s", series[k].label);
  }
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  const float width_px = std::max(ImGui::GetContentRegionAvail().x, 50.0F);
  const ImVec2 corner(origin.x + width_px, origin.y + height_px);
  draw->AddRect(origin, corner, kGrid);
  ImGui::Dummy(ImVec2(width_px, height_px));
  if (s.plot_count < 2) return;
  const float t_end = s.plot[s.plot_count - 1].t_s;
  const float t_begin = t_end - window_s;
  std::size_t first = s.plot_count;
  while (first > 0 && s.plot[first - 1].t_s >= t_begin) --first;
  float lo = -0.1F;
  float hi = 0.1F;
  for (std::size_t i = first; i < s.plot_count; ++i) {
    for (int k = 0; k < series_count; ++k) {
      const float v = series[k].value(s.plot[i]);
      if (std::isfinite(v)) {
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
    }
  }
  const float margin = 0.05F * (hi - lo);
  lo -= margin;
  hi += margin;
  const auto x_of = [&](float t) { return origin.x + (t - t_begin) / window_s * width_px; };
  const auto y_of = [&](float v) { return corner.y - (v - lo) / (hi - lo) * height_px; };
  draw->AddLine(ImVec2(origin.x, y_of(0)), ImVec2(corner.x, y_of(0)), kGrid);
  char label[48];
  hq::format_into(label, "{:+.2f}", static_cast<double>(hi));
  draw->AddText(ImVec2(origin.x + 2, origin.y + 1), kGrid, label);
  hq::format_into(label, "{:+.2f}  (last {:.0f} s)", static_cast<double>(lo),
                  static_cast<double>(window_s));
  draw->AddText(ImVec2(origin.x + 2, corner.y - 14), kGrid, label);
  draw->PushClipRect(origin, corner, true);
  // One polyline per run of finite values (a non-finite value, e.g. a sample without truth,
  // breaks the line), at most one vertex per pixel column: a 120 s window is ~4000 samples on
  // ~1000 pixels, and every vertex costs the software renderer.
  const auto flush = [&](ImU32 colour) {
    if (line.size() >= 2) {
      draw->AddPolyline(line.data(), static_cast<int>(line.size()), colour, ImDrawFlags_None, 1.5F);
    }
    line.clear();
  };
  for (int k = 0; k < series_count; ++k) {
    line.clear();
    for (std::size_t i = first; i < s.plot_count; ++i) {
      const float value = series[k].value(s.plot[i]);
      if (!std::isfinite(value)) {
        flush(series[k].colour);
        continue;
      }
      const ImVec2 p(x_of(s.plot[i].t_s), y_of(value));
      if (!line.empty() && p.x - line.back().x < 1.0F && i + 1 < s.plot_count) continue;
      line.push_back(p);  // capacity reserved once: no allocation per frame
    }
    flush(series[k].colour);
  }
  draw->PopClipRect();
}

// A bar centred on zero with a mark there: empty is zero force, full left/right the negative/
// positive full scale.
void centred_bar(const char* label, float value, float full_scale, float bar_width) {
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  const float width = std::max(bar_width, 40.0F);
  const float height = ImGui::GetFrameHeight();
  ImGui::Dummy(ImVec2(width, height));
  const ImVec2 corner(origin.x + width, origin.y + height);
  draw->AddRectFilled(origin, corner, IM_COL32(40, 40, 48, 255));
  const float mid = origin.x + width / 2;
  const float fraction = std::isfinite(value) ? std::clamp(value / full_scale, -1.0F, 1.0F) : 0.0F;
  const float end = mid + fraction * width / 2;
  draw->AddRectFilled(ImVec2(std::min(mid, end), origin.y + 2),
                      ImVec2(std::max(mid, end), corner.y - 2), kCommanded);
  draw->AddLine(ImVec2(mid, origin.y), ImVec2(mid, corner.y), IM_COL32(255, 255, 255, 255), 2.0F);
  char text[48];
  hq::format_into(text, "{} {:+.2f} N", label, static_cast<double>(value));
  draw->AddText(ImVec2(origin.x + 4, origin.y + 2), IM_COL32(230, 230, 230, 255), text);
}

struct SavedPlacement {
  int x = 0;
  int y = 0;
  int width = 0;
  int height = 0;
};

std::optional<SavedPlacement> read_placement(const std::string& path) {
  if (path.empty()) return std::nullopt;
  std::FILE* f = std::fopen(path.c_str(), "r");
  if (f == nullptr) return std::nullopt;
  SavedPlacement p;
  const int n = std::fscanf(f, "window %d %d %d %d", &p.x, &p.y, &p.width, &p.height);
  std::fclose(f);
  if (n != 4 || p.width <= 0 || p.height <= 0) return std::nullopt;
  return p;
}

void write_placement(const std::string& path, const SavedPlacement& p) {
  if (path.empty()) return;
  std::error_code error;
  std::filesystem::create_directories(std::filesystem::path(path).parent_path(), error);
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) {
    hq::log::error("hq-ground: {}: cannot write the window placement\n", path);
    return;
  }
  fmt::print(f, "window {} {} {} {}\n", p.x, p.y, p.width, p.height);
  std::fclose(f);
}

}  // namespace

std::string default_window_ini_path() {
  if (const char* xdg = std::getenv("XDG_CONFIG_HOME"); xdg != nullptr && xdg[0] != '\0') {
    return std::string(xdg) + "/haptiquad/console.ini";
  }
  if (const char* home = std::getenv("HOME"); home != nullptr && home[0] != '\0') {
    return std::string(home) + "/.config/haptiquad/console.ini";
  }
  return {};
}

std::uint32_t flight_key_for_scancode(int sdl_scancode) {
  switch (sdl_scancode) {
    case SDL_SCANCODE_W:
    case SDL_SCANCODE_UP:
      return kKeyForward;
    case SDL_SCANCODE_S:
    case SDL_SCANCODE_DOWN:
      return kKeyBack;
    case SDL_SCANCODE_Q:
    case SDL_SCANCODE_A:
    case SDL_SCANCODE_LEFT:
      return kKeyYawLeft;
    case SDL_SCANCODE_E:
    case SDL_SCANCODE_D:
    case SDL_SCANCODE_RIGHT:
      return kKeyYawRight;
    case SDL_SCANCODE_PAGEUP:
      return kKeyClimb;
    case SDL_SCANCODE_PAGEDOWN:
      return kKeyDescend;
    default:
      return 0;
  }
}

struct ConsoleWindow::Impl {
  SDL_Window* window = nullptr;
  SDL_GLContext gl = nullptr;
  int marker_target_id = 0;        ///< The marker panel's target id field.
  int vehicle_marker_target = -1;  ///< The vehicle's target the field last took.
  // The heights the status bar, the controls and the link panel took at the last frame: the
  // layout gives them that much (their content depends on the width only), the camera the rest.
  float status_needed_px = 0;
  float control_needed_px = 0;
  float link_needed_px = 0;
  bool imgui_sdl = false;
  bool imgui_gl = false;
  double max_fps = 60;
  WindowOptions options;
  SDL_Rect display{0, 0, 0, 0};
  FlightKeys* flight_keys = nullptr;
  const Timeline* replay = nullptr;  ///< Replay: the strip's timeline.
  Texture camera;
  Texture depth;
  FrameDecoder decoder;
  std::uint64_t submitted_sequence = 0;
  std::uint64_t uploaded_sequence = 0;
  Clock::time_point first_frame{};
  Clock::time_point next_frame{};
  std::array<float, 256> render_ms{};
  WindowStats stats;
  std::vector<std::uint8_t> pixels;
  float plot_window_s = 20.0F;
  std::vector<ImVec2> polyline;  ///< A plot's line, reserved once at the plot's capacity.
  std::unique_ptr<AlarmTone> alarm;
  AlarmMute alarm_mute;
  bool mute_key = false;  ///< B pressed this frame.

  // Hands a new frame's bytes to the decoder thread, and uploads whatever it finished since;
  // the UI thread does only the copy and the texture upload, never the JPEG decode.
  void decode(const Snapshot& s) {
    if (s.camera_sequence != submitted_sequence && s.jpeg_size > 0) {
      submitted_sequence = s.camera_sequence;
      decoder.submit(s.camera_sequence, s.jpeg.data(), s.jpeg_size, s.depth.data(), s.depth_size,
                     s.camera_exposure_ns, s.camera_receipt_ns);
    }
    decoder.upload_latest(uploaded_sequence, camera, depth, stats);
  }

  void camera_panel(const Snapshot& s) {
    ImGui::Begin("Camera", nullptr,
                 ImGuiWindowFlags_NoScrollbar | ImGuiWindowFlags_NoScrollWithMouse);
    char video[160] = "";
    if (stats.video_p50_ms >= 0) {
      hq::format_into(video,
                      "video {:.0f} ms (p50 {:.0f}, p99 {:.0f}): vehicle+link {:.0f}, decode "
                      "{:.0f}, display {:.0f}",
                      stats.video_last_ms, stats.video_p50_ms, stats.video_p99_ms,
                      stats.video_link_p50_ms, stats.video_decode_p50_ms,
                      stats.video_display_p50_ms);
    }
    char size[80];
    hq::format_into(size, "  {} x {}, {} frames", stats.camera_width_px, stats.camera_height_px,
                    static_cast<unsigned long long>(stats.camera_frames_decoded));
    const CameraPanelResult shown =
        draw_camera_panel(s, ImageTexture{camera.id, camera.width_px, camera.height_px},
                          ImageTexture{depth.id, depth.width_px, depth.height_px}, video, size);
    stats.camera_image_whole = shown.image_whole;
    stats.camera_shown_x_px = static_cast<int>(shown.image.x);
    stats.camera_shown_y_px = static_cast<int>(shown.image.y);
    stats.camera_shown_width_px = static_cast<int>(shown.image.width);
    stats.camera_shown_height_px = static_cast<int>(shown.image.height);
    ImGui::End();
  }

  void plots_panel(const Snapshot& s) {
    ImGui::Begin("Plots (Fig. 6-8)", nullptr, ImGuiWindowFlags_NoScrollbar);
    if (polyline.capacity() < s.plot.size()) polyline.reserve(s.plot.size());
    ImGui::SliderFloat("window s", &plot_window_s, 5.0F, 120.0F, "%.0f");
    const float h = std::max((ImGui::GetContentRegionAvail().y - 7 * 22) / 6, 40.0F);
    static const char* const kAxes[3] = {"v_x H [m/s]", "v_y H [m/s]", "climb [m/s], up +"};
    // Simulator truth is the third series, drawn only once some state carried it.
    constexpr float kNone = std::numeric_limits<float>::quiet_NaN();
    static const Series kVx[3] = {
        {"estimated", kEstimated, [](const PlotSample& p) { return p.v_est_H_mps[0]; }},
        {"commanded", kCommanded, [](const PlotSample& p) { return p.v_cmd_H_mps[0]; }},
        {"truth (sim)", kTruth,
         [](const PlotSample& p) { return p.truth_valid ? p.v_truth_H_mps[0] : kNone; }}};
    static const Series kVy[3] = {
        {"estimated", kEstimated, [](const PlotSample& p) { return p.v_est_H_mps[1]; }},
        {"commanded", kCommanded, [](const PlotSample& p) { return p.v_cmd_H_mps[1]; }},
        {"truth (sim)", kTruth,
         [](const PlotSample& p) { return p.truth_valid ? p.v_truth_H_mps[1] : kNone; }}};
    // H is NED (z down): the climb is -v_z, plotted up positive as the operator reads it.
    static const Series kVz[3] = {
        {"estimated", kEstimated, [](const PlotSample& p) { return -p.v_est_H_mps[2]; }},
        {"commanded", kCommanded, [](const PlotSample& p) { return -p.v_cmd_H_mps[2]; }},
        {"truth (sim)", kTruth,
         [](const PlotSample& p) { return p.truth_valid ? -p.v_truth_H_mps[2] : kNone; }}};
    const int velocity_series = s.have_truth ? 3 : 2;
    static const Series kObs[3] = {
        {"x", kObstacle, [](const PlotSample& p) { return p.v_obs_H_mps[0]; }},
        {"y", IM_COL32(255, 140, 200, 255), [](const PlotSample& p) { return p.v_obs_H_mps[1]; }},
        {"z", IM_COL32(200, 200, 80, 255), [](const PlotSample& p) { return p.v_obs_H_mps[2]; }}};
    static const Series kYaw[2] = {
        {"measured", kEstimated, [](const PlotSample& p) { return p.yaw_rate_meas_radps; }},
        {"commanded", kCommanded, [](const PlotSample& p) { return p.yaw_rate_cmd_radps; }}};
    static const Series kLatency[3] = {
        {"one way", IM_COL32(160, 220, 160, 255), [](const PlotSample& p) { return p.latency_ms; }},
        {"state age", IM_COL32(240, 200, 90, 255),
         [](const PlotSample& p) { return p.state_age_ms; }},
        {"round trip", IM_COL32(230, 120, 120, 255),
         [](const PlotSample& p) { return p.round_trip_ms; }}};
    draw_plot(kAxes[0], s, kVx, velocity_series, plot_window_s, h, polyline);
    draw_plot(kAxes[1], s, kVy, velocity_series, plot_window_s, h, polyline);
    draw_plot(kAxes[2], s, kVz, velocity_series, plot_window_s, h, polyline);
    draw_plot("v_obs H [m/s]", s, kObs, 3, plot_window_s, h, polyline);
    draw_plot("yaw rate [rad/s]", s, kYaw, 2, plot_window_s, h, polyline);
    draw_plot("latency [ms]", s, kLatency, 3, plot_window_s, h, polyline);
    stats.plot_samples_drawn = s.plot_count;
    ImGui::End();
  }

  // The markers the camera sees, placed in W through R_QC, p_QC and the vehicle's pose.
  template <typename ToPx>
  void top_view_markers(ImDrawList* draw, const Snapshot& s, const ToPx& to_px) const {
    const float yaw = s.yaw_W_rad;
    const std::array<float, 9>& R = options.R_B_C;
    for (std::size_t i = 0; i < s.marker_count; ++i) {
      const std::array<float, 3>& c = s.markers[i].p_camera_marker_m;
      const float qx = R[0] * c[0] + R[1] * c[1] + R[2] * c[2] + options.p_B_C_m[0];
      const float qy = R[3] * c[0] + R[4] * c[1] + R[5] * c[2] + options.p_B_C_m[1];
      const float x_W = s.position_W.x_W_m + std::cos(yaw) * qx - std::sin(yaw) * qy;
      const float y_W = s.position_W.y_W_m + std::sin(yaw) * qx + std::cos(yaw) * qy;
      const ImVec2 mp = to_px(x_W, y_W);
      draw->AddRect(ImVec2(mp.x - 5, mp.y - 5), ImVec2(mp.x + 5, mp.y + 5), kMarker, 0, 0, 2.0F);
      char id[16];
      hq::format_into(id, "{}", s.markers[i].id);
      draw->AddText(ImVec2(mp.x + 7, mp.y - 7), kMarker, id);
    }
  }

  // The top view's legend. Two short lines so that a narrow panel does not cut the yaw off.
  static void top_view_legend(ImDrawList* draw, ImVec2 origin, const Snapshot& s) {
    char text[160];
    if (s.position_lost) {
      // The vehicle's pose is invalid: say why; the greyed dot is the last valid position.
      char reason[96];
      hq::format_into(text, "POSITION LOST: {}; grey: last valid position",
                      position_invalid_text(s.position_invalid_reason, s.position_age_s,
                                            s.position_sigma_m, reason, sizeof reason));
      draw->AddText(ImVec2(origin.x + 4, origin.y + 4), IM_COL32(255, 150, 40, 255), text);
    } else {
      hq::format_into(text, "{}; grid 1 m, north up",
                      s.position_from_vehicle ? "vehicle position" : "DEAD-RECKONED (drifts)");
      draw->AddText(ImVec2(origin.x + 4, origin.y + 4), IM_COL32(220, 220, 220, 255), text);
    }
    hq::format_into(text, "x {:.2f} m  y {:.2f} m  yaw {:.0f} deg  {} obstacle pts",
                    static_cast<double>(s.position_W.x_W_m),
                    static_cast<double>(s.position_W.y_W_m),
                    static_cast<double>(s.yaw_W_rad) * 57.29578, s.cloud_count);
    draw->AddText(ImVec2(origin.x + 4, origin.y + 4 + ImGui::GetFontSize()),
                  IM_COL32(220, 220, 220, 255), text);
    draw->AddText(ImVec2(origin.x + 4, origin.y + 4 + 2 * ImGui::GetFontSize()),
                  IM_COL32(255, 255, 255, 255), "white: body x");
    draw->AddText(ImVec2(origin.x + 4, origin.y + 4 + 3 * ImGui::GetFontSize()), kCameraAxis,
                  "yellow: camera axis, W flies it");
  }

  void top_view_panel(const Snapshot& s) {
    // A fixed window name (ImGui keys windows by it); what the track is comes in the text.
    ImGui::Begin("Top view");
    ImDrawList* draw = ImGui::GetWindowDrawList();
    const ImVec2 origin = ImGui::GetCursorScreenPos();
    const ImVec2 size(std::max(ImGui::GetContentRegionAvail().x, 50.0F),
                      std::max(ImGui::GetContentRegionAvail().y, 50.0F));
    const ImVec2 corner(origin.x + size.x, origin.y + size.y);
    draw->AddRectFilled(origin, corner, IM_COL32(20, 25, 20, 255));
    ImGui::Dummy(size);
    // Extent of the track and cloud, square metres per pixel, north (x_W) up, east right.
    float min_x = s.position_W.x_W_m - 1;
    float max_x = s.position_W.x_W_m + 1;
    float min_y = s.position_W.y_W_m - 1;
    float max_y = s.position_W.y_W_m + 1;
    for (std::size_t i = 0; i < s.track_count; ++i) {
      min_x = std::min(min_x, s.track[i].x_W_m);
      max_x = std::max(max_x, s.track[i].x_W_m);
      min_y = std::min(min_y, s.track[i].y_W_m);
      max_y = std::max(max_y, s.track[i].y_W_m);
    }
    const float m_span = std::max(max_x - min_x, max_y - min_y) * 1.2F;
    const float px_per_m = std::min(size.x, size.y) / m_span;
    const ImVec2 mid(origin.x + size.x / 2, origin.y + size.y / 2);
    const float cx = (min_x + max_x) / 2;
    const float cy = (min_y + max_y) / 2;
    const auto to_px = [&](float x, float y) {
      return ImVec2(mid.x + (y - cy) * px_per_m, mid.y - (x - cx) * px_per_m);
    };
    draw->PushClipRect(origin, corner, true);
    for (float g = std::floor(min_x - m_span); g <= max_x + m_span; g += 1.0F) {
      draw->AddLine(to_px(g, min_y - m_span), to_px(g, max_y + m_span), IM_COL32(45, 55, 45, 255));
    }
    for (float g = std::floor(min_y - m_span); g <= max_y + m_span; g += 1.0F) {
      draw->AddLine(to_px(min_x - m_span, g), to_px(max_x + m_span, g), IM_COL32(45, 55, 45, 255));
    }
    // The obstacle points stay out of the legend's four lines at the top.
    draw->PushClipRect(ImVec2(origin.x, origin.y + 4 * ImGui::GetFontSize() + 8), corner, true);
    for (std::size_t i = 0; i < s.cloud_count; ++i) {
      const ImVec2 q = to_px(s.cloud_W[i].x_W_m, s.cloud_W[i].y_W_m);
      draw->AddRectFilled(q, ImVec2(q.x + 2, q.y + 2), kObstacle);
    }
    draw->PopClipRect();
    // The previous vehicle session's trail, greyed: history, not where this vehicle is.
    for (std::size_t i = 1; i < s.previous_track_count; ++i) {
      draw->AddLine(to_px(s.previous_track[i - 1].x_W_m, s.previous_track[i - 1].y_W_m),
                    to_px(s.previous_track[i].x_W_m, s.previous_track[i].y_W_m),
                    IM_COL32(120, 120, 120, 160), 1.0F);
    }
    for (std::size_t i = 1; i < s.track_count; ++i) {
      draw->AddLine(to_px(s.track[i - 1].x_W_m, s.track[i - 1].y_W_m),
                    to_px(s.track[i].x_W_m, s.track[i].y_W_m), kEstimated, 2.0F);
    }
    const ImVec2 p = to_px(s.position_W.x_W_m, s.position_W.y_W_m);
    // The camera's field of view as a wedge along its axis (W flies along the camera axis,
    // eq. 9's alpha), then the markers it sees placed through R_QC and the heading.
    const float yaw = s.yaw_W_rad;
    const auto camera_yaw =
        static_cast<float>(static_cast<double>(yaw) + options.camera_heading_rad);
    const auto half_fov = static_cast<float>(options.camera_hfov_rad / 2);
    const float reach_px = 0.35F * std::min(size.x, size.y);
    const auto along = [&](float heading, float length) {
      return ImVec2(p.x + std::sin(heading) * length, p.y - std::cos(heading) * length);
    };
    if (s.position_lost) {
      // No pose to draw from: the last valid position, greyed, without heading or view.
      draw->AddCircle(p, 7, IM_COL32(140, 140, 140, 255), 0, 2.0F);
    } else {
      draw->AddTriangleFilled(p, along(camera_yaw - half_fov, reach_px),
                              along(camera_yaw + half_fov, reach_px), IM_COL32(255, 200, 60, 40));
      draw->AddLine(p, along(camera_yaw - half_fov, reach_px), IM_COL32(255, 200, 60, 120));
      draw->AddLine(p, along(camera_yaw + half_fov, reach_px), IM_COL32(255, 200, 60, 120));
      top_view_markers(draw, s, to_px);
      draw->AddCircleFilled(p, 5, IM_COL32(255, 255, 255, 255));
      draw_arrow(draw, p, ImVec2(std::sin(yaw) * 25, -std::cos(yaw) * 25),
                 IM_COL32(255, 255, 255, 255));
      draw_arrow(draw, p, ImVec2(std::sin(camera_yaw) * 40, -std::cos(camera_yaw) * 40),
                 kCameraAxis);
    }
    draw->PopClipRect();
    top_view_legend(draw, origin, s);
    ImGui::End();
  }

  // Laid out from the current size on every frame: a resize re-lays the panels out. The status
  // bar has a fixed height, so nothing below it moves as its values change.
  void draw_panels(const Snapshot& s, UiActions& actions, float W, float H) {
    const AlarmCause cause = alarm_cause(s);
    const bool muted = alarm_mute.update(cause, mute_key);
    mute_key = false;
    if (alarm) alarm->play(muted ? AlarmCause::kNone : cause);
    if (cause != AlarmCause::kNone) ++stats.alarm_frames;
    stats.alarm_cause = to_string(cause);
    stats.alarm_muted = muted;
    stats.alarm_tone_samples = alarm ? alarm->tone_samples() : 0;
    StatusBarInput bar;
    bar.stale_s = stale_s(s);
    bar.alarm = cause;
    bar.alarm_muted = muted;
    bar.audio = alarm && alarm->available();
    bar.audio_status = alarm ? alarm->status().c_str() : "off";
    const float top = std::max(status_bar_height(), status_needed_px);
    const StatusBarActions bar_actions = draw_status_bar(s, bar, W, top);
    status_needed_px = bar_actions.needed_height_px;
    stats.status_bar_whole =
        bar_actions.columns_inside && bar_actions.needed_height_px <= top + 0.5F;
    if (bar_actions.take_off) actions.take_off = true;
    if (bar_actions.toggle_mute) mute_key = true;  // applied on the next frame
    if (bar_actions.take_off_hint) ++stats.take_off_hint_frames;
    if (s.have_state && bar.stale_s < 0) {
      const double climb_mps = -static_cast<double>(s.latest.v_est_H_mps[2]);
      stats.climb_shown_max_mps = std::max(stats.climb_shown_max_mps, climb_mps);
      stats.climb_shown_min_mps = std::min(stats.climb_shown_min_mps, climb_mps);
    }
    const float rest = std::max(H - top, 100.0F);
    const auto place = [&](float x, float y, float width, float height) {
      ImGui::SetNextWindowPos(ImVec2(std::floor(x * W), std::floor(top + y * rest)),
                              ImGuiCond_Always);
      ImGui::SetNextWindowSize(ImVec2(std::floor(width * W), std::floor(height * rest)),
                               ImGuiCond_Always);
    };
    // The left column holds the camera, the controls and the link's figures; the right the
    // plots, the top view and the events. The controls and the link panel get at least what
    // their content took (their force bars and last lines whole down to 1024x640); the camera,
    // scaled whole into its panel, takes the rest.
    const float control_share = std::max(0.32F, control_needed_px / rest);
    const float link_share = std::max(0.22F, link_needed_px / rest);
    const float camera_share = std::max(1.0F - control_share - link_share, 0.1F);
    place(0, 0, 0.45F, camera_share);
    camera_panel(s);
    place(0.45F, 0, 0.55F, 0.58F);
    plots_panel(s);
    place(0, camera_share, 0.45F, control_share);
    control_panel(s, actions);
    place(0, camera_share + control_share, 0.45F, link_share);
    link_panel(s);
    place(0.45F, 0.58F, 0.3F, 0.42F);
    top_view_panel(s);
    place(0.75F, 0.58F, 0.25F, 0.42F);
    events_panel(s);
    link_lost_banner(s, top, W);
    vehicle_ended_banner(s, top, W);
    stats.mode_shown = s.mode;
  }

  // The window's events: quit, the flight keys (keyboard flying), the replay's keys, and the
  // mode keys (T teleop, H hover, L land, M marker, X explore, U take off, Esc quit).
  void poll_events(UiActions& actions) {
    SDL_Event event;
    while (SDL_PollEvent(&event) != 0) {
      ImGui_ImplSDL2_ProcessEvent(&event);
      if (event.type == SDL_QUIT) actions.quit = true;
      if (flight_keys != nullptr) flight_key_event(event);
      const bool typed = event.type == SDL_KEYDOWN && !ImGui::GetIO().WantCaptureKeyboard;
      if (typed && replay != nullptr && event.key.keysym.sym != SDLK_ESCAPE) {
        // Replay: its keys, and no mode requests (there is no vehicle to ask).
        replay_key(event.key.keysym.sym, actions);
        continue;
      }
      if (typed && event.key.repeat == 0) mode_key(event.key.keysym.sym, actions);
    }
  }

  void flight_key_event(const SDL_Event& event) {
    // Key ups always count (a key released over a text field must not stay held).
    const std::uint32_t key = event.type == SDL_KEYDOWN || event.type == SDL_KEYUP
                                  ? flight_key_for_scancode(event.key.keysym.scancode)
                                  : 0;
    if (event.type == SDL_KEYUP) flight_keys->release(key);
    if (event.type == SDL_KEYDOWN && !ImGui::GetIO().WantCaptureKeyboard) flight_keys->press(key);
    if (event.type == SDL_WINDOWEVENT && event.window.event == SDL_WINDOWEVENT_FOCUS_LOST) {
      flight_keys->release_all();
    }
  }

  void mode_key(SDL_Keycode key, UiActions& actions) {
    switch (key) {
      case SDLK_t:
        actions.mode_request = "teleop";
        break;
      case SDLK_h:
        actions.mode_request = "hover";
        break;
      case SDLK_l:
        actions.mode_request = "land";
        break;
      case SDLK_m:
        actions.mode_request = "marker";
        break;
      case SDLK_x:
        actions.mode_request = "explore";
        break;
      case SDLK_u:
        actions.take_off = true;
        break;
      case SDLK_b:
        mute_key = true;
        break;
      case SDLK_ESCAPE:
        actions.quit = true;
        break;
      default:
        break;
    }
  }

  // The frame's render time and the frame rate, then a sleep to the next slot (never a busy
  // wait, the haptic loop and the link share these cores).
  void pace(Clock::time_point begin) {
    const Clock::time_point end = Clock::now();
    render_ms[stats.frames % render_ms.size()] =
        std::chrono::duration<float, std::milli>(end - begin).count();
    ++stats.frames;
    // The link panel shows these: refreshed twice a second, from a copy on the stack.
    if (stats.frames % 30 == 0) render_quantiles(stats);
    const double elapsed_s = std::chrono::duration<double>(end - first_frame).count();
    if (elapsed_s > 0) stats.fps = static_cast<double>(stats.frames - 1) / elapsed_s;
    next_frame +=
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / max_fps));
    if (next_frame > end) {
      std::this_thread::sleep_until(next_frame);
    } else {
      next_frame = end;
    }
  }

  // Median and maximum over the last render_ms.size() frames, into `out`; no allocation.
  void render_quantiles(WindowStats& out) const {
    const std::size_t n =
        static_cast<std::size_t>(std::min<std::uint64_t>(stats.frames, render_ms.size()));
    if (n == 0) return;
    std::array<float, 256> sorted = render_ms;
    std::sort(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(n));
    out.render_ms_p50 = sorted[n / 2];
    out.render_ms_max = sorted[n - 1];
  }

  // The floor: one empty ImGui window, no text, no plots, no texture.
  void draw_bare(int w, int h) {
    ImGui::SetNextWindowPos(ImVec2(0, 0), ImGuiCond_Always);
    ImGui::SetNextWindowSize(ImVec2(static_cast<float>(w), static_cast<float>(h)),
                             ImGuiCond_Always);
    ImGui::Begin("Bare", nullptr, ImGuiWindowFlags_NoDecoration);
    ImGui::End();
  }

  /// Seconds since the newest vehicle state when it is stale (> kStaleAfterS), else < 0.
  static double stale_s(const Snapshot& s) {
    if (!s.have_state) return -1.0;
    if (s.link.link_lost) return std::max(s.link.state_age_s, kStaleAfterS);
    return s.link.state_age_s > kStaleAfterS ? s.link.state_age_s : -1.0;
  }

  /// Across the window when the vehicle went silent: its age, on top of everything.
  void link_lost_banner(const Snapshot& s, float top, float width) {
    if (!s.have_state || !s.link.link_lost) return;
    ImDrawList* draw = ImGui::GetForegroundDrawList();
    const float height = 2.2F * ImGui::GetFontSize() + 12;
    draw->AddRectFilled(ImVec2(0, top), ImVec2(width, top + height), IM_COL32(200, 20, 20, 235));
    char text[160];
    hq::format_into(
        text, "VEHICLE LINK LOST {:.1f} s - no vehicle state; everything shown is from before",
        s.link.state_age_s);
    ImFont* font = ImGui::GetFont();
    const float size = 2.0F * ImGui::GetFontSize();
    const ImVec2 extent = font->CalcTextSizeA(size, width, 0, text);
    draw->AddText(font, size, ImVec2(std::max(4.0F, (width - extent.x) / 2), top + 6),
                  IM_COL32(255, 255, 255, 255), text);
    ++stats.link_lost_banner_frames;
  }

  /// Across the window when the vehicle said goodbye: why it ended, calm (it is no alarm).
  void vehicle_ended_banner(const Snapshot& s, float top, float width) {
    char text[200];
    if (s.link.link_lost || !hq::console::vehicle_ended_banner(s.link, text, sizeof text)) return;
    ImDrawList* draw = ImGui::GetForegroundDrawList();
    const float size = 1.4F * ImGui::GetFontSize();
    const float height = size + 12;
    draw->AddRectFilled(ImVec2(0, top), ImVec2(width, top + height), IM_COL32(40, 70, 120, 235));
    ImFont* font = ImGui::GetFont();
    const ImVec2 extent = font->CalcTextSizeA(size, width, 0, text);
    draw->AddText(font, size, ImVec2(std::max(4.0F, (width - extent.x) / 2), top + 6),
                  IM_COL32(255, 255, 255, 255), text);
    ++stats.vehicle_ended_banner_frames;
  }

  // Under the mode buttons: why marker or explore is greyed, in plain words (one line for both
  // when the reason is the same, as it is for a vehicle without its marker stage).
  void modes_off_note(const Snapshot& s) {
    const std::string_view marker = s.marker_mode_off;
    const std::string_view explore = s.explore_mode_off;
    stats.modes_off_note.clear();
    if (marker.empty() && explore.empty()) return;
    if (marker == explore) {
      stats.modes_off_note.append("marker, explore: ").append(marker);
    } else {
      if (!marker.empty()) stats.modes_off_note.append("marker: ").append(marker);
      if (!marker.empty() && !explore.empty()) stats.modes_off_note.append("; ");
      if (!explore.empty()) stats.modes_off_note.append("explore: ").append(explore);
    }
    ImGui::PushTextWrapPos(0);
    ImGui::TextColored(ImVec4(1.0F, 0.75F, 0.3F, 1), "%s", stats.modes_off_note.c_str());
    ImGui::PopTextWrapPos();
  }

  void control_panel(const Snapshot& s, UiActions& actions) {
    ImGui::Begin("Vehicle and modes");
    if (char banner[192]; control_banner(s.link, banner, sizeof banner)) {
      ImGui::TextColored(ImVec4(1, 0.15F, 0.15F, 1), "%s", banner);  // loud: the hand flies nothing
    }
    if (char banner[256]; intrusion_banner(s.link, banner, sizeof banner)) {
      ImGui::PushTextWrapPos(0);  // the certificate to revoke is at the end of a long line
      ImGui::TextColored(ImVec4(1, 0.15F, 0.15F, 1), "%s", banner);
      ImGui::PopTextWrapPos();
    }
    // One line: the controls' force bars must stay in the panel at 1280x800.
    const double stale = stale_s(s);
    ImGui::TextColored(ImColor(stale >= 0 ? kStale : IM_COL32(230, 230, 230, 255)),
                       "roll %+.1f deg  pitch %+.1f deg   source: %s",
                       static_cast<double>(s.roll_rad) * 57.29578,
                       static_cast<double>(s.pitch_rad) * 57.29578, s.source.data());
    // A replay has no vehicle to ask: the requests are greyed out, not live-looking.
    if (s.replay.active) ImGui::TextDisabled("replay: mode requests off (no vehicle to ask)");
    ImGui::BeginDisabled(s.replay.active);
    static const char* const kModes[5] = {"teleop", "hover", "land", "marker", "explore"};
    static const char* const kKeys[5] = {"teleop (T)", "hover (H)", "land (L)", "marker (M)",
                                         "explore (X)"};
    // Greyed before a refusal: the vehicle says in every state which modes it offers.
    const bool marker_on = s.marker_mode_off[0] == '\0';
    const bool explore_on = s.explore_mode_off[0] == '\0';
    stats.marker_button_enabled = marker_on && !s.replay.active;
    stats.explore_button_enabled = explore_on && !s.replay.active;
    for (int i = 0; i < 5; ++i) {
      if (i > 0) ImGui::SameLine();
      const bool off = (i == 3 && !marker_on) || (i == 4 && !explore_on);
      const bool current = s.mode == kModes[i];
      if (current) ImGui::PushStyleColor(ImGuiCol_Button, IM_COL32(40, 130, 60, 255));
      ImGui::BeginDisabled(off);
      if (ImGui::Button(kKeys[i])) actions.mode_request = kModes[i];
      ImGui::EndDisabled();
      if (current) ImGui::PopStyleColor();
    }
    modes_off_note(s);
    ImGui::Text("vehicles seen:");
    for (std::size_t i = 0; i < s.link.vehicle_id_count; ++i) {
      ImGui::SameLine();
      char label[32];
      hq::format_into(label, "{}{}", s.link.vehicle_ids[i] == s.link.selected_vehicle ? "* " : "",
                      s.link.vehicle_ids[i]);
      if (ImGui::Button(label)) {
        actions.select_vehicle = true;
        actions.vehicle_id = s.link.vehicle_ids[i];
      }
    }
    // Marker mode with a chosen target: each button asks for Mode marker with a task.
    ImGui::BeginDisabled(!marker_on);
    ImGui::Text("marker:");
    ImGui::SameLine();
    // The box follows the vehicle's target when that changes (it said 0 while the vehicle
    // flew to 12); the operator's own entry stands until the next change.
    if (s.marker_target_id >= 0 && s.marker_target_id != vehicle_marker_target) {
      marker_target_id = s.marker_target_id;
      vehicle_marker_target = s.marker_target_id;
    }
    ImGui::SetNextItemWidth(100);
    ImGui::InputInt("target id", &marker_target_id);
    marker_target_id = std::max(marker_target_id, 0);
    static const char* const kTasks[3] = {"hold", "goto", "land"};
    static const char* const kTaskLabels[3] = {"Hold", "Go to", "Land on"};
    for (int i = 0; i < 3; ++i) {
      ImGui::SameLine();
      if (ImGui::Button(kTaskLabels[i])) {
        actions.mode_request = "marker";
        actions.marker_task = kTasks[i];
        actions.marker_id = marker_target_id;
      }
    }
    ImGui::EndDisabled();
    ImGui::EndDisabled();
    ImGui::Separator();
    const HapticState& h = s.haptics;
    ImGui::Text("haptic device: %s  buttons 0x%x  %s", h.connected ? "connected" : "LOST",
                h.buttons, h.status.data());
    // F_D's values are on its bars below.
    ImGui::Text("p_D [mm] %+6.1f %+6.1f %+6.1f  cue weight %.2f  passivity %.3f J",
                static_cast<double>(h.p_D_m[0]) * 1e3, static_cast<double>(h.p_D_m[1]) * 1e3,
                static_cast<double>(h.p_D_m[2]) * 1e3, static_cast<double>(h.cue_weight),
                static_cast<double>(h.passivity_energy_j));
    // Force as bars centred on zero, the device's 3 axes (5 N full scale either way), side by
    // side on one line.
    const float gap = ImGui::GetStyle().ItemSpacing.x;
    const float bar_width = (ImGui::GetContentRegionAvail().x - 2 * gap) / 3;
    for (int i = 0; i < 3; ++i) {
      if (i > 0) ImGui::SameLine(0, gap);
      const char label[3] = {'F', "xyz"[i], '\0'};
      centred_bar(label, h.F_D_n[static_cast<std::size_t>(i)], 5.0F, bar_width);
    }
    const ImVec2 clip = ImGui::GetWindowDrawList()->GetClipRectMax();
    stats.force_bars_whole =
        ImGui::GetItemRectMax().y <= clip.y + 0.5F && ImGui::GetItemRectMax().x <= clip.x + 0.5F;
    control_needed_px = content_height();
    stats.control_panel_whole = control_needed_px <= ImGui::GetWindowHeight() + 0.5F;
    ImGui::End();
  }

  // The height the current window's content took so far, with its bottom padding.
  static float content_height() {
    const ImGuiStyle& style = ImGui::GetStyle();
    return ImGui::GetCursorPosY() - style.ItemSpacing.y + style.WindowPadding.y;
  }

  void link_panel(const Snapshot& s) {
    ImGui::Begin("Link health");
    // Long lines wrap in a narrow window rather than lose their end.
    ImGui::PushTextWrapPos(0);
    const LinkHealth& l = s.link;
    // The link's state in the status bar's and the banner's words, not thresholds of its own.
    char state[64];
    link_state_text(s, state, sizeof state);
    ImGui::Text("states: %s (age %.2f s)  heartbeat %s", state, l.state_age_s,
                l.heartbeat_seen ? "seen" : "none");
    ImGui::Text("latency last %.2f ms  p50 %.2f  p99 %.2f", l.last_latency_ms, l.latency_p50_ms,
                l.latency_p99_ms);
    ImGui::Text(
        "round trip %.0f ms (p50 %.0f, p99 %.0f)  state age %.0f ms (p99 %.0f)  "
        "loss %.1f %%",
        l.round_trip_ms, l.round_trip_p50_ms, l.round_trip_p99_ms, l.state_one_way_ms,
        l.state_one_way_p99_ms, l.state_loss_percent);
    ImGui::Text("rates: states %.1f Hz  camera %.1f Hz", l.state_rate_hz, l.camera_rate_hz);
    ImGui::Text("received %llu states, %llu frames, %llu events",
                static_cast<unsigned long long>(l.states),
                static_cast<unsigned long long>(l.camera_frames),
                static_cast<unsigned long long>(l.events));
    ImGui::Text("drops: %llu states missing, %llu rejected; sent %llu commands, %llu failed",
                static_cast<unsigned long long>(l.sequence_gaps),
                static_cast<unsigned long long>(l.states_rejected),
                static_cast<unsigned long long>(l.commands_sent),
                static_cast<unsigned long long>(l.write_failures));
    ImGui::Text("console %.1f fps, render p50 %.1f ms (max %.1f, last 256 frames)", stats.fps,
                stats.render_ms_p50, stats.render_ms_max);
    ImGui::PopTextWrapPos();
    link_needed_px = content_height();
    stats.link_panel_whole = link_needed_px <= ImGui::GetWindowHeight() + 0.5F;
    ImGui::End();
  }

  void events_panel(const Snapshot& s) {
    ImGui::Begin("Events");
    for (std::size_t i = s.event_count; i-- > 0;) {
      const EventLine& e = s.events[i];
      const ImVec4 colour = e.severity >= 2   ? ImVec4(1, 0.4F, 0.4F, 1)
                            : e.severity == 1 ? ImVec4(1, 0.8F, 0.3F, 1)
                                              : ImVec4(0.85F, 0.85F, 0.85F, 1);
      ImGui::PushStyleColor(ImGuiCol_Text, colour);
      ImGui::TextWrapped("%7.2f s  %s", e.t_s, e.text.data());
      ImGui::PopStyleColor();
    }
    ImGui::End();
  }
};

ConsoleWindow::ConsoleWindow(const std::string& title, const WindowOptions& options)
    : impl_(std::make_unique<Impl>()) {
  impl_->max_fps = options.max_fps;
  impl_->options = options;
  if (SDL_Init(SDL_INIT_VIDEO) != 0) {
    throw InputError(std::string("SDL_Init(video): ") + SDL_GetError() +
                     " (no display? use --headless)");
  }
  // Fit the display: at most 1600 x 960, never larger than its usable area, placed inside it;
  // the remembered placement when it still fits (another screen may be smaller).
  SDL_Rect& d = impl_->display;
  if (SDL_GetDisplayUsableBounds(0, &d) != 0 || d.w <= 0 || d.h <= 0) d = {0, 0, 1600, 960};
  int width_px = options.width_px > 0 ? options.width_px : std::min(1600, d.w);
  int height_px = options.height_px > 0 ? options.height_px : std::min(960, d.h);
  int x_px = -1;
  int y_px = -1;
  if (options.width_px <= 0) {
    if (const std::optional<SavedPlacement> saved = read_placement(options.ini_path)) {
      if (saved->width <= d.w && saved->height <= d.h) {
        width_px = saved->width;
        height_px = saved->height;
        x_px = saved->x;
        y_px = saved->y;
      }
    }
  }
  width_px = std::clamp(width_px, 320, d.w);
  height_px = std::clamp(height_px, 240, d.h);
  if (x_px < d.x || x_px + width_px > d.x + d.w) x_px = d.x + (d.w - width_px) / 2;
  if (y_px < d.y || y_px + height_px > d.y + d.h) y_px = d.y + (d.h - height_px) / 2;
  impl_->stats.display_width_px = d.w;
  impl_->stats.display_height_px = d.h;
  SDL_GL_SetAttribute(SDL_GL_CONTEXT_FLAGS, 0);
  SDL_GL_SetAttribute(SDL_GL_CONTEXT_PROFILE_MASK, SDL_GL_CONTEXT_PROFILE_CORE);
  SDL_GL_SetAttribute(SDL_GL_CONTEXT_MAJOR_VERSION, 3);
  SDL_GL_SetAttribute(SDL_GL_CONTEXT_MINOR_VERSION, 3);
  SDL_GL_SetAttribute(SDL_GL_DOUBLEBUFFER, 1);
  impl_->window = SDL_CreateWindow(title.c_str(), x_px, y_px, width_px, height_px,
                                   SDL_WINDOW_OPENGL | SDL_WINDOW_RESIZABLE | SDL_WINDOW_SHOWN);
  if (impl_->window == nullptr) {
    const std::string error = SDL_GetError();
    SDL_Quit();
    throw InputError("SDL_CreateWindow: " + error);
  }
  impl_->gl = SDL_GL_CreateContext(impl_->window);
  if (impl_->gl == nullptr) {
    const std::string error = SDL_GetError();
    SDL_DestroyWindow(impl_->window);
    SDL_Quit();
    throw InputError("SDL_GL_CreateContext(3.3 core): " + error);
  }
  SDL_GL_MakeCurrent(impl_->window, impl_->gl);
  SDL_GL_SetSwapInterval(0);  // the frame cap below paces; vsync would also block on Xvfb
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;  // the layout below, not a file in the working dir
  ImGui::StyleColorsDark();
  // The panels draw no background of their own over the cleared frame (kBackground).
  ImGui::GetStyle().Colors[ImGuiCol_WindowBg] = ImVec4(0, 0, 0, 0);
  impl_->imgui_sdl = ImGui_ImplSDL2_InitForOpenGL(impl_->window, impl_->gl);
  impl_->imgui_gl = ImGui_ImplOpenGL3_Init("#version 330");
  if (!impl_->imgui_sdl || !impl_->imgui_gl)
    throw InputError("ImGui backend initialisation failed");
  if (!options.bare) impl_->alarm = std::make_unique<AlarmTone>();
  impl_->stats.alarm_audio = impl_->alarm ? impl_->alarm->status() : "off";
  const auto* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  impl_->stats.gl_renderer = renderer != nullptr ? renderer : "?";
}

ConsoleWindow::~ConsoleWindow() {
  if (impl_->flight_keys != nullptr) impl_->flight_keys->set_window_open(false);
  if (impl_->window != nullptr && !impl_->options.ini_path.empty()) {
    SavedPlacement p;
    SDL_GetWindowPosition(impl_->window, &p.x, &p.y);
    SDL_GetWindowSize(impl_->window, &p.width, &p.height);
    write_placement(impl_->options.ini_path, p);
  }
  impl_->camera = Texture{};
  impl_->alarm.reset();  // before SDL_Quit
  if (impl_->imgui_gl) ImGui_ImplOpenGL3_Shutdown();
  if (impl_->imgui_sdl) ImGui_ImplSDL2_Shutdown();
  if (ImGui::GetCurrentContext() != nullptr) ImGui::DestroyContext();
  if (impl_->gl != nullptr) SDL_GL_DeleteContext(impl_->gl);
  if (impl_->window != nullptr) SDL_DestroyWindow(impl_->window);
  SDL_Quit();
}

UiActions ConsoleWindow::frame(const Snapshot& s) {
  Impl& m = *impl_;
  UiActions actions;
  m.poll_events(actions);
  const Clock::time_point begin = Clock::now();
  if (m.stats.frames == 0) {
    m.first_frame = begin;
    m.next_frame = begin;
  }
  m.decode(s);
  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplSDL2_NewFrame();
  ImGui::NewFrame();
  int w = 0;
  int h = 0;
  SDL_GetWindowSize(m.window, &w, &h);
  const float W = static_cast<float>(w);
  // Replay: the timeline strip takes the bottom; the panels share the rest.
  const float H = static_cast<float>(h) - (m.replay != nullptr ? kReplayStripHeightPx : 0.0F);
  if (m.options.bare) {
    m.draw_bare(w, h);
  } else {
    if (m.replay != nullptr) draw_replay_strip(*m.replay, s, actions, 0, H, W);
    m.draw_panels(s, actions, W, H);
  }
  SDL_GetWindowPosition(m.window, &m.stats.x_px, &m.stats.y_px);
  m.stats.width_px = w;
  m.stats.height_px = h;
  ImGui::Render();
  glViewport(0, 0, w, h);
  glClearColor(kBackground[0], kBackground[1], kBackground[2], 1.0F);
  glClear(GL_COLOR_BUFFER_BIT);
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
  if (!m.pixels.empty()) {
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, m.pixels.data());
  }
  SDL_GL_SwapWindow(m.window);
  m.pace(begin);
  return actions;
}

void ConsoleWindow::save_screenshot(const Snapshot& s, const std::string& path) {
  int w = 0;
  int h = 0;
  SDL_GetWindowSize(impl_->window, &w, &h);
  impl_->pixels.assign(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3, 0);
  frame(s);
  const cv::Mat rgb(h, w, CV_8UC3, impl_->pixels.data());
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  cv::flip(bgr, bgr, 0);  // GL rows start at the bottom
  impl_->pixels.clear();
  if (!cv::imwrite(path, bgr)) throw InputError(path + ": cannot write the screenshot (PNG)");
}

void ConsoleWindow::set_flight_keys(FlightKeys* keys) {
  if (impl_->flight_keys != nullptr) impl_->flight_keys->set_window_open(false);
  impl_->flight_keys = keys;
  if (keys != nullptr) keys->set_window_open(true);
}

void ConsoleWindow::set_replay(const Timeline* timeline) { impl_->replay = timeline; }

void ConsoleWindow::queue_key(const std::string& name) {
  const SDL_Keycode key = SDL_GetKeyFromName(name.c_str());
  if (key == SDLK_UNKNOWN) {
    throw InputError("key '" + name + "': not an SDL key name (Space, Left, Right, [, ], T...)");
  }
  SDL_Event event{};
  event.type = SDL_KEYDOWN;
  event.key.state = SDL_PRESSED;
  event.key.keysym.sym = key;
  event.key.keysym.scancode = SDL_GetScancodeFromKey(key);
  event.key.windowID = SDL_GetWindowID(impl_->window);
  SDL_PushEvent(&event);
  event.type = SDL_KEYUP;
  event.key.state = SDL_RELEASED;
  SDL_PushEvent(&event);
}

WindowStats ConsoleWindow::stats() const {
  WindowStats s = impl_->stats;
  impl_->render_quantiles(s);
  return s;
}

}  // namespace hq::console
