// hq-bench-memory: per-frame cost and memory use of the obstacle memory over a long simulated
// flight at 320x240 (the scripted circle of hq-sim in the room world, depth from the simulator's
// RgbdRenderer), beside PCL's own VoxelGrid + RadiusOutlierRemoval on the same frames (the
// peer, on every 10th frame). Not run by ctest.
//   hq-bench-memory [--seconds 600] [--world onboard/sim/worlds/room.yaml] [--config cfg.yaml]
#include "hq/base/program.hpp"
#include "hq/base/quantile.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/estimator/complementary_filter.hpp"
#include "hq/obstacle_memory/obstacle_memory.hpp"
#include "hq/sim/scripted_flight.hpp"
#include "hq/sim/simulator.hpp"

#include <CLI/CLI.hpp>
#include <pcl/filters/radius_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fmt/format.h>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

namespace {

using SteadyClock = std::chrono::steady_clock;

double ms_between(SteadyClock::time_point a, SteadyClock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

long rss_kib() {
  std::ifstream status("/proc/self/status");
  std::string key;
  while (status >> key) {
    if (key == "VmRSS:") {
      long kib = 0;
      status >> kib;
      return kib;
    }
  }
  return -1;
}

/// The peer: the same frame through PCL's filters, cloud building included as in the memory.
double pcl_peer_ms(const cv::Mat& depth, const hq::geometry::PinholeCamera& camera,
                   const Eigen::Isometry3d& T_O_C, const hq::obstacle_memory::MemoryConfig& config,
                   pcl::PointCloud<pcl::PointXYZ>::Ptr& cloud,
                   pcl::PointCloud<pcl::PointXYZ>::Ptr& voxels,
                   pcl::PointCloud<pcl::PointXYZ>& cleaned) {
  const auto start = SteadyClock::now();
  const auto leaf = static_cast<float>(config.leaf_m);
  cloud->clear();
  const Eigen::Isometry3f T_O_C_f = T_O_C.cast<float>();
  for (int v = 0; v < depth.rows; v += config.pixel_stride) {
    const auto* row = depth.ptr<float>(v);
    for (int u = 0; u < depth.cols; u += config.pixel_stride) {
      const float z = row[u];
      const auto z_m = static_cast<double>(z);
      if (!(z_m >= config.min_range_m && z_m <= config.max_range_m)) continue;
      const Eigen::Vector3f p_C = camera.ray(u, v).cast<float>() * z;
      const Eigen::Vector3f p_O = T_O_C_f * p_C;
      cloud->push_back(pcl::PointXYZ(p_O.x(), p_O.y(), p_O.z()));
    }
  }
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(cloud);
  grid.setLeafSize(leaf, leaf, leaf);
  grid.filter(*voxels);
  pcl::RadiusOutlierRemoval<pcl::PointXYZ> outliers;
  outliers.setInputCloud(voxels);
  outliers.setRadiusSearch(1.75 * static_cast<double>(leaf));
  outliers.setMinNeighborsInRadius(config.min_neighbors);
  outliers.filter(cleaned);
  return ms_between(start, SteadyClock::now());
}

/// What one flight measured.
struct FlightFigures {
  std::vector<double> memory_ms, peer_ms;
  int map_size_at_10s = -1;
  int max_map_size = 0;
  long clears = 0;
};

/// The scripted circle for `seconds`, every frame into the memory, every 10th also into PCL.
FlightFigures fly(double seconds, const hq::sim::World& world,
                  const hq::obstacle_memory::MemoryConfig& memory_config,
                  hq::obstacle_memory::ObstacleMemory& memory) {
  const hq::sim::SimConfig sim_config = hq::sim::default_sim_config(320, 240);
  hq::sim::Simulator sim(sim_config, world);
  const hq::sim::FlightScript script =
      hq::sim::script_for_world(world, hq::sim::FlightScript::Kind::kCircle);
  FlightFigures f;
  f.memory_ms.reserve(static_cast<std::size_t>(seconds * 31.0));
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::PointCloud<pcl::PointXYZ>::Ptr voxels(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::PointCloud<pcl::PointXYZ> cleaned;
  cv::Mat image, depth;
  const auto end_ns = static_cast<std::int64_t>(seconds * 1e9);
  for (std::int64_t t_ns = 0; t_ns < end_ns; t_ns += hq::sim::kScriptControlPeriodNs) {
    sim.set_command(hq::sim::scripted_command(sim, script, 1e-9 * static_cast<double>(t_ns)));
    sim.step_to(t_ns);
    if (!sim.camera_due()) continue;
    sim.render_camera(image, depth);
    const hq::sim::TruthState& truth = sim.truth();
    const Eigen::Matrix3d R_H_B =
        hq::estimator::R_H_B_from_tilt(truth.euler_rad.x(), truth.euler_rad.y());
    // The simulator's truth stands in for the odometry: its N is the memory's O here.
    const Eigen::Isometry3d T_O_C = sim.camera_T_N_C();
    const auto t0 = SteadyClock::now();
    const hq::obstacle_memory::MemoryUpdate update =
        memory.update(sim.camera_t_ns(), depth, T_O_C, R_H_B, 1.2);
    const auto t1 = SteadyClock::now();
    f.memory_ms.push_back(ms_between(t0, t1));
    f.max_map_size = std::max(f.max_map_size, update.map_size);
    f.clears += update.cleared ? 1 : 0;
    if (f.map_size_at_10s < 0 && t_ns >= 10'000'000'000) f.map_size_at_10s = update.map_size;
    if (f.memory_ms.size() % 10 == 0) {
      f.peer_ms.push_back(pcl_peer_ms(depth, sim_config.camera.pinhole, T_O_C, memory_config, cloud,
                                      voxels, cleaned));
    }
  }
  return f;
}

int run(int argc, char** argv) {
  CLI::App app{"hq-bench-memory: obstacle memory cost over a simulated flight"};
  double seconds = 600.0;
  std::string world_path = "onboard/sim/worlds/room.yaml";
  std::string config_path;
  app.add_option("--seconds", seconds, "simulated flight length (s)")
      ->check(CLI::Range(1.0, 7200.0));
  app.add_option("--world", world_path, "world file");
  app.add_option("--config", config_path, "on-board config: its memory section");
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;

  hq::obstacle_memory::MemoryConfig memory_config;
  if (!config_path.empty()) {
    hq::config::StrictMap root(hq::config::load_yaml_file(config_path), config_path);
    hq::config::StrictMap section = root.child("memory");
    hq::obstacle_memory::read_config(section, memory_config);
  }
  const hq::sim::World world = hq::sim::load_world(world_path);
  const hq::sim::SimConfig sim_config = hq::sim::default_sim_config(320, 240);
  const Eigen::Isometry3d& T_B_C = sim_config.camera.T_B_C;
  hq::obstacle_memory::ObstacleMemory memory(memory_config, sim_config.camera.pinhole,
                                             T_B_C.linear(), T_B_C.translation());

  const long rss_start_kib = rss_kib();
  const FlightFigures f = fly(seconds, world, memory_config, memory);
  const long rss_end_kib = rss_kib();

  const double p50 = hq::quantile(f.memory_ms, 0.5);
  const double p99 = hq::quantile(f.memory_ms, 0.99);
  const double peer_p50 = hq::quantile(f.peer_ms, 0.5);
  const double peer_p99 = hq::quantile(f.peer_ms, 0.99);
  fmt::print("hq-bench-memory: {:.0f} s simulated flight, {} frames at 320x240, {}\n", seconds,
             f.memory_ms.size(), world_path);
  fmt::print("{:<46} {:>9} {:>9}\n", "per frame (ms)", "p50", "p99");
  fmt::print("{:<46} {:9.3f} {:9.3f}\n", "ObstacleMemory::update (all of it)", p50, p99);
  fmt::print("{:<46} {:9.3f} {:9.3f}\n", "peer: cloud + pcl::VoxelGrid + RadiusOutlierRem.",
             peer_p50, peer_p99);
  fmt::print("ratio peer / memory (p50): {:.2f}; target <= 2 ms/frame: {}\n",
             p50 > 0.0 ? peer_p50 / p50 : 0.0, p99 <= 2.0 ? "met (p99)" : "NOT met (p99)");
  fmt::print("map points: at 10 s {}, max {}, at end {} (capacity {}); pose-jump clears {}\n",
             f.map_size_at_10s, f.max_map_size, memory.size(), memory_config.capacity, f.clears);
  fmt::print("memory: buffers {:.2f} MiB (fixed); process RSS {} KiB at start, {} KiB at end\n",
             static_cast<double>(memory.memory_bytes()) / (1024.0 * 1024.0), rss_start_kib,
             rss_end_kib);
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-bench-memory", argc, argv, run); }
