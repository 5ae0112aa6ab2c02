// The obstacle memory's map saved at the end of a simulated flight (what
// hq-sim-flight --save-map writes) reads back with PCL's own readers: every point, finite, and
// within the memory's radius of where the vehicle flew.

#include "memory_campaign.hpp"
#include <gtest/gtest.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_types.h>

#include <cstdio>
#include <fmt/format.h>
#include <string>
#include <unistd.h>

namespace hq::closed_loop {
namespace {

using testing::MemoryCase;

TEST(SavedMap, PcdAndPlyReadBackWithTheMemorysPointsInPlausibleBounds) {
  const sim::World room = sim::load_world("onboard/sim/worlds/room.yaml");
  const testing::MemoryRun r = testing::draw_memory_run(MemoryCase::kYawClose, 1, 20261126);
  const testing::Scenario s = testing::memory_scenario(r, true, room);
  auto loop = s.make();
  loop->run();
  const obstacle_memory::ObstacleMemory& memory = loop->chain().memory();
  ASSERT_GT(memory.size(), 100);

  const std::string stem = "/tmp/hq_saved_map_" + std::to_string(getpid());
  for (const std::string ext : {".pcd", ".ply"}) {
    const std::string path = stem + ext;
    memory.save(path);
    pcl::PointCloud<pcl::PointXYZ> cloud;
    const int status =
        ext == ".pcd" ? pcl::io::loadPCDFile(path, cloud) : pcl::io::loadPLYFile(path, cloud);
    std::remove(path.c_str());
    ASSERT_EQ(status, 0) << path;
    EXPECT_EQ(static_cast<int>(cloud.size()), memory.size()) << ext;
    // W is the odometry's world (the camera at the first frame). The vehicle flew less than
    // 2 m from there and the memory forgets beyond radius_m, so no point can be farther than
    // their sum; the box and the floor make the cloud span metres, not a degenerate blob.
    const double reach_m = memory.config().radius_m + 2.0;
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e9F);
    Eigen::Vector3f hi = Eigen::Vector3f::Constant(-1e9F);
    for (const pcl::PointXYZ& p : cloud) {
      const Eigen::Vector3f v(p.x, p.y, p.z);
      ASSERT_TRUE(v.allFinite()) << ext;
      EXPECT_LT(v.norm(), reach_m) << ext;
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
    fmt::print("{}: {} points, bounds [{:.2f} {:.2f} {:.2f}] .. [{:.2f} {:.2f} {:.2f}] m\n", ext,
               cloud.size(), static_cast<double>(lo.x()), static_cast<double>(lo.y()),
               static_cast<double>(lo.z()), static_cast<double>(hi.x()),
               static_cast<double>(hi.y()), static_cast<double>(hi.z()));
    EXPECT_GT((hi - lo).norm(), 1.0) << ext;
  }
}

}  // namespace
}  // namespace hq::closed_loop
