#include "hq/obstacle_memory/obstacle_memory.hpp"

#include "hq/config/strict_yaml.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"

#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace hq::obstacle_memory {
namespace {

using ::testing::HasSubstr;
constexpr std::int64_t kFrameNs = 33'333'333;
constexpr double kD0 = 1.2;

geometry::PinholeCamera test_camera() {
  geometry::PinholeCamera camera;
  camera.fx = 277.0;
  camera.fy = 277.0;
  camera.cx = 159.5;
  camera.cy = 119.5;
  camera.width = 320;
  camera.height = 240;
  return camera;
}

// Camera looking along the body's x (forward), level: optical z = body x, x = body y, y = body z.
Eigen::Matrix3d forward_R_B_C() {
  Eigen::Matrix3d R;
  R << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  return R;
}

ObstacleMemory make_memory(const MemoryConfig& config = MemoryConfig{}) {
  return ObstacleMemory(config, test_camera(), forward_R_B_C(), Eigen::Vector3d::Zero());
}

cv::Mat wall(float z_m) { return cv::Mat(240, 320, CV_32FC1, cv::Scalar(z_m)); }
cv::Mat no_depth() { return wall(0.0f); }

// The camera turned right (NED yaw) by yaw_rad about its own y axis (down), at p_O_m.
Eigen::Isometry3d camera_pose(double yaw_rad, const Eigen::Vector3d& p_O_m = {0, 0, 0}) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitY()).matrix();
  T.translation() = p_O_m;
  return T;
}

const Eigen::Matrix3d kLevel = Eigen::Matrix3d::Identity();

TEST(ObstacleMemory, WallInViewIsStoredButNotReturned) {
  ObstacleMemory memory = make_memory();
  const MemoryUpdate update = memory.update(0, wall(1.0f), camera_pose(0.0), kLevel, kD0);
  ASSERT_TRUE(update.updated) << update.reason;
  EXPECT_GT(update.inserted, 100);
  EXPECT_EQ(update.map_size, memory.size());
  EXPECT_EQ(update.count, 0);  // the view's own depth stands for it
}

TEST(ObstacleMemory, WallRememberedOnTheLeftAfterAYawRight) {
  ObstacleMemory memory = make_memory();
  ASSERT_TRUE(memory.update(0, wall(1.0f), camera_pose(0.0), kLevel, kD0).updated);
  // GIVEN the wall 1 m ahead, WHEN the vehicle yaws 90 deg right in small steps, seeing nothing,
  // THEN the wall is remembered on its left (NED body y < 0), about 1 m away.
  MemoryUpdate update;
  for (int i = 1; i <= 9; ++i) {
    update =
        memory.update(i * kFrameNs, no_depth(), camera_pose(i * 10.0 * M_PI / 180.0), kLevel, kD0);
  }
  ASSERT_TRUE(update.updated) << update.reason;
  ASSERT_GE(update.count, 1);
  const Eigen::Vector3d& nearest = update.p_H_m[0];
  EXPECT_NEAR(nearest.norm(), 1.0, 0.1);
  EXPECT_LT(nearest.y(), -0.9);
  for (int i = 1; i < update.count; ++i) {
    EXPECT_GE(update.p_H_m[static_cast<std::size_t>(i)].norm(), nearest.norm());
  }
}

TEST(ObstacleMemory, FreeSpaceSeenThroughAPointForgetsIt) {
  ObstacleMemory memory = make_memory();
  ASSERT_TRUE(memory.update(0, wall(1.0f), camera_pose(0.0), kLevel, kD0).updated);
  // The obstacle moved away: the same rays now reach 3 m.
  const MemoryUpdate update = memory.update(kFrameNs, wall(3.0f), camera_pose(0.0), kLevel, kD0);
  ASSERT_TRUE(update.updated);
  std::vector<Eigen::Vector3f> cloud(kMaxTelemetryPoints);
  const int n = memory.telemetry_cloud(cloud);
  ASSERT_GT(n, 0);
  for (int i = 0; i < n; ++i) EXPECT_GT(cloud[static_cast<std::size_t>(i)].z(), 2.5f);
}

TEST(ObstacleMemory, PointsAgeOut) {
  MemoryConfig config;
  config.max_age_s = 1.0;
  ObstacleMemory memory = make_memory(config);
  ASSERT_TRUE(memory.update(0, wall(1.0f), camera_pose(0.0), kLevel, kD0).updated);
  ASSERT_GT(memory.size(), 0);
  EXPECT_GT(memory.update(900'000'000, no_depth(), camera_pose(0.0), kLevel, kD0).map_size, 0);
  EXPECT_EQ(memory.update(1'100'000'000, no_depth(), camera_pose(0.0), kLevel, kD0).map_size, 0);
}

TEST(ObstacleMemory, PointsBeyondTheRadiusAreForgotten) {
  MemoryConfig config;
  config.radius_m = 2.45;
  ObstacleMemory memory = make_memory(config);
  ASSERT_TRUE(memory.update(0, wall(1.0f), camera_pose(0.0), kLevel, kD0).updated);
  const int stored = memory.size();
  // Backing away 0.2 m per frame (below the jump bound) along -z of the first camera.
  int size_at_1_4m = -1;
  for (int i = 1; i <= 25; ++i) {
    const MemoryUpdate update =
        memory.update(i * kFrameNs, no_depth(), camera_pose(0.0, {0, 0, -0.2 * i}), kLevel, kD0);
    ASSERT_FALSE(update.cleared);
    if (i == 7) size_at_1_4m = update.map_size;
  }
  // 1.4 m back the wall's centre is 2.4 m away, its corners about 2.5 m: they went first.
  EXPECT_GT(size_at_1_4m, 0);
  EXPECT_LT(size_at_1_4m, stored);
  EXPECT_EQ(memory.size(), 0);  // 6 m away: all of it
}

TEST(ObstacleMemory, IsolatedSpeckleIsNotRememberedASurfaceIs) {
  ObstacleMemory memory = make_memory();
  cv::Mat depth = no_depth();
  depth.at<float>(100, 100) = 1.0f;
  depth.at<float>(20, 300) = 2.0f;
  MemoryUpdate update = memory.update(0, depth, camera_pose(0.0), kLevel, kD0);
  ASSERT_TRUE(update.updated);
  // Isolated pixels have no neighbours to give a surface normal: not remembered at all, before
  // the voxel speckle filter even sees them.
  EXPECT_EQ(update.inserted, 0);
  EXPECT_EQ(memory.size(), 0);
  update = memory.update(kFrameNs, wall(1.0f), camera_pose(0.0), kLevel, kD0);
  EXPECT_GT(update.inserted, 100);
  EXPECT_LT(update.speckle_removed, update.inserted / 20);  // at most the plane's corners
}

TEST(ObstacleMemory, BadDepthNeverEntersTheMap) {
  ObstacleMemory memory = make_memory();
  cv::Mat depth = wall(std::numeric_limits<float>::quiet_NaN());
  depth.rowRange(0, 60).setTo(std::numeric_limits<float>::infinity());
  depth.rowRange(60, 120).setTo(-1.0f);
  depth.rowRange(120, 180).setTo(50.0f);  // beyond max_range_m
  depth.rowRange(180, 240).setTo(0.1f);   // nearer than min_range_m
  const MemoryUpdate update = memory.update(0, depth, camera_pose(0.0), kLevel, kD0);
  ASSERT_TRUE(update.updated);
  EXPECT_EQ(update.inserted, 0);
  EXPECT_EQ(memory.size(), 0);

  const MemoryUpdate wrong_type = memory.update(
      kFrameNs, cv::Mat(240, 320, CV_16UC1, cv::Scalar(1000)), camera_pose(0.0), kLevel, kD0);
  EXPECT_FALSE(wrong_type.updated);
  EXPECT_THAT(wrong_type.reason, HasSubstr("CV_32FC1"));
}

TEST(ObstacleMemory, NonFinitePoseIsRejectedAndTheMapKept) {
  ObstacleMemory memory = make_memory();
  ASSERT_TRUE(memory.update(0, wall(1.0f), camera_pose(0.0), kLevel, kD0).updated);
  const int stored = memory.size();
  Eigen::Isometry3d bad = camera_pose(0.0);
  bad.translation().x() = std::numeric_limits<double>::quiet_NaN();
  const MemoryUpdate update = memory.update(kFrameNs, wall(1.0f), bad, kLevel, kD0);
  EXPECT_FALSE(update.updated);
  EXPECT_THAT(update.reason, HasSubstr("not finite"));
  EXPECT_EQ(memory.size(), stored);
  EXPECT_EQ(memory.clear_count(), 0);
}

TEST(ObstacleMemory, PoseJumpClearsTheMapAndSaysSo) {
  ObstacleMemory memory = make_memory();
  ASSERT_TRUE(memory.update(0, wall(1.0f), camera_pose(0.0), kLevel, kD0).updated);
  const MemoryUpdate small =
      memory.update(kFrameNs, no_depth(), camera_pose(0.0, {0.1, 0, 0}), kLevel, kD0);
  EXPECT_FALSE(small.cleared);
  EXPECT_GT(small.map_size, 0);
  const MemoryUpdate jump =
      memory.update(2 * kFrameNs, no_depth(), camera_pose(0.0, {1.1, 0, 0}), kLevel, kD0);
  EXPECT_TRUE(jump.cleared);
  EXPECT_EQ(jump.clear_count, 1);
  EXPECT_EQ(jump.map_size, 0);
  const MemoryUpdate turn =
      memory.update(3 * kFrameNs, wall(1.0f), camera_pose(1.0, {1.1, 0, 0}), kLevel, kD0);
  EXPECT_TRUE(turn.cleared);  // 57 deg in one frame
  EXPECT_EQ(turn.clear_count, 2);
  EXPECT_EQ(turn.map_size, turn.inserted);  // only the new frame
}

TEST(ObstacleMemory, MapStaysWithinCapacity) {
  MemoryConfig config;
  config.capacity = 500;
  config.max_age_s = 100.0;
  ObstacleMemory memory = make_memory(config);
  for (int i = 0; i < 40; ++i) {
    const MemoryUpdate update =
        memory.update(i * kFrameNs, wall(1.0f + 0.02f * static_cast<float>(i % 5)),
                      camera_pose(i * 0.3), kLevel, kD0);
    ASSERT_TRUE(update.updated);
    ASSERT_LE(update.map_size, 500);
  }
  // Full: the earliest insertions were evicted (a voxel refreshed in place may go with them).
  EXPECT_GE(memory.size(), 480);
}

TEST(ObstacleMemory, TelemetryCloudIsBoundedAndFromTheMap) {
  MemoryConfig config;
  config.leaf_m = 0.03;
  config.pixel_stride = 1;
  ObstacleMemory memory = make_memory(config);
  ASSERT_TRUE(memory.update(0, wall(1.5f), camera_pose(0.0), kLevel, kD0).updated);
  ASSERT_GT(memory.size(), kMaxTelemetryPoints);
  std::vector<Eigen::Vector3f> cloud(3 * kMaxTelemetryPoints);
  EXPECT_EQ(memory.telemetry_cloud(cloud), kMaxTelemetryPoints);
  for (int i = 0; i < kMaxTelemetryPoints; ++i) {
    EXPECT_NEAR(cloud[static_cast<std::size_t>(i)].z(), 1.5f, 0.03f);
  }
}

// pcl::VoxelGrid is the reference of the hash down-sampling: same voxels, same count.
TEST(ObstacleMemory, DownSamplingMatchesPclVoxelGrid) {
  MemoryConfig config;
  config.pixel_stride = 1;
  config.min_neighbors = 0;
  config.leaf_m = 0.07;
  ObstacleMemory memory = make_memory(config);
  cv::Mat depth(240, 320, CV_32FC1);
  pcl::PointCloud<pcl::PointXYZ> cloud;
  const geometry::PinholeCamera camera = test_camera();
  for (int v = 0; v < 240; ++v) {
    for (int u = 0; u < 320; ++u) {
      const float z = 0.8f + 0.004f * static_cast<float>(u) + 0.002f * static_cast<float>(v);
      depth.at<float>(v, u) = z;
      const Eigen::Vector3d ray_C = camera.ray(u, v);
      cloud.push_back(
          pcl::PointXYZ(static_cast<float>(ray_C.x()) * z, static_cast<float>(ray_C.y()) * z, z));
    }
  }
  const MemoryUpdate update = memory.update(0, depth, camera_pose(0.0), kLevel, kD0);
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(cloud.makeShared());
  grid.setLeafSize(0.07f, 0.07f, 0.07f);
  pcl::PointCloud<pcl::PointXYZ> reference;
  grid.filter(reference);
  // Float rounding at voxel faces may move a point or two across.
  EXPECT_NEAR(update.inserted, static_cast<int>(reference.size()), 2);
}

TEST(ObstacleMemory, UpdateAllocatesNothingAfterTheFirstFrame) {
  ObstacleMemory memory = make_memory();
  const cv::Mat near = wall(1.0f);
  const cv::Mat empty = no_depth();
  (void)memory.update(0, near, camera_pose(0.0), kLevel, kD0);
  std::vector<Eigen::Vector3f> cloud(kMaxTelemetryPoints);
  const long before = hq::testing::allocation_count();
  for (int i = 1; i < 20; ++i) {
    (void)memory.update(i * kFrameNs, (i % 2) ? empty : near, camera_pose(0.05 * i), kLevel, kD0);
    (void)memory.telemetry_cloud(cloud);
  }
  EXPECT_EQ(hq::testing::allocation_count(), before);
}

// PCL's own readers are the peer of the map writer: what they read back must be the map, point
// for point, in both formats.
int load_with_pcl(const std::string& path, pcl::PointCloud<pcl::PointXYZ>& cloud) {
  return path.ends_with(".pcd") ? pcl::io::loadPCDFile(path, cloud)
                                : pcl::io::loadPLYFile(path, cloud);
}

std::vector<Eigen::Vector3f> map_points(const ObstacleMemory& memory) {
  std::vector<Eigen::Vector3f> points;
  memory.for_each_point(
      [&](const Eigen::Vector3f& p_O_m, std::int64_t) { points.push_back(p_O_m); });
  return points;
}

TEST(ObstacleMemory, SavedPcdAndPlyReadBackWithPclPointForPoint) {
  ObstacleMemory memory = make_memory();
  ASSERT_TRUE(memory.update(0, wall(2.0f), camera_pose(0.0), kLevel, kD0).updated);
  const std::vector<Eigen::Vector3f> expected = map_points(memory);
  ASSERT_GT(expected.size(), 100U);
  const std::filesystem::path dir = std::filesystem::temp_directory_path();
  for (const char* name : {"hq_memory_test.pcd", "hq_memory_test.ply"}) {
    const std::string path = (dir / name).string();
    memory.save(path);
    pcl::PointCloud<pcl::PointXYZ> cloud;
    const int status = load_with_pcl(path, cloud);
    std::remove(path.c_str());
    ASSERT_GE(status, 0) << path;
    ASSERT_EQ(cloud.size(), expected.size()) << path;
    for (std::size_t i = 0; i < expected.size(); ++i) {
      // Bit for bit: the file holds the map's float32 coordinates, nothing rounded.
      ASSERT_EQ(cloud[i].getVector3fMap(), expected[i]) << path << " point " << i;
    }
    // Bounds of the wall at z = 2 m seen through the 320x240 camera (half width 2 * 160 / 277):
    // the points are where the memory put them, not merely as many.
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e9f);
    Eigen::Vector3f hi = Eigen::Vector3f::Constant(-1e9f);
    for (const pcl::PointXYZ& p : cloud) {
      lo = lo.cwiseMin(p.getVector3fMap());
      hi = hi.cwiseMax(p.getVector3fMap());
    }
    EXPECT_NEAR(lo.z(), 2.0f, 1e-3f) << path;
    EXPECT_NEAR(hi.x(), 2.0f * 160.0f / 277.0f, 0.1f) << path;
    EXPECT_NEAR(lo.x(), -2.0f * 160.0f / 277.0f, 0.1f) << path;
  }
}

TEST(ObstacleMemory, SavedEmptyMapReadsBackWithPclAsNoPoints) {
  const ObstacleMemory memory = make_memory();
  ASSERT_EQ(memory.size(), 0);
  const std::filesystem::path dir = std::filesystem::temp_directory_path();
  for (const char* name : {"hq_memory_empty_test.pcd", "hq_memory_empty_test.ply"}) {
    const std::string path = (dir / name).string();
    memory.save(path);
    pcl::PointCloud<pcl::PointXYZ> cloud;
    cloud.push_back(pcl::PointXYZ(1.0f, 2.0f, 3.0f));  // the reader must replace it
    const int status = load_with_pcl(path, cloud);
    std::remove(path.c_str());
    ASSERT_GE(status, 0) << path;
    EXPECT_EQ(cloud.size(), 0U) << path;
  }
}

TEST(ObstacleMemory, SavedPcdHeaderDeclaresBinaryXyzFloats) {
  ObstacleMemory memory = make_memory();
  ASSERT_TRUE(memory.update(0, wall(2.0f), camera_pose(0.0), kLevel, kD0).updated);
  const std::string path =
      (std::filesystem::temp_directory_path() / "hq_memory_header.pcd").string();
  memory.save(path);
  std::ifstream in(path, std::ios::binary);
  std::vector<std::string> header;
  std::string line;
  while (header.size() < 11 && std::getline(in, line)) header.push_back(line);
  const auto data_start = in.tellg();
  in.seekg(0, std::ios::end);
  const auto data_bytes = static_cast<std::size_t>(in.tellg() - data_start);
  std::remove(path.c_str());
  const std::string n = std::to_string(memory.size());
  EXPECT_THAT(header, ::testing::ElementsAre(
                          "# .PCD v0.7 - Point Cloud Data file format", "VERSION 0.7",
                          "FIELDS x y z", "SIZE 4 4 4", "TYPE F F F", "COUNT 1 1 1", "WIDTH " + n,
                          "HEIGHT 1", "VIEWPOINT 0 0 0 1 0 0 0", "POINTS " + n, "DATA binary"));
  EXPECT_EQ(data_bytes, static_cast<std::size_t>(memory.size()) * 12U);
}

TEST(ObstacleMemory, SaveNamesTheBadPath) {
  ObstacleMemory memory = make_memory();
  EXPECT_THAT(hq::testing::input_error_message([&] { memory.save("/tmp/map.xyz"); }),
              HasSubstr("/tmp/map.xyz: unknown extension, expected .pcd or .ply"));
  ASSERT_TRUE(memory.update(0, wall(2.0f), camera_pose(0.0), kLevel, kD0).updated);
  for (const std::string path : {"/nonexistent-dir/map.pcd", "/nonexistent-dir/map.ply"}) {
    EXPECT_THAT(hq::testing::input_error_message([&] { memory.save(path); }),
                HasSubstr(path + ": cannot open for writing: No such file or directory"));
  }
}

TEST(ObstacleMemoryConfig, ReadsEveryKeyAndRejectsBadOnes) {
  const YAML::Node node = YAML::Load(
      "{enabled: false, leaf_m: 0.05, pixel_stride: 3, min_range_m: 0.3, max_range_m: 3.5, "
      "min_neighbors: 4, max_age_s: 5, radius_m: 3, capacity: 1000, max_pose_jump_m: 0.2, "
      "max_pose_jump_deg: 10, vertical_band_m: 0.4, sectors: 36, max_points: 6}");
  config::StrictMap section(node, "onboard.yaml", "memory");
  MemoryConfig config;
  read_config(section, config);
  EXPECT_FALSE(config.enabled);
  EXPECT_EQ(config.pixel_stride, 3);
  EXPECT_EQ(config.capacity, 1000);
  EXPECT_NEAR(config.max_pose_jump_rad, 10.0 * M_PI / 180.0, 1e-12);
  EXPECT_EQ(config.max_points, 6);

  const auto message = [](const std::string& yaml) {
    return hq::testing::input_error_message([&] {
      config::StrictMap map(YAML::Load(yaml), "onboard.yaml", "memory");
      MemoryConfig out;
      read_config(map, out);
    });
  };
  EXPECT_THAT(message("{leaf_m: -0.1}"), HasSubstr("memory.leaf_m"));
  EXPECT_THAT(message("{max_points: 17}"), HasSubstr("memory.max_points"));
  EXPECT_THAT(message("{min_range_m: 2, max_range_m: 1}"), HasSubstr("expected > min_range_m"));
  EXPECT_THAT(message("{leaf: 0.1}"), HasSubstr("leaf"));
}

TEST(ObstacleMemoryConfig, ReaderAndConstructorRefuseTheSameConfigAlike) {
  // GIVEN configs each out of range in one field, or inconsistent across two, as YAML and as
  // the same values set in code
  struct Case {
    std::string yaml;
    std::string expected;
    void (*set)(MemoryConfig&);
  };
  const std::vector<Case> cases = {
      {"{sectors: 2}", "memory.sectors = 2", [](MemoryConfig& c) { c.sectors = 2; }},
      {"{pixel_stride: 0}", "memory.pixel_stride = 0", [](MemoryConfig& c) { c.pixel_stride = 0; }},
      {"{capacity: 0}", "memory.capacity = 0", [](MemoryConfig& c) { c.capacity = 0; }},
      {"{min_range_m: 3, max_range_m: 2}", "memory.max_range_m = 2",
       [](MemoryConfig& c) {
         c.min_range_m = 3.0;
         c.max_range_m = 2.0;
       }},
      {"{max_pose_jump_deg: 0.01}", "memory.max_pose_jump_deg = 0.01",
       [](MemoryConfig& c) { c.max_pose_jump_rad = 0.01 * M_PI / 180.0; }},
      {"{support_normal_max_deg: 91}", "memory.support_normal_max_deg = 91",
       [](MemoryConfig& c) { c.support_normal_max_rad = 91.0 * M_PI / 180.0; }},
  };
  for (const Case& c : cases) {
    // WHEN read from a file, and WHEN handed to the constructor
    const std::string from_file = hq::testing::input_error_message([&] {
      config::StrictMap map(YAML::Load(c.yaml), "onboard.yaml", "memory");
      MemoryConfig read;
      read_config(map, read);
    });
    MemoryConfig direct;
    c.set(direct);
    const std::string from_constructor = hq::testing::input_error_message(
        [&] { ObstacleMemory(direct, test_camera(), forward_R_B_C(), Eigen::Vector3d::Zero()); });
    // THEN both refuse it naming the key and value; the file's message also names the file
    EXPECT_THAT(from_file, HasSubstr("onboard.yaml: " + c.expected)) << c.yaml;
    EXPECT_THAT(from_constructor, HasSubstr(c.expected)) << c.yaml;
  }
  // AND the defaults pass.
  EXPECT_NO_THROW(validate(MemoryConfig{}));
}

TEST(ObstacleMemory, RejectsAnUnusableCameraOrExtrinsics) {
  geometry::PinholeCamera camera = test_camera();
  camera.fx = 0.0;
  EXPECT_THAT(hq::testing::input_error_message([&] {
                ObstacleMemory(MemoryConfig{}, camera, forward_R_B_C(), Eigen::Vector3d::Zero());
              }),
              HasSubstr("memory: camera 320x240"));
  EXPECT_THAT(hq::testing::input_error_message([&] {
                ObstacleMemory(MemoryConfig{}, test_camera(), 2.0 * forward_R_B_C(),
                               Eigen::Vector3d::Zero());
              }),
              HasSubstr("not a rotation"));
}

}  // namespace
}  // namespace hq::obstacle_memory

namespace hq::obstacle_memory {
namespace {

// A level camera 0.4 m above a floor: the lower half of the image is floor (depth along each
// ray to the plane y_C = 0.4). The floor is a support surface, never remembered; the same
// camera looking at a wall does remember it. Tilting the body by 30 deg (R_HQ) turns the floor
// in the camera into a slope the test must still see as horizontal in H.
TEST(ObstacleMemory, FloorIsNotRememberedAWallIs) {
  const geometry::PinholeCamera camera = test_camera();
  for (const double pitch_deg : {0.0, 20.0}) {
    const double pitch = pitch_deg * M_PI / 180.0;
    // The body pitched nose-down by pitch; the floor is horizontal in H.
    const Eigen::Matrix3d R_H_B_from_tilt =
        Eigen::AngleAxisd(-pitch, Eigen::Vector3d::UnitY()).toRotationMatrix();
    const Eigen::Matrix3d R_HC = R_H_B_from_tilt * forward_R_B_C();
    cv::Mat floor = no_depth();
    for (int v = 0; v < camera.height; ++v) {
      for (int u = 0; u < camera.width; ++u) {
        const Eigen::Vector3d ray_C = camera.ray(u, v);
        const double down = (R_HC * ray_C).z();  // H z is down
        if (down > 1e-3) floor.at<float>(v, u) = static_cast<float>(0.4 / down);
      }
    }
    ObstacleMemory memory = make_memory();
    const MemoryUpdate update = memory.update(0, floor, camera_pose(0.0), R_H_B_from_tilt, kD0);
    ASSERT_TRUE(update.updated) << update.reason;
    EXPECT_EQ(update.inserted, 0) << "pitch " << pitch_deg;
    EXPECT_EQ(memory.size(), 0) << "pitch " << pitch_deg;
  }
  ObstacleMemory memory = make_memory();
  EXPECT_GT(memory.update(0, wall(1.5f), camera_pose(0.0), kLevel, kD0).inserted, 100);
}

}  // namespace
}  // namespace hq::obstacle_memory
