#include "hq/base/error.hpp"
#include "hq/sim/rgbd_renderer.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/aruco.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace hq::sim {
namespace {

using ::testing::HasSubstr;

constexpr double kPi = 3.14159265358979323846;

CameraParams noise_free_camera(int width, int height) {
  CameraParams p;
  p.pinhole = pinhole_from_fov(width, height, 60.0 * kPi / 180.0);
  p.image_noise_sigma = 0.0;
  p.depth.noise_sigma_per_m2 = 0.0;
  p.depth.disparity_subpixels = 0;
  p.depth.edge_jump_ratio = 0.0;
  return p;
}

/// Camera at p looking along world +x (optical z), image x right = world -y, y down = world -z.
Eigen::Isometry3d looking_north(const Eigen::Vector3d& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = -Eigen::Vector3d::UnitY();
  T.linear().col(1) = -Eigen::Vector3d::UnitZ();
  T.linear().col(2) = Eigen::Vector3d::UnitX();
  T.translation() = p;
  return T;
}

World base_world() {
  World world;
  world.floor.half_u_m = world.floor.half_v_m = 20.0;
  return world;
}

Rectangle wall_at_x(double x) {
  Rectangle wall;
  wall.center_m = Eigen::Vector3d(x, 0.0, 1.5);
  wall.normal = -Eigen::Vector3d::UnitX();
  wall.axis_u = Eigen::Vector3d::UnitY();
  wall.axis_v = Eigen::Vector3d::UnitZ();
  wall.half_u_m = 5.0;
  wall.half_v_m = 1.5;
  return wall;
}

float centre_depth(const cv::Mat& depth) { return depth.at<float>(depth.rows / 2, depth.cols / 2); }

class RendererFixture : public ::testing::Test {
 protected:
  void render(const World& world, const Eigen::Isometry3d& T_N_C, const CameraParams& params,
              std::uint64_t seed = 1) {
    RgbdRenderer renderer(params, world, seed);
    renderer.render(T_N_C, 0, image_, depth_);
  }
  cv::Mat image_, depth_;
};

// Odd sizes put a pixel centre exactly on the optical axis.
TEST_F(RendererFixture, WallAtKnownDistanceGivesThatDepthAtCentre) {
  World world = base_world();
  world.walls.push_back(wall_at_x(3.0));
  render(world, looking_north({0.5, 0.0, 1.0}), noise_free_camera(321, 241));
  EXPECT_NEAR(centre_depth(depth_), 2.5, 1e-4);
  // Depth is z along the optical axis, so the same wall reads 2.5 m off-centre too.
  EXPECT_NEAR(depth_.at<float>(120, 40), 2.5, 1e-4);
  EXPECT_EQ(image_.type(), CV_8UC3);
  EXPECT_EQ(depth_.type(), CV_32F);
}

TEST_F(RendererFixture, FloorSeenStraightDownGivesHeight) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = -Eigen::Vector3d::UnitY();
  T.linear().col(1) = -Eigen::Vector3d::UnitX();
  T.linear().col(2) = -Eigen::Vector3d::UnitZ();
  T.translation() = Eigen::Vector3d(0.3, 0.2, 1.7);
  render(base_world(), T, noise_free_camera(161, 121));
  EXPECT_NEAR(centre_depth(depth_), 1.7, 1e-4);
}

TEST_F(RendererFixture, YawedBoxShowsItsNearEdgeAndAxisAlignedItsFace) {
  World world = base_world();
  Box box;
  box.center_m = Eigen::Vector3d(3.0, 0.0, 1.0);
  box.size_m = Eigen::Vector3d(1.0, 1.0, 2.0);
  world.boxes.push_back(box);
  render(world, looking_north({0.0, 0.0, 1.0}), noise_free_camera(161, 121));
  EXPECT_NEAR(centre_depth(depth_), 2.5, 1e-4);
  world.boxes[0].yaw_rad = kPi / 4.0;  // a vertical edge now points at the camera
  render(world, looking_north({0.0, 0.0, 1.0}), noise_free_camera(161, 121));
  EXPECT_NEAR(centre_depth(depth_), 3.0 - 0.5 * std::sqrt(2.0), 1e-3);
}

TEST_F(RendererFixture, CylinderGivesDistanceMinusRadiusAndItsTop) {
  World world = base_world();
  Cylinder c;
  c.center_m = Eigen::Vector2d(4.0, 0.0);
  c.radius_m = 0.4;
  c.height_m = 0.8;
  world.cylinders.push_back(c);
  render(world, looking_north({0.0, 0.0, 0.5}), noise_free_camera(161, 121));
  EXPECT_NEAR(centre_depth(depth_), 3.6, 1e-3);
  // From above, looking down onto the top cap.
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = -Eigen::Vector3d::UnitY();
  T.linear().col(1) = -Eigen::Vector3d::UnitX();
  T.linear().col(2) = -Eigen::Vector3d::UnitZ();
  T.translation() = Eigen::Vector3d(4.1, 0.0, 2.0);
  render(world, T, noise_free_camera(161, 121));
  EXPECT_NEAR(centre_depth(depth_), 1.2, 1e-4);
}

TEST_F(RendererFixture, NearestSurfaceWinsWhenPrimitivesOverlapAlongTheRay) {
  World world = base_world();
  world.walls.push_back(wall_at_x(5.0));
  Box box;
  box.center_m = Eigen::Vector3d(2.0, 0.0, 1.0);
  box.size_m = Eigen::Vector3d(0.4, 0.4, 0.4);
  world.boxes.push_back(box);
  render(world, looking_north({0.0, 0.0, 1.0}), noise_free_camera(161, 121));
  EXPECT_NEAR(centre_depth(depth_), 1.8, 1e-4);
  EXPECT_NEAR(depth_.at<float>(60, 5), 5.0, 1e-3);  // beside the box: the wall
}

TEST_F(RendererFixture, DepthBelowMinRangeOrAboveMaxRangeIsZero) {
  World world = base_world();
  world.walls.push_back(wall_at_x(0.8));
  CameraParams params = noise_free_camera(81, 61);
  render(world, looking_north({0.5, 0.0, 1.0}), params);  // 0.3 m < 0.5 m
  EXPECT_EQ(centre_depth(depth_), 0.0f);
  world.walls[0] = wall_at_x(9.0);
  render(world, looking_north({0.5, 0.0, 1.0}), params);  // 8.5 m > 6 m
  EXPECT_EQ(centre_depth(depth_), 0.0f);
}

TEST_F(RendererFixture, DarkSurfacesAndDepthEdgesReturnNoDepth) {
  World world = base_world();
  world.walls.push_back(wall_at_x(3.0));
  world.walls[0].texture.color_bgr.setConstant(0.02f);
  CameraParams params = noise_free_camera(81, 61);
  render(world, looking_north({0.0, 0.0, 1.0}), params);
  EXPECT_EQ(centre_depth(depth_), 0.0f);

  World edge_world = base_world();
  edge_world.walls.push_back(wall_at_x(4.0));
  Box box;
  box.center_m = Eigen::Vector3d(2.0, 0.0, 1.0);
  box.size_m = Eigen::Vector3d(0.5, 0.5, 0.5);
  edge_world.boxes.push_back(box);
  params.depth.edge_jump_ratio = 0.04;
  render(edge_world, looking_north({0.0, 0.0, 1.0}), params);
  EXPECT_GT(centre_depth(depth_), 0.0f);
  // Scan the centre row: every box/wall transition loses its depth on both sides.
  const int row = depth_.rows / 2;
  int transitions = 0;
  for (int u = 1; u < depth_.cols - 2; ++u) {
    const float a = depth_.at<float>(row, u - 1);
    const float b = depth_.at<float>(row, u + 2);
    if (a > 0.0f && b > 0.0f && std::abs(a - b) > 1.0f) {
      ++transitions;
      EXPECT_EQ(depth_.at<float>(row, u), 0.0f);
      EXPECT_EQ(depth_.at<float>(row, u + 1), 0.0f);
    }
  }
  EXPECT_EQ(transitions, 2);
}

TEST_F(RendererFixture, StructuredLightNoiseGrowsWithDepthSquared) {
  CameraParams params = noise_free_camera(161, 121);
  params.depth.noise_sigma_per_m2 = 1.425e-3;
  params.depth.disparity_subpixels = 8;
  const auto patch_sigma = [&](double distance_m) {
    World world = base_world();
    world.walls.push_back(wall_at_x(distance_m));
    render(world, looking_north({0.0, 0.0, 1.0}), params);
    cv::Scalar mean, sigma;
    cv::meanStdDev(depth_(cv::Rect(60, 40, 40, 40)), mean, sigma);
    EXPECT_NEAR(mean[0], distance_m, 0.01 * distance_m * distance_m);
    return sigma[0];
  };
  const double sigma_1m = patch_sigma(1.0);
  const double sigma_4m = patch_sigma(4.0);
  // sigma_z = k z^2 (plus quantisation, also ~ z^2): 16x from 1 m to 4 m; allow 10x..22x.
  EXPECT_GT(sigma_4m, 10.0 * sigma_1m);
  EXPECT_LT(sigma_4m, 22.0 * sigma_1m);
  EXPECT_NEAR(sigma_4m, 1.425e-3 * 16.0, 0.6 * 1.425e-3 * 16.0);
}

TEST_F(RendererFixture, MarkerOnWallIsDetectedByArucoApriltag36h11WithItsId) {
  World world = base_world();
  world.walls.push_back(wall_at_x(2.0));
  for (int id : {42, 7}) {
    Marker m;
    m.id = id;
    m.center_N_m = Eigen::Vector3d(2.0, id == 42 ? 0.3 : -0.3, 1.0);
    m.normal_N = -Eigen::Vector3d::UnitX();
    m.size_m = 0.2;
    world.markers.push_back(m);
  }
  CameraParams params = noise_free_camera(640, 480);
  params.image_noise_sigma = 1.0;
  render(world, looking_north({0.5, 0.0, 1.0}), params);
  cv::Mat gray;
  cv::cvtColor(image_, gray, cv::COLOR_BGR2GRAY);
  const cv::Ptr<cv::aruco::Dictionary> dictionary =
      cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11);
  std::vector<std::vector<cv::Point2f>> corners;
  std::vector<int> ids;
  cv::aruco::detectMarkers(gray, dictionary, corners, ids);
  std::sort(ids.begin(), ids.end());
  ASSERT_EQ(ids, (std::vector<int>{7, 42})) << "detected " << ids.size() << " markers";
  // Id 42 is on the left (world +y is image left when looking north).
  for (std::size_t i = 0; i < ids.size(); ++i) {
    cv::Point2f centre(0, 0);
    for (const cv::Point2f& c : corners[i]) centre += 0.25f * c;
    EXPECT_EQ(centre.x < 320.0f, ids[i] == 42) << "id " << ids[i] << " at x " << centre.x;
    // 0.2 m at 1.5 m with fx = 554 px: about 74 px wide.
    EXPECT_NEAR(cv::norm(corners[i][0] - corners[i][1]), 0.2 * params.pinhole.fx / 1.5, 3.0);
  }
}

TEST_F(RendererFixture, MarkerOffEverySurfaceIsRejected) {
  World world = base_world();
  Marker m;
  m.id = 3;
  m.center_N_m = Eigen::Vector3d(1.0, 1.0, 1.0);  // in mid-air
  world.markers.push_back(m);
  try {
    RgbdRenderer renderer(noise_free_camera(32, 24), world, 1);
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("markers[0] (id 3)"));
  }
}

TEST_F(RendererFixture, SameSeedGivesIdenticalImagesAndAnotherSeedDoesNot) {
  World world = base_world();
  world.walls.push_back(wall_at_x(3.0));
  CameraParams params;  // default: noisy image and depth
  params.pinhole = pinhole_from_fov(160, 120, 1.0);
  const Eigen::Isometry3d T = looking_north({0.0, 0.0, 1.0});
  cv::Mat image_a, depth_a, image_b, depth_b, image_c, depth_c;
  RgbdRenderer a(params, world, 5);
  RgbdRenderer b(params, world, 5);
  RgbdRenderer c(params, world, 6);
  a.render(T, 3, image_a, depth_a);
  b.render(T, 3, image_b, depth_b);
  c.render(T, 3, image_c, depth_c);
  EXPECT_EQ(cv::norm(image_a, image_b, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(depth_a, depth_b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(image_a, image_c, cv::NORM_L1), 0.0);
  EXPECT_GT(cv::norm(depth_a, depth_c, cv::NORM_L1), 0.0);
  // The buffers are reused, not reallocated.
  const std::uint8_t* data = image_a.data;
  a.render(T, 4, image_a, depth_a);
  EXPECT_EQ(image_a.data, data);
}

/// A person walking (0.4 m radius) from (4, -1) to (4, 1) at 1 m/s before a wall at x = 5.5.
World world_with_a_walker() {
  World world = base_world();
  world.walls.push_back(wall_at_x(5.5));
  Walker walker;
  walker.from_m = Eigen::Vector2d(4.0, -1.0);
  walker.to_m = Eigen::Vector2d(4.0, 1.0);
  walker.speed_mps = 1.0;
  walker.radius_m = 0.4;
  walker.texture.kind = Texture::Kind::kStripes;
  walker.texture.scale_m = 0.1f;
  walker.texture.contrast = 0.8f;
  world.people.push_back(walker);
  return world;
}

// GIVEN a person crossing the view 4 m ahead, WHEN rendered at t = 0 (the person at y = -1)
// and t = 1 s (y = 0) and t = 3 s (back at y = 0), THEN the depth along a ray is the nearer of
// the wall and the person's circle where the person is then.
TEST_F(RendererFixture, PersonMovesAcrossTheViewAtTheFramesTime) {
  const World world = world_with_a_walker();
  const CameraParams params = noise_free_camera(161, 121);
  RgbdRenderer renderer(params, world, 1);
  const Eigen::Isometry3d T = looking_north({0.0, 0.0, 1.0});
  // Pixel (60, 114) looks along world (1, a, 0): a = -(114 - cx) / fx, towards y = -1 at x = 4.
  const geometry::PinholeCamera& cam = params.pinhole;
  const int u = 114;
  const double a = -(u - cam.cx) / cam.fx;
  // Nearest s with |(s, a s) - c| = r: the depth, as the ray's x component is 1 (z in C).
  const auto depth_to_circle = [&](const Eigen::Vector2d& c, double r) {
    const double qa = 1.0 + a * a;
    const double qb = c.x() + a * c.y();
    const double qc = c.squaredNorm() - r * r;
    return (qb - std::sqrt(qb * qb - qa * qc)) / qa;
  };
  const double on_person_m = depth_to_circle({4.0, -1.0}, 0.4);
  ASSERT_GT(on_person_m, 3.6);
  ASSERT_LT(on_person_m, 4.0);

  renderer.render(T, 0.0, 0, image_, depth_);
  EXPECT_NEAR(centre_depth(depth_), 5.5, 1e-3);  // the wall beside the person
  EXPECT_NEAR(depth_.at<float>(60, u), on_person_m, 1e-3);
  renderer.render(T, 1.0, 1, image_, depth_);
  EXPECT_NEAR(centre_depth(depth_), 4.0 - 0.4, 1e-3);
  EXPECT_NEAR(depth_.at<float>(60, u), 5.5, 1e-3);  // the person has left the ray
  renderer.render(T, 3.0, 3, image_, depth_);       // on the way back
  EXPECT_NEAR(centre_depth(depth_), 4.0 - 0.4, 1e-3);
  renderer.render(T, 2.0, 2, image_, depth_);  // at the far end, y = 1
  EXPECT_NEAR(centre_depth(depth_), 5.5, 1e-3);
  // The reference ray caster puts the person in the same place.
  cv::Mat image_ref, depth_ref;
  renderer.render_reference(T, 0.0, 0, image_ref, depth_ref);
  EXPECT_NEAR(depth_ref.at<float>(60, u), on_person_m, 1e-3);
  // Without a time the people stand where they are at t = 0.
  renderer.render(T, 0, image_, depth_);
  EXPECT_NEAR(depth_.at<float>(60, u), on_person_m, 1e-3);
}

// GIVEN the camera moving sideways with the person, THEN the person's pixels are the same: the
// clothes are fixed to the body, not to the world (a world-fixed texture would slide).
TEST_F(RendererFixture, PersonsTextureMovesWithThePerson) {
  const World world = world_with_a_walker();
  const CameraParams params = noise_free_camera(161, 121);
  RgbdRenderer renderer(params, world, 1);
  cv::Mat image_a, depth_a, image_b, depth_b;
  renderer.render(looking_north({0.0, 0.0, 1.0}), 1.0, 0, image_a, depth_a);  // person at y = 0
  renderer.render(looking_north({0.0, 0.5, 1.0}), 1.5, 0, image_b, depth_b);  // at y = 0.5
  int person_pixels = 0;
  double max_difference = 0.0;
  double min_level = 255.0;
  double max_level = 0.0;
  // Above the horizon no floor is seen; the wall is 5.5 m away, the person nearer than 4.4 m.
  for (int v = 0; v <= 60; ++v) {
    for (int u = 0; u < image_a.cols; ++u) {
      const float z_a = depth_a.at<float>(v, u);
      const float z_b = depth_b.at<float>(v, u);
      if (!(z_a > 0.0f && z_a < 4.5f && z_b > 0.0f && z_b < 4.5f)) continue;
      ++person_pixels;
      const cv::Vec3b pa = image_a.at<cv::Vec3b>(v, u);
      const cv::Vec3b pb = image_b.at<cv::Vec3b>(v, u);
      for (int k = 0; k < 3; ++k) {
        max_difference = std::max(
            max_difference, std::abs(static_cast<double>(pa[k]) - static_cast<double>(pb[k])));
      }
      min_level = std::min(min_level, static_cast<double>(pa[1]));
      max_level = std::max(max_level, static_cast<double>(pa[1]));
    }
  }
  EXPECT_GT(person_pixels, 500);           // 28 px wide, 29 rows above the horizon
  EXPECT_GT(max_level - min_level, 40.0);  // textured, so a sliding texture would show
  EXPECT_LE(max_difference, 1.0);
}

TEST_F(RendererFixture, GrayModeGivesOneChannel) {
  World world = base_world();
  world.walls.push_back(wall_at_x(3.0));
  CameraParams params = noise_free_camera(64, 48);
  params.gray = true;
  render(world, looking_north({0.0, 0.0, 1.0}), params);
  EXPECT_EQ(image_.type(), CV_8UC1);
  cv::Scalar mean = cv::mean(image_);
  EXPECT_GT(mean[0], 20.0);
}

}  // namespace
}  // namespace hq::sim
