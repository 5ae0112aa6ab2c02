#include "hq/obstacles/obstacle_field.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"

#include "hq/testing/allocation_counter.hpp"
#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <array>
#include <cmath>
#include <limits>
#include <random>

namespace hq::obstacles {
namespace {

using ::testing::HasSubstr;
constexpr double kDeg = M_PI / 180.0;

geometry::PinholeCamera test_camera() {
  geometry::PinholeCamera camera;
  camera.fx = 525.0;
  camera.fy = 525.0;
  camera.cx = 319.5;
  camera.cy = 239.5;
  camera.width = 640;
  camera.height = 480;
  return camera;
}

// Camera looking 45 deg right and 30 deg down (optical frame: z forward, x right, y down).
Eigen::Matrix3d default_R_body_camera() {
  Eigen::Matrix3d R_forward_optical;
  R_forward_optical << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  return Eigen::AngleAxisd(45.0 * kDeg, Eigen::Vector3d::UnitZ()).matrix() *
         Eigen::AngleAxisd(-30.0 * kDeg, Eigen::Vector3d::UnitY()).matrix() * R_forward_optical;
}

// A wall perpendicular to the optical axis: constant z.
cv::Mat wall(float z_m) { return cv::Mat(480, 640, CV_32FC1, cv::Scalar(z_m)); }

TEST(ObstacleField, FlatWallPushesAwayAlongTheCameraAxisHorizontalProjection) {
  const Eigen::Matrix3d R_QC = default_R_body_camera();
  ObstacleField field(ObstacleConfig{}, test_camera(), R_QC, Eigen::Vector3d::Zero());
  const ObstacleResult result = field.compute(wall(0.8f), Eigen::Matrix3d::Identity());
  ASSERT_TRUE(result.valid);
  EXPECT_FALSE(result.near_hazard);
  ASSERT_EQ(result.count, 1);  // one nearest point on a flat wall
  EXPECT_NEAR(result.points[0].distance_m, 0.8, 0.01);

  const Eigen::Vector3d axis_H = R_QC.col(2);  // optical axis, H = Q for a level vehicle
  const Eigen::Vector2d axis_horizontal = axis_H.head<2>().normalized();
  const Eigen::Vector2d push_horizontal = result.v_obs_horizontal_mps.head<2>();
  ASSERT_GT(push_horizontal.norm(), 0.01);
  EXPECT_GT(push_horizontal.normalized().dot(-axis_horizontal), std::cos(1.0 * kDeg));
  // The camera looks down, so the push also has an upward (NED z < 0) part.
  EXPECT_LT(result.v_obs_horizontal_mps.z(), 0.0);
  // Magnitude of the Khatib term at d = 0.8, d0 = 1.2, eta = 0.05.
  const double expected = 0.05 * (1.0 / 0.8 - 1.0 / 1.2) / (0.8 * 0.8);
  EXPECT_NEAR(result.v_obs_horizontal_mps.norm(), expected, 0.02 * expected);
}

TEST(ObstacleField, PitchedVehicleSeesTheWallInH) {
  // A vehicle pitched 10 deg nose down: the same wall is seen 10 deg further down in H.
  const Eigen::Matrix3d R_QC = default_R_body_camera();
  ObstacleField field(ObstacleConfig{}, test_camera(), R_QC, Eigen::Vector3d::Zero());
  const Eigen::Matrix3d R_HQ = Eigen::AngleAxisd(-10.0 * kDeg, Eigen::Vector3d::UnitY()).matrix();
  const ObstacleResult result = field.compute(wall(0.8f), R_HQ);
  ASSERT_EQ(result.count, 1);
  const Eigen::Vector3d expected_direction = -(R_HQ * R_QC.col(2));
  EXPECT_GT(result.v_obs_horizontal_mps.normalized().dot(expected_direction), std::cos(1.0 * kDeg));
}

TEST(ObstacleField, NothingWithinRangeGivesZero) {
  ObstacleField field(ObstacleConfig{}, test_camera(), default_R_body_camera(),
                      Eigen::Vector3d(0.1, 0.0, 0.05));
  const ObstacleResult result = field.compute(wall(3.0f), Eigen::Matrix3d::Identity());
  ASSERT_TRUE(result.valid);
  EXPECT_EQ(result.count, 0);
  EXPECT_TRUE(result.v_obs_horizontal_mps.isZero());
}

cv::Mat far_scene_with_speckle() {
  cv::Mat depth = wall(4.0f);
  std::mt19937 rng(1);
  std::uniform_int_distribution<int> jitter(0, 3);
  // Isolated 0.2 m pixels 20 px apart (~770 of them): at most one per 16 px cell.
  for (int v = 0; v + 3 < 480; v += 20) {
    for (int u = 0; u + 3 < 640; u += 20) depth.at<float>(v + jitter(rng), u + jitter(rng)) = 0.2f;
  }
  return depth;
}

TEST(ObstacleField, SinglePixelSpeckleGivesZero) {
  ObstacleField field(ObstacleConfig{}, test_camera(), default_R_body_camera(),
                      Eigen::Vector3d::Zero());
  const ObstacleResult result =
      field.compute(far_scene_with_speckle(), Eigen::Matrix3d::Identity());
  ASSERT_TRUE(result.valid);
  EXPECT_EQ(result.count, 0);
  EXPECT_TRUE(result.v_obs_horizontal_mps.isZero());

  // The same scene with a plain min-pool (rank 1) would see obstacles everywhere.
  ObstacleConfig plain;
  plain.speckle_rank = 1;
  ObstacleField naive(plain, test_camera(), default_R_body_camera(), Eigen::Vector3d::Zero());
  EXPECT_GT(naive.compute(far_scene_with_speckle(), Eigen::Matrix3d::Identity()).count, 0);
}

TEST(ObstacleField, VeryCloseWallSaturates) {
  ObstacleConfig config;
  config.min_range_m = 0.0;
  ObstacleField field(config, test_camera(), default_R_body_camera(), Eigen::Vector3d::Zero());
  const ObstacleResult result = field.compute(wall(0.12f), Eigen::Matrix3d::Identity());
  EXPECT_NEAR(result.v_obs_horizontal_mps.norm(), config.max_repulsive_speed_mps, 1e-12);
}

TEST(ObstacleField, NearInvalidCentralBlobIsAHazardAndPushes) {
  // GIVEN a far scene whose centre is invalid, as when a surface is nearer than the min range.
  cv::Mat depth = wall(3.0f);
  depth(cv::Rect(200, 140, 240, 200)).setTo(0.0f);
  const Eigen::Matrix3d R_QC = default_R_body_camera();
  ObstacleField field(ObstacleConfig{}, test_camera(), R_QC, Eigen::Vector3d::Zero());
  const ObstacleResult result = field.compute(depth, Eigen::Matrix3d::Identity());
  EXPECT_TRUE(result.near_hazard);
  EXPECT_GT(result.central_invalid_fraction, 0.6);
  ASSERT_GE(result.count, 1);
  EXPECT_TRUE(result.points[0].near_hazard);
  EXPECT_NEAR(result.points[0].distance_m, ObstacleConfig{}.min_range_m, 1e-9);
  EXPECT_GT(result.v_obs_horizontal_mps.normalized().dot(-R_QC.col(2)), std::cos(0.1 * kDeg));
}

TEST(ObstacleField, NanDepthIsIgnored) {
  cv::Mat depth = wall(3.0f);
  std::mt19937 rng(2);
  std::uniform_int_distribution<int> u(0, 639);
  std::uniform_int_distribution<int> v(0, 479);
  for (int i = 0; i < 20000; ++i) depth.at<float>(v(rng), u(rng)) = std::nanf("");
  ObstacleField field(ObstacleConfig{}, test_camera(), default_R_body_camera(),
                      Eigen::Vector3d::Zero());
  ObstacleResult result = field.compute(depth, Eigen::Matrix3d::Identity());
  EXPECT_FALSE(result.near_hazard);
  EXPECT_EQ(result.count, 0);
  EXPECT_TRUE(result.v_obs_horizontal_mps.allFinite());

  // NaN around a near wall patch: the patch still counts, the output stays finite.
  depth(cv::Rect(300, 220, 40, 40)).setTo(0.7f);
  result = field.compute(depth, Eigen::Matrix3d::Identity());
  ASSERT_GE(result.count, 1);
  EXPECT_NEAR(result.points[0].distance_m, 0.7, 0.02);
  EXPECT_TRUE(result.v_obs_horizontal_mps.allFinite());
}

TEST(ObstacleField, WrongImageIsReportedNotCrashed) {
  ObstacleField field(ObstacleConfig{}, test_camera(), default_R_body_camera(),
                      Eigen::Vector3d::Zero());
  const ObstacleResult result =
      field.compute(cv::Mat(240, 320, CV_32FC1, cv::Scalar(1.0f)), Eigen::Matrix3d::Identity());
  EXPECT_FALSE(result.valid);
  EXPECT_THAT(result.reason, HasSubstr("CV_32FC1"));
  EXPECT_TRUE(result.v_obs_horizontal_mps.isZero());
}

TEST(ObstacleField, ComputeAllocatesNothing) {
  ObstacleField field(ObstacleConfig{}, test_camera(), default_R_body_camera(),
                      Eigen::Vector3d::Zero());
  const cv::Mat near = wall(0.7f);
  const cv::Mat speckle = far_scene_with_speckle();
  const long before = hq::testing::allocation_count();
  for (int i = 0; i < 5; ++i) {
    static_cast<void>(field.compute(near, Eigen::Matrix3d::Identity()));
    static_cast<void>(field.compute(speckle, Eigen::Matrix3d::Identity()));
  }
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
}

TEST(ObstacleConfig, BadValueIsRejectedNamingTheKey) {
  const YAML::Node node = YAML::Load("{cell_px: 16, influence_distance_m: -1.2}");
  config::StrictMap section(node, "config/onboard.yaml", "obstacles");
  ObstacleConfig config;
  try {
    read_config(section, config);
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(
        e.what(),
        HasSubstr("config/onboard.yaml: obstacles.influence_distance_m = -1.2, expected > 0"));
  }
}

TEST(ObstacleConfig, ShippedOnboardYamlSectionLoads) {
  const YAML::Node root = config::load_yaml_file("config/onboard.yaml");
  config::StrictMap section(root["obstacles"], "config/onboard.yaml", "obstacles");
  ObstacleConfig config;
  EXPECT_NO_THROW(read_config(section, config));
}

TEST(ObstacleField, RememberedPointPushesWithTheSameLawAsAViewMinimum) {
  const Eigen::Matrix3d R_QC = default_R_body_camera();
  ObstacleField field(ObstacleConfig{}, test_camera(), R_QC, Eigen::Vector3d::Zero());
  const ObstacleResult seen = field.compute(wall(0.8f), Eigen::Matrix3d::Identity());
  ASSERT_EQ(seen.count, 1);
  // GIVEN nothing near in view (a wall at 6 m) WHEN the same point is remembered instead,
  // THEN v_obs is the same vector and the point is flagged as remembered.
  const std::array<Eigen::Vector3d, 2> remembered = {
      seen.points[0].p_horizontal_m,
      Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN())};
  const ObstacleResult result = field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), remembered);
  ASSERT_TRUE(result.valid);
  ASSERT_EQ(result.count, 1);  // the NaN point is skipped
  EXPECT_TRUE(result.points[0].remembered);
  EXPECT_FALSE(seen.points[0].remembered);
  EXPECT_LT((result.v_obs_horizontal_mps - seen.v_obs_horizontal_mps).norm(), 1e-9);
}

TEST(ObstacleField, RememberedPointsAddToTheViewAndSaturate) {
  ObstacleField field(ObstacleConfig{}, test_camera(), default_R_body_camera(),
                      Eigen::Vector3d::Zero());
  const std::array<Eigen::Vector3d, 1> behind = {Eigen::Vector3d(-0.5, 0.0, 0.0)};
  const ObstacleResult result = field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), behind);
  const double expected = 0.05 * (1.0 / 0.5 - 1.0 / 1.2) / (0.5 * 0.5);
  EXPECT_NEAR(result.v_obs_horizontal_mps.x(), expected, 1e-9);  // pushed forward
  const std::array<Eigen::Vector3d, 1> touching = {Eigen::Vector3d(-0.06, 0.0, 0.0)};
  const ObstacleResult saturated =
      field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), touching);
  EXPECT_NEAR(saturated.v_obs_horizontal_mps.norm(), ObstacleConfig{}.max_repulsive_speed_mps,
              1e-9);
}

}  // namespace
}  // namespace hq::obstacles
