// hq-record: records a live RGB-D camera in the TUM RGB-D layout, so that every tool of the
// project (hq-odometry, hq-onboard --source replay, hq-evaluate) runs on the recording.
#include "hq/base/error.hpp"
#include "hq/base/log.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/sources/camera_sources.hpp"
#include "hq/sources/tum_recorder.hpp"

#include <CLI/CLI.hpp>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <optional>
#include <string>

namespace {
volatile std::sig_atomic_t g_stop = 0;
void request_stop(int /*signal*/) { g_stop = 1; }

std::string kinds_help() {
  std::string text = "camera: openni2[:uri] (device or .oni) | freenect[:index]; in this build: ";
  const auto kinds = hq::sources::available_camera_sources();
  if (kinds.empty()) return text + "none";
  for (std::size_t i = 0; i < kinds.size(); ++i) text += (i ? ", " : "") + kinds[i];
  return text;
}
}  // namespace

static int run(int argc, char** argv) {
  CLI::App app{"Record a live RGB-D camera in the TUM RGB-D layout"};
  std::string spec, out_dir;
  double seconds = 10.0;
  hq::sources::CameraSourceOptions options;
  app.add_option("--source", spec, kinds_help())->required();
  app.add_option("--out", out_dir, "new directory for rgb/, depth/, rgb.txt, depth.txt, ...")
      ->required();
  app.add_option("--seconds", seconds, "recording length (Ctrl-C stops earlier)")
      ->check(CLI::Range(0.1, 86400.0));
  app.add_option("--camera", options.camera_file, "camera file instead of the device's intrinsics");
  app.add_option("--width", options.width, "stream width");
  app.add_option("--height", options.height, "stream height");
  app.add_option("--fps", options.fps, "stream rate");
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;

  const auto source = hq::sources::open_camera_source(spec, options);
  hq::log::note("hq-record: {}\n", source->describe().c_str());
  hq::sources::TumRecorder recorder(out_dir, source->camera(), "hq-record " + spec);
  std::signal(SIGINT, request_stop);
  std::signal(SIGTERM, request_stop);

  const std::int64_t end_ns = hq::monotonic_now_ns() + static_cast<std::int64_t>(1e9 * seconds);
  hq::sources::RgbdFrame frame;
  std::string last_error;
  int accel_samples = 0;
  while (g_stop == 0 && hq::monotonic_now_ns() < end_ns) {
    const hq::sources::FrameStatus status = source->next(frame);
    if (status == hq::sources::FrameStatus::kEndOfStream) break;
    if (status == hq::sources::FrameStatus::kNoFrame) {
      if (source->error() != last_error) hq::log::note("hq-record: {}\n", source->error().c_str());
      last_error = source->error();
      continue;
    }
    last_error.clear();
    recorder.write_frame(frame);
    if (const auto accel = source->accelerometer()) {
      recorder.write_accel(*accel);
      ++accel_samples;
    }
  }
  recorder.close();
  hq::log::note("hq-record: {} frames and {} accelerometer samples written to {}\n",
                recorder.frames(), accel_samples, out_dir.c_str());
  return recorder.frames() > 0 ? 0 : 1;
}

int main(int argc, char** argv) { return hq::run_tool("hq-record", argc, argv, run); }
