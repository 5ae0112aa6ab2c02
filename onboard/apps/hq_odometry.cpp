// hq-odometry: dense RGB-D odometry over a recorded sequence, written as a TUM trajectory.
#include "hq/base/error.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/config/camera_info.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/odometry/dense_odometry.hpp"
#include "hq/recording/tum_io.hpp"
#include "hq/sources/tum_frame_source.hpp"

#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

static int run(int argc, char** argv) {
  CLI::App app{"Dense RGB-D odometry (DVO, Kerl 2013) over a TUM RGB-D sequence"};
  std::string sequence_dir;
  std::string camera_path;
  std::string config_path;
  std::string out_path = "trajectory.txt";
  app.add_option("sequence-dir", sequence_dir, "TUM RGB-D sequence folder")->required();
  app.add_option("--camera", camera_path, "camera file, e.g. calib/tum_fr1.yaml")->required();
  app.add_option("--config", config_path, "YAML with an odometry: section (optional)");
  app.add_option("--out", out_path, "estimated trajectory, TUM format (camera in world)");
  CLI11_PARSE(app, argc, argv);

  hq::odometry::OdometryConfig config;
  if (!config_path.empty()) {
    hq::config::StrictMap root(hq::config::load_yaml_file(config_path), config_path);
    hq::config::StrictMap section = root.child("odometry");
    hq::odometry::read_config(section, config);
  }
  hq::sources::TumFrameSource source(sequence_dir, hq::config::load_camera_info(camera_path));
  hq::odometry::DenseOdometry odometry(config, source.camera());
  std::fprintf(stderr, "hq-odometry: %s\n", source.describe().c_str());

  std::vector<hq::recording::StampedPose> trajectory;
  hq::sources::RgbdFrame frame;
  int lost = 0;
  while (source.next(frame) == hq::sources::FrameStatus::kFrame) {
    const auto start = std::chrono::steady_clock::now();
    const hq::odometry::OdometryResult result =
        odometry.track(frame.t_ns, frame.gray, frame.depth_m);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    if (result.status == hq::odometry::TrackingStatus::kLost) ++lost;
    trajectory.push_back({frame.t_ns, result.T_world_cur});
    std::fprintf(stderr, "frame %4zu  %-11s %6.2f ms  valid %.2f  iterations %2d%s  %s\n",
                 source.position(), hq::odometry::to_string(result.status), ms, result.valid_ratio,
                 result.iterations, result.new_keyframe ? "  keyframe" : "", result.reason);
  }
  hq::recording::write_tum_trajectory(out_path, trajectory);
  std::fprintf(stderr, "hq-odometry: %zu poses written to %s, %d lost\n", trajectory.size(),
               out_path.c_str(), lost);
  return 0;
}

int main(int argc, char** argv) { return hq::run_tool("hq-odometry", argc, argv, run); }
