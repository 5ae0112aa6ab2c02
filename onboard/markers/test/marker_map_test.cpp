// Marker map: drift of the chained map vs the optimised pose graph on a simulated flight over
// the marker grid; save/load; bad input.
#include "hq/markers/marker_map.hpp"

#include "hq/markers/marker_detector.hpp"
#include "hq/markers/testing/sim_marker_truth.hpp"
#include "hq/sim/rgbd_renderer.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/world.hpp"
#include "hq/testing/input_error.hpp"

#include "sim_views.hpp"
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <random>
#include <vector>

namespace hq::markers {
namespace {

using ::testing::HasSubstr;

struct FrameRecord {
  std::int64_t t_ns = 0;
  std::vector<MarkerDetection> detections;
  Eigen::Isometry3d T_O_C = Eigen::Isometry3d::Identity();
};

constexpr double kOdomSigmaM = 0.004;      // per frame
constexpr double kOdomSigmaRad = 0.004;    // per frame
constexpr double kOdomYawBiasRad = 0.003;  // per frame: a slow heading drift

geometry::Matrix6d odometry_covariance() {
  geometry::Matrix6d c = geometry::Matrix6d::Zero();
  c.diagonal().head<3>().setConstant(kOdomSigmaM * kOdomSigmaM);
  c.diagonal().tail<3>().setConstant(kOdomSigmaRad * kOdomSigmaRad);
  return c;
}

// A lawn-mower flight at 1.1 m over the 5 x 5 grid, camera looking ahead and 50 deg down,
// rendered and detected once; odometry = truth increments with noise and a yaw bias.
class MarkerMapFlight : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    world = new sim::World(sim::load_world("onboard/sim/worlds/marker_grid.yaml"));
    const sim::CameraParams camera = sim::default_sim_config(640, 480).camera;
    sim::RgbdRenderer renderer(camera, *world, 21);
    MarkerDetector detector(MarkerDetectorConfig{}, camera.pinhole);
    frames = new std::vector<FrameRecord>();
    std::mt19937 rng(9);
    std::normal_distribution<double> noise(0.0, 1.0);
    Eigen::Isometry3d T_O_C = Eigen::Isometry3d::Identity();
    Eigen::Isometry3d T_N_C_prev = Eigen::Isometry3d::Identity();
    cv::Mat image;
    cv::Mat depth_m;
    std::uint64_t index = 0;
    for (int row = 0; row < 4; ++row) {
      const double y = -1.5 + row * 1.0;
      const double dir = row % 2 == 0 ? 1.0 : -1.0;
      for (int k = 0; k <= 20; ++k) {
        const double x = dir * (-1.9 + 0.15 * k);
        const Eigen::Vector3d c(x, y, 1.1);
        const Eigen::Isometry3d T_N_C = test::look_at(c, c + Eigen::Vector3d(dir * 0.9, 0.0, -1.1));
        renderer.render(T_N_C, index, image, depth_m);
        FrameRecord f;
        f.t_ns = static_cast<std::int64_t>(index) * 33'333'333;
        detector.detect(image, depth_m);
        f.detections = detector.detections();
        if (index == 0) {
          T_O_C = T_N_C;
        } else {
          geometry::Vector6d xi;
          for (int i = 0; i < 3; ++i) xi(i) = kOdomSigmaM * noise(rng);
          for (int i = 3; i < 6; ++i) xi(i) = kOdomSigmaRad * noise(rng);
          xi(4) += kOdomYawBiasRad;  // camera y is down: a rotation about it is a yaw
          T_O_C = T_O_C * (T_N_C_prev.inverse() * T_N_C) * geometry::exp_se3(xi);
        }
        f.T_O_C = T_O_C;
        T_N_C_prev = T_N_C;
        frames->push_back(f);
        ++index;
      }
    }
  }
  static void TearDownTestSuite() {
    delete world;
    delete frames;
  }

  struct MapError {
    double mean_m = 0;
    double max_m = 0;
    int mapped = 0;
  };
  static MapError error_of(const MarkerMap& map) {
    MapError e;
    const int gauge = map.ids().front();
    Eigen::Isometry3d T_N_W = Eigen::Isometry3d::Identity();
    for (const sim::Marker& m : world->markers) {
      if (m.id == gauge) T_N_W = test::T_N_M(m);
    }
    for (const sim::Marker& m : world->markers) {
      const auto T = map.T_map_marker(m.id);
      if (!T) continue;
      const double err = ((T_N_W * *T).translation() - m.center_N_m).norm();
      e.mean_m += err;
      e.max_m = std::max(e.max_m, err);
      ++e.mapped;
    }
    e.mean_m /= std::max(1, e.mapped);
    return e;
  }
  static MarkerMap build(const MarkerMapConfig& config) {
    MarkerMap map(config);
    for (const FrameRecord& f : *frames) {
      map.add_frame(f.t_ns, f.detections, f.T_O_C, odometry_covariance());
    }
    return map;
  }

  static sim::World* world;
  static std::vector<FrameRecord>* frames;
};
sim::World* MarkerMapFlight::world = nullptr;
std::vector<FrameRecord>* MarkerMapFlight::frames = nullptr;

TEST_F(MarkerMapFlight, OptimisationReducesTheChainedDrift) {
  MarkerMapConfig chained_only;
  chained_only.optimise_every_keyframes = 0;
  MarkerMap map = build(chained_only);
  const MapError before = error_of(map);
  const MapOptimisation run = map.optimise();
  const MapError after = error_of(map);

  MarkerMap incremental = build(MarkerMapConfig{});
  const MapError online = error_of(incremental);

  fmt::print("[ marker map ] {} frames, {} keyframes, {} of {} markers mapped\n", frames->size(),
             map.keyframes(), before.mapped, world->markers.size());
  fmt::print("[ marker map ] chained (before): mean {:.1f} max {:.1f} mm\n", 1e3 * before.mean_m,
             1e3 * before.max_m);
  fmt::print("[ marker map ] incremental     : mean {:.1f} max {:.1f} mm\n", 1e3 * online.mean_m,
             1e3 * online.max_m);
  fmt::print(
      "[ marker map ] optimised       : mean {:.1f} max {:.1f} mm ({} iterations, cost {:.1f} -> "
      "{:.1f})\n",
      1e3 * after.mean_m, 1e3 * after.max_m, run.iterations, run.initial_cost, run.final_cost);
  EXPECT_GE(before.mapped, 20);
  EXPECT_EQ(after.mapped, before.mapped);
  EXPECT_LT(run.final_cost, run.initial_cost);
  EXPECT_LT(after.mean_m, before.mean_m);
  EXPECT_LT(after.max_m, before.max_m);
  // Measured (seed 9): chained 10.5 / 26.6 mm, optimised 3.7 / 10.4 mm mean / max.
  EXPECT_LT(after.mean_m, 0.008);
  EXPECT_LT(after.max_m, 0.02);
  EXPECT_LT(online.mean_m, before.mean_m);
}

TEST_F(MarkerMapFlight, SavedMapLoadsBackIdentically) {
  MarkerMap map = build(MarkerMapConfig{});
  map.optimise();
  std::string path = (std::filesystem::temp_directory_path() / "hq_marker_map.yaml").string();
  map.save(path);
  const MarkerMap loaded = MarkerMap::load(path);
  ASSERT_EQ(loaded.ids(), map.ids());
  for (int id : map.ids()) {
    const Eigen::Isometry3d a = *map.T_map_marker(id);
    const Eigen::Isometry3d b = *loaded.T_map_marker(id);
    EXPECT_LT((a.translation() - b.translation()).norm(), 1e-9);
    EXPECT_LT(test::angle_between_rad(a.linear(), b.linear()), 1e-9);
  }
}

std::string write_temp(const std::string& text) {
  std::string path = (std::filesystem::temp_directory_path() / "hq_map_bad.yaml").string();
  std::ofstream(path) << text;
  return path;
}

TEST(MarkerMapFile, CorruptFilesNameFileAndKey) {
  auto message = [](const std::string& text) {
    const std::string path = write_temp(text);
    return testing::input_error_message([&] { MarkerMap::load(path); });
  };
  EXPECT_THAT(
      message("markers: [{id: 1, p_map_marker_m: [0, 0], q_map_marker_xyzw: [0, 0, 0, 1]}]\n"),
      AllOf(HasSubstr("hq_map_bad.yaml"), HasSubstr("markers[0].p_map_marker_m")));
  EXPECT_THAT(
      message("markers: [{id: 1, p_map_marker_m: [0, 0, 0], q_map_marker_xyzw: [0, 0, 0, 2]}]\n"),
      HasSubstr("markers[0].q_map_marker_xyzw has norm 2"));
  EXPECT_THAT(
      message("markers: [{id: 1, p_map_marker_m: [0, 0, 0], q_map_marker_xyzw: [0, 0, 0, 1]},\n"
              "          {id: 1, p_map_marker_m: [1, 0, 0], q_map_marker_xyzw: [0, 0, 0, 1]}]\n"),
      HasSubstr("markers[1].id = 1, expected each id once"));
  EXPECT_THAT(
      message("markers: [{id: 1, p_map_marker_m: [0, 0, 0], q_map_marker_xyzw: [0, 0, 0, 1], "
              "colour: red}]\n"),
      HasSubstr("markers[0].colour"));
  EXPECT_THAT(message("marker: []\n"), HasSubstr("marker"));
  EXPECT_THAT(
      message("markers: [{id: 1, p_map_marker_m: [0, 0, 0], q_map_marker_xyzw: [0, 0, 0, 1]\n"),
      HasSubstr("hq_map_bad.yaml"));
  EXPECT_THAT(testing::input_error_message([] { MarkerMap::load("/nonexistent/map.yaml"); }),
              HasSubstr("/nonexistent/map.yaml"));
}

TEST(MarkerMap, NonFiniteInputIsRejected) {
  MarkerMap map;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation().x() = std::nan("");
  EXPECT_THAT(testing::input_error_message(
                  [&] { map.add_frame(5, {}, T, geometry::Matrix6d::Identity()); }),
              HasSubstr("t_ns=5"));
  std::vector<MarkerDetection> detections(1);
  detections[0].id = 4;
  detections[0].T_camera_marker = T;
  EXPECT_THAT(testing::input_error_message([&] {
                map.add_frame(6, detections, Eigen::Isometry3d::Identity(),
                              geometry::Matrix6d::Identity());
              }),
              HasSubstr("id 4"));
  EXPECT_TRUE(map.ids().empty());
}

}  // namespace
}  // namespace hq::markers
