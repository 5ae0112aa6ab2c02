// hq-bench-markers: AprilTag detection time per 640x480 frame of the simulated marker grid:
// ViSP detection + corner pose, + depth-plane refinement, beside OpenCV's aruco AprilTag 36h11
// detector (corners only) on the same frames, one thread each. Not run by ctest.
//   hq-bench-markers [world.yaml]   (default onboard/sim/worlds/marker_grid.yaml)
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/markers/marker_detector.hpp"
#include "hq/sim/rgbd_renderer.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/world.hpp"

#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fmt/format.h>
#include <functional>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

struct Stats {
  double median_ms = 0;
  double p90_ms = 0;
  double detections_per_frame = 0;
};

Stats time_frames(std::size_t n, const std::function<int(std::size_t)>& detect_frame) {
  std::vector<double> ms;
  int detections = 0;
  for (int pass = 0; pass < 3; ++pass) {
    for (std::size_t i = 0; i < n; ++i) {
      const auto start = Clock::now();
      const int found = detect_frame(i);
      ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count());
      if (pass == 0) detections += found;
    }
  }
  std::sort(ms.begin(), ms.end());
  return {ms[ms.size() / 2], ms[ms.size() * 9 / 10],
          static_cast<double>(detections) / static_cast<double>(n)};
}

int run(int argc, char** argv) {
  CLI::App app{"hq-bench-markers: AprilTag detection time and rate on rendered frames"};
  std::string world_path = "onboard/sim/worlds/marker_grid.yaml";
  app.add_option("world", world_path, "simulator world with markers");
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  const hq::sim::World world = hq::sim::load_world(world_path);
  const hq::sim::CameraParams camera = hq::sim::default_sim_config(640, 480).camera;
  hq::sim::RgbdRenderer renderer(camera, world, 3);
  constexpr std::size_t kFrames = 30;
  std::vector<cv::Mat> images(kFrames);
  std::vector<cv::Mat> grays(kFrames);
  std::vector<cv::Mat> depths(kFrames);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> xy(-1.2, 1.2);
  std::uniform_real_distribution<double> yaw(-M_PI, M_PI);
  for (std::size_t i = 0; i < kFrames; ++i) {
    const Eigen::Vector3d target(xy(rng), xy(rng), 0.0);
    const double a = yaw(rng);
    const Eigen::Vector3d c = target + Eigen::Vector3d(0.8 * std::cos(a), 0.8 * std::sin(a), 1.1);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    const Eigen::Vector3d z = (target - c).normalized();
    const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
    T.linear() << x, z.cross(x), z;
    T.translation() = c;
    renderer.render(T, static_cast<std::uint64_t>(i), images[i], depths[i]);
    cv::cvtColor(images[i], grays[i], cv::COLOR_BGR2GRAY);
  }

  hq::markers::MarkerDetectorConfig image_only;
  image_only.refine_with_depth = false;
  hq::markers::MarkerDetector detector_image(image_only, camera.pinhole);
  hq::markers::MarkerDetector detector_depth(hq::markers::MarkerDetectorConfig{}, camera.pinhole);
  hq::markers::MarkerDetectorConfig decimated;
  decimated.quad_decimate = 2.0;
  hq::markers::MarkerDetector detector_decimated(decimated, camera.pinhole);
  const cv::Ptr<cv::aruco::Dictionary> dictionary =
      cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11);
  const cv::Ptr<cv::aruco::DetectorParameters> parameters = cv::aruco::DetectorParameters::create();
  std::vector<std::vector<cv::Point2f>> corners;
  std::vector<int> ids;

  const Stats visp = time_frames(kFrames, [&](std::size_t i) {
    detector_image.detect(grays[i]);
    return static_cast<int>(detector_image.detections().size());
  });
  const Stats visp_depth = time_frames(kFrames, [&](std::size_t i) {
    detector_depth.detect(grays[i], depths[i]);
    return static_cast<int>(detector_depth.detections().size());
  });
  const Stats visp_decimated = time_frames(kFrames, [&](std::size_t i) {
    detector_decimated.detect(grays[i], depths[i]);
    return static_cast<int>(detector_decimated.detections().size());
  });
  const Stats aruco = time_frames(kFrames, [&](std::size_t i) {
    cv::aruco::detectMarkers(grays[i], dictionary, corners, ids, parameters);
    return static_cast<int>(ids.size());
  });
  fmt::print("hq-bench-markers: {} frames 640x480 of {}, 3 passes, one thread\n", kFrames,
             world_path);
  fmt::print("{:<34} {:>9} {:>9} {:>12} {:>8}\n", "detector", "median ms", "p90 ms", "tags/frame",
             "ratio");
  auto row = [&](const char* name, const Stats& s) {
    fmt::print("{:<34} {:9.2f} {:9.2f} {:12.2f} {:8.2f}\n", name, s.median_ms, s.p90_ms,
               s.detections_per_frame, s.median_ms / aruco.median_ms);
  };
  row("hq ViSP AprilTag + pose", visp);
  row("hq ViSP AprilTag + pose + depth", visp_depth);
  row("hq ... + depth, quad_decimate 2", visp_decimated);
  row("peer: OpenCV aruco 36h11 corners", aruco);
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-bench-markers", argc, argv, run); }
