// hq-odometry: dense RGB-D odometry over a recorded sequence, written as a TUM trajectory.
#include "hq/base/error.hpp"
#include "hq/base/log.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/config/camera_info.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/odometry/dense_odometry.hpp"
#include "hq/recording/tum_io.hpp"
#include "hq/sources/camera_sources.hpp"
#include "hq/sources/tum_frame_source.hpp"

#include <CLI/CLI.hpp>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace {
volatile std::sig_atomic_t g_stop = 0;
void request_stop(int /*signal*/) { g_stop = 1; }

struct Options {
  std::string sequence_dir;
  std::string camera_path;
  std::string config_path;
  std::string source_spec;
  double seconds = 0.0;
  std::string out_path = "trajectory.txt";
};

void add_options(CLI::App& app, Options& o) {
  std::string kinds;
  for (const std::string& kind : hq::sources::available_camera_sources()) {
    kinds += (kinds.empty() ? "" : ", ") + kind;
  }
  app.add_option("sequence-dir", o.sequence_dir, "TUM RGB-D sequence folder");
  app.add_option("--source", o.source_spec,
                 "live camera instead of a sequence: openni2[:uri] | freenect[:index] (this "
                 "build: " +
                     (kinds.empty() ? std::string("none") : kinds) + ")");
  app.add_option("--seconds", o.seconds, "stop a live run after this long (0 = at Ctrl-C)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--camera", o.camera_path,
                 "camera file, e.g. calib/tum_fr1.yaml (required for a sequence; for a camera "
                 "it replaces the device's intrinsics)");
  app.add_option("--config", o.config_path, "YAML with an odometry: section (optional)");
  app.add_option("--out", o.out_path,
                 "estimated trajectory, TUM format (the camera C in the odometry origin O)");
}

hq::odometry::OdometryConfig load_config(const std::string& config_path) {
  hq::odometry::OdometryConfig config;
  if (!config_path.empty()) {
    hq::config::StrictMap root(hq::config::load_yaml_file(config_path), config_path);
    hq::config::StrictMap section = root.child("odometry");
    hq::odometry::read_config(section, config);
    root.finish_sections();
  }
  return config;
}

std::unique_ptr<hq::sources::FrameSource> open_source(const Options& o) {
  if (o.source_spec.empty() == o.sequence_dir.empty()) {
    throw hq::InputError("give either a sequence directory or --source <camera>, not " +
                         std::string(o.sequence_dir.empty() ? "neither" : "both"));
  }
  if (!o.sequence_dir.empty() && o.camera_path.empty()) {
    throw hq::InputError("--camera is required with a sequence directory");
  }
  if (o.source_spec.empty()) {
    return std::make_unique<hq::sources::TumFrameSource>(
        o.sequence_dir, hq::config::load_camera_info(o.camera_path));
  }
  hq::sources::CameraSourceOptions options;
  options.camera_file = o.camera_path;
  std::unique_ptr<hq::sources::FrameSource> camera =
      hq::sources::open_camera_source(o.source_spec, options);
  std::signal(SIGINT, request_stop);
  std::signal(SIGTERM, request_stop);
  return camera;
}

/// Tracks every frame until the end of the stream, --seconds or Ctrl-C; returns the poses
/// T_O_C and counts lost frames.
std::vector<hq::recording::StampedPose> track_all(hq::sources::FrameSource& source,
                                                  hq::odometry::DenseOdometry& odometry,
                                                  double seconds, int& lost) {
  const std::int64_t end_ns = hq::monotonic_now_ns() + static_cast<std::int64_t>(1e9 * seconds);
  std::vector<hq::recording::StampedPose> trajectory;
  hq::sources::RgbdFrame frame;
  std::string last_error;
  while (g_stop == 0 && (seconds <= 0.0 || hq::monotonic_now_ns() < end_ns)) {
    const hq::sources::FrameStatus status = source.next(frame);
    if (status == hq::sources::FrameStatus::kEndOfStream) break;
    if (status == hq::sources::FrameStatus::kNoFrame) {
      // A live camera was lost; the source reopens it on later calls.
      if (source.error() != last_error) {
        hq::log::note("hq-odometry: {}\n", source.error().c_str());
      }
      last_error = source.error();
      continue;
    }
    last_error.clear();
    const std::int64_t start_ns = hq::monotonic_now_ns();
    const hq::odometry::OdometryResult result =
        odometry.track(frame.t_ns, frame.gray, frame.depth_m);
    const double ms = 1e3 * hq::to_seconds(hq::monotonic_now_ns() - start_ns);
    if (result.status == hq::odometry::TrackingStatus::kLost) ++lost;
    trajectory.push_back({frame.t_ns, result.T_O_C});
    hq::log::note("frame {:4}  {:<11} {:6.2f} ms  valid {:.2f}  iterations {:2}{}  {}\n",
                  trajectory.size(), hq::odometry::to_string(result.status), ms, result.valid_ratio,
                  result.iterations, result.new_keyframe ? "  keyframe" : "", result.reason);
  }
  return trajectory;
}

}  // namespace

static int run(int argc, char** argv) {
  CLI::App app{"Dense RGB-D odometry (DVO, Kerl 2013) over a TUM RGB-D sequence or a camera"};
  Options o;
  add_options(app, o);
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;

  const hq::odometry::OdometryConfig config = load_config(o.config_path);
  const std::unique_ptr<hq::sources::FrameSource> source = open_source(o);
  hq::odometry::DenseOdometry odometry(config, source->camera());
  hq::log::note("hq-odometry: {}\n", source->describe().c_str());
  int lost = 0;
  const std::vector<hq::recording::StampedPose> trajectory =
      track_all(*source, odometry, o.seconds, lost);
  hq::recording::write_tum_trajectory(o.out_path, trajectory);
  hq::log::note("hq-odometry: {} poses written to {}, {} lost\n", trajectory.size(),
                o.out_path.c_str(), lost);
  return 0;
}

int main(int argc, char** argv) { return hq::run_tool("hq-odometry", argc, argv, run); }
