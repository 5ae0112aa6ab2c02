// hq-bench-chain: time from frame arrival to setpoint of the OnboardChain at 640x480 on the
// bundled real frames (TUM fr1_360), per stage, over repeated passes. Not run by ctest.
//   hq-bench-chain [--sequence DIR] [--camera calib/tum_fr1.yaml] [--config config/onboard.yaml]
//                  [--passes 60]
// The frames are decoded once and played back and forth (0 1 2 3 4 3 2 1 0 1 ...), so that
// consecutive frames are always neighbours, stamped 68 ms apart as recorded; the IMU is a level
// body at rest at 200 Hz (timing does not depend on its values). Target: total <= 6 ms median.
// At each reversal the odometry's constant-motion initialisation points the wrong way, so one
// frame per pass exceeds estimator.max_mean_error and the estimator re-seeds and warms up again:
// the "no estimate" counts printed come from the playback, not from the recorded motion.
#include "hq/base/error.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/config/camera_info.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/pipeline/stage_timing.hpp"
#include "hq/pipeline/steady_clock.hpp"
#include "hq/recording/data_dir.hpp"
#include "hq/sources/tum_frame_source.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <fmt/format.h>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace {

using hq::pipeline::SteadyClock;

int run(int argc, char** argv) {
  CLI::App app{"hq-bench-chain: per-stage latency of the on-board chain on real frames"};
  std::string sequence_dir;
  std::string camera_path = "calib/tum_fr1.yaml";
  std::string config_path = "config/onboard.yaml";
  std::string vehicle_path = "calib/vehicle_core_paper.yaml";
  int passes = 60;
  app.add_option("--sequence", sequence_dir, "TUM sequence (default: the bundled fr1_360)");
  app.add_option("--camera", camera_path, "camera file");
  app.add_option("--config", config_path, "on-board config");
  app.add_option("--vehicle", vehicle_path, "vehicle file");
  app.add_option("--passes", passes, "back-and-forth passes over the frames")
      ->check(CLI::Range(1, 100000));
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  if (sequence_dir.empty()) {
    const auto data = hq::recording::find_data_dir();
    if (!data) {
      throw hq::InputError("no --sequence and no real data: " +
                           hq::recording::data_dir_search_description());
    }
    sequence_dir = *data + "/tum/rgbd_dataset_freiburg1_360";
  }
  const hq::config::CameraInfo camera = hq::config::load_camera_info(camera_path);
  hq::sources::TumFrameSource source(sequence_dir, camera);
  std::vector<hq::sources::RgbdFrame> frames;
  for (hq::sources::RgbdFrame frame; source.next(frame) == hq::sources::FrameStatus::kFrame;) {
    frames.push_back({frame.t_ns, frame.bgr.clone(), frame.gray.clone(), frame.depth_m.clone()});
  }
  if (frames.size() < 2) throw hq::InputError(sequence_dir + ": fewer than 2 frames");
  std::vector<std::size_t> order;  // back and forth
  for (int p = 0; p < passes; ++p) {
    for (std::size_t i = 0; i + 1 < frames.size(); ++i) order.push_back(i);
    for (std::size_t i = frames.size() - 1; i > 0; --i) order.push_back(i);
  }

  const SteadyClock clock;
  const hq::pipeline::OnboardConfig config = hq::pipeline::load_onboard_config(config_path);
  const hq::VehicleConfig vehicle = hq::load_vehicle_config(vehicle_path);
  hq::pipeline::OnboardChain chain(config, vehicle, source.camera(), &clock);
  hq::pipeline::StageTimingLog log(order.size());
  constexpr std::int64_t kFramePeriodNs = 68'000'000;
  constexpr std::int64_t kImuPeriodNs = 5'000'000;
  int ok = 0;
  int lost = 0;
  std::vector<std::pair<const char*, int>> reasons;
  reasons.reserve(16);
  for (std::size_t k = 0; k < order.size(); ++k) {
    const std::int64_t t_ns = static_cast<std::int64_t>(k + 1) * kFramePeriodNs;
    for (std::int64_t t = t_ns - kFramePeriodNs + kImuPeriodNs; t <= t_ns; t += kImuPeriodNs) {
      chain.on_imu(t, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 0.0, -9.80665));
    }
    const hq::sources::RgbdFrame& frame = frames[order[k]];
    const hq::pipeline::ChainOutput out = chain.on_frame(t_ns, frame.gray, frame.depth_m);
    if (k > 0) log.add(out.durations);  // the first frame sizes the buffers
    ok += out.estimate.ok() ? 1 : 0;
    if (!out.estimate.ok() && k > 0) {
      // Reasons are static strings: count them by address.
      std::size_t r = 0;
      while (r < reasons.size() && reasons[r].first != out.estimate.reason) ++r;
      if (r == reasons.size()) reasons.emplace_back(out.estimate.reason, 0);
      ++reasons[r].second;
    }
    lost += out.tracking == hq::odometry::TrackingStatus::kLost ? 1 : 0;
  }
  fmt::print("hq-bench-chain: {}, {}x{}, {} frames ({} passes), {} estimates ok, {} lost\n",
             sequence_dir, source.camera().width, source.camera().height, order.size(), passes, ok,
             lost);
  for (const auto& [reason, count] : reasons) {
    fmt::print("  no estimate on {} frames: {}\n", count, reason);
  }
  log.print(stdout);
  const double total_ms = log.statistics(hq::pipeline::kStageCount - 1).median_ms;
  fmt::print("target: total median <= 6 ms on one core: {} ({:.3f} ms)\n",
             total_ms <= 6.0 ? "met" : "MISSED", total_ms);
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-bench-chain", argc, argv, run); }
