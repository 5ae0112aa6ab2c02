#include "hq/obstacles/obstacle_field.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/obstacles/support_surface.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"

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
Eigen::Matrix3d default_R_B_C() {
  Eigen::Matrix3d R_forward_optical;
  R_forward_optical << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  return Eigen::AngleAxisd(45.0 * kDeg, Eigen::Vector3d::UnitZ()).matrix() *
         Eigen::AngleAxisd(-30.0 * kDeg, Eigen::Vector3d::UnitY()).matrix() * R_forward_optical;
}

// A wall perpendicular to the optical axis: constant z.
cv::Mat wall(float z_m) { return cv::Mat(480, 640, CV_32FC1, cv::Scalar(z_m)); }

TEST(ObstacleField, FlatWallPushesAwayAlongTheCameraAxisHorizontalProjection) {
  const Eigen::Matrix3d R_QC = default_R_B_C();
  ObstacleField field(ObstacleConfig{}, test_camera(), R_QC, Eigen::Vector3d::Zero());
  const ObstacleResult result = field.compute(wall(0.8f), Eigen::Matrix3d::Identity());
  ASSERT_TRUE(result.valid);
  EXPECT_FALSE(result.near_hazard);
  ASSERT_EQ(result.count, 1);  // one nearest point on a flat wall
  EXPECT_NEAR(result.points[0].distance_m, 0.8, 0.01);

  const Eigen::Vector3d axis_H = R_QC.col(2);  // optical axis, H = Q for a level vehicle
  const Eigen::Vector2d axis_horizontal = axis_H.head<2>().normalized();
  const Eigen::Vector2d push_horizontal = result.v_obs_H_mps.head<2>();
  ASSERT_GT(push_horizontal.norm(), 0.01);
  EXPECT_GT(push_horizontal.normalized().dot(-axis_horizontal), std::cos(1.0 * kDeg));
  // The camera looks down, so the push also has an upward (NED z < 0) part.
  EXPECT_LT(result.v_obs_H_mps.z(), 0.0);
  // Magnitude of the Khatib term on the clearance d = 0.8 m - vehicle_radius_m (the law now acts
  // on the distance to the vehicle's sphere, not to its centre), d0 = 1.0, eta = 0.05.
  const ObstacleConfig config;
  const double d = 0.8 - config.vehicle_radius_m;
  const double d0 = config.influence_distance_m;
  const double expected = config.gain * (1.0 / d - 1.0 / d0) / (d * d);
  EXPECT_NEAR(result.v_obs_H_mps.norm(), expected, 0.02 * expected);
}

TEST(ObstacleField, PitchedVehicleSeesTheWallInH) {
  // A vehicle pitched 10 deg nose down: the same wall is seen 10 deg further down in H.
  const Eigen::Matrix3d R_QC = default_R_B_C();
  ObstacleField field(ObstacleConfig{}, test_camera(), R_QC, Eigen::Vector3d::Zero());
  const Eigen::Matrix3d R_HQ = Eigen::AngleAxisd(-10.0 * kDeg, Eigen::Vector3d::UnitY()).matrix();
  const ObstacleResult result = field.compute(wall(0.8f), R_HQ);
  ASSERT_EQ(result.count, 1);
  const Eigen::Vector3d expected_direction = -(R_HQ * R_QC.col(2));
  EXPECT_GT(result.v_obs_H_mps.normalized().dot(expected_direction), std::cos(1.0 * kDeg));
}

TEST(ObstacleField, NothingWithinRangeGivesZero) {
  ObstacleField field(ObstacleConfig{}, test_camera(), default_R_B_C(),
                      Eigen::Vector3d(0.1, 0.0, 0.05));
  const ObstacleResult result = field.compute(wall(3.0f), Eigen::Matrix3d::Identity());
  ASSERT_TRUE(result.valid);
  EXPECT_EQ(result.count, 0);
  EXPECT_TRUE(result.v_obs_H_mps.isZero());
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
  ObstacleField field(ObstacleConfig{}, test_camera(), default_R_B_C(), Eigen::Vector3d::Zero());
  const ObstacleResult result =
      field.compute(far_scene_with_speckle(), Eigen::Matrix3d::Identity());
  ASSERT_TRUE(result.valid);
  EXPECT_EQ(result.count, 0);
  EXPECT_TRUE(result.v_obs_H_mps.isZero());

  // The same scene with a plain min-pool (rank 1) would see obstacles everywhere.
  ObstacleConfig plain;
  plain.speckle_rank = 1;
  ObstacleField naive(plain, test_camera(), default_R_B_C(), Eigen::Vector3d::Zero());
  EXPECT_GT(naive.compute(far_scene_with_speckle(), Eigen::Matrix3d::Identity()).count, 0);
}

TEST(ObstacleField, VeryCloseWallSaturates) {
  ObstacleConfig config;
  config.min_range_m = 0.0;
  ObstacleField field(config, test_camera(), default_R_B_C(), Eigen::Vector3d::Zero());
  const ObstacleResult result = field.compute(wall(0.12f), Eigen::Matrix3d::Identity());
  EXPECT_NEAR(result.v_obs_H_mps.norm(), config.max_repulsive_speed_mps, 1e-12);
}

TEST(ObstacleField, NearInvalidCentralBlobIsAHazardAndPushes) {
  // GIVEN a far scene whose centre is invalid, as when a surface is nearer than the min range.
  cv::Mat depth = wall(3.0f);
  depth(cv::Rect(200, 140, 240, 200)).setTo(0.0f);
  const Eigen::Matrix3d R_QC = default_R_B_C();
  ObstacleField field(ObstacleConfig{}, test_camera(), R_QC, Eigen::Vector3d::Zero());
  const ObstacleResult result = field.compute(depth, Eigen::Matrix3d::Identity());
  EXPECT_TRUE(result.near_hazard);
  EXPECT_GT(result.central_invalid_fraction, 0.6);
  ASSERT_GE(result.count, 1);
  EXPECT_TRUE(result.points[0].near_hazard);
  EXPECT_NEAR(result.points[0].distance_m, ObstacleConfig{}.min_range_m, 1e-9);
  EXPECT_GT(result.v_obs_H_mps.normalized().dot(-R_QC.col(2)), std::cos(0.1 * kDeg));
}

TEST(ObstacleField, NanDepthIsIgnored) {
  cv::Mat depth = wall(3.0f);
  std::mt19937 rng(2);
  std::uniform_int_distribution<int> u(0, 639);
  std::uniform_int_distribution<int> v(0, 479);
  for (int i = 0; i < 20000; ++i) depth.at<float>(v(rng), u(rng)) = std::nanf("");
  ObstacleField field(ObstacleConfig{}, test_camera(), default_R_B_C(), Eigen::Vector3d::Zero());
  ObstacleResult result = field.compute(depth, Eigen::Matrix3d::Identity());
  EXPECT_FALSE(result.near_hazard);
  EXPECT_EQ(result.count, 0);
  EXPECT_TRUE(result.v_obs_H_mps.allFinite());

  // NaN around a near wall patch: the patch still counts, the output stays finite.
  depth(cv::Rect(300, 220, 40, 40)).setTo(0.7f);
  result = field.compute(depth, Eigen::Matrix3d::Identity());
  ASSERT_GE(result.count, 1);
  EXPECT_NEAR(result.points[0].distance_m, 0.7, 0.02);
  EXPECT_TRUE(result.v_obs_H_mps.allFinite());
}

TEST(ObstacleField, WrongImageIsReportedNotCrashed) {
  ObstacleField field(ObstacleConfig{}, test_camera(), default_R_B_C(), Eigen::Vector3d::Zero());
  const ObstacleResult result =
      field.compute(cv::Mat(240, 320, CV_32FC1, cv::Scalar(1.0f)), Eigen::Matrix3d::Identity());
  EXPECT_FALSE(result.valid);
  EXPECT_THAT(result.reason, HasSubstr("CV_32FC1"));
  EXPECT_TRUE(result.v_obs_H_mps.isZero());
}

TEST(ObstacleField, ComputeAllocatesNothing) {
  ObstacleField field(ObstacleConfig{}, test_camera(), default_R_B_C(), Eigen::Vector3d::Zero());
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

TEST(ObstacleField, RememberedPointPushesAsAColumnOnItsHorizontalOffset) {
  const Eigen::Matrix3d R_QC = default_R_B_C();
  ObstacleField field(ObstacleConfig{}, test_camera(), R_QC, Eigen::Vector3d::Zero());
  // A wall at 0.6 m along the 30 deg down axis: the camera sees it by its face below the body.
  const ObstacleResult seen = field.compute(wall(0.6f), Eigen::Matrix3d::Identity());
  ASSERT_EQ(seen.count, 1);
  const Eigen::Vector3d p = seen.points[0].p_H_m;
  ASSERT_GT(p.z(), 0.1);
  // GIVEN nothing near in view (a wall at 6 m) WHEN that point is remembered instead (and a NaN
  // one), THEN it pushes as the wall's column does at the vehicle's height: horizontally, with
  // the view's law on its horizontal offset, flagged as remembered.
  const std::array<Eigen::Vector3d, 2> remembered = {
      p, Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN())};
  const ObstacleResult result = field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), remembered);
  ASSERT_TRUE(result.valid);
  ASSERT_EQ(result.count, 1);  // the NaN point is skipped
  EXPECT_TRUE(result.points[0].remembered);
  EXPECT_FALSE(seen.points[0].remembered);
  const ObstacleResult column =
      field.compute(wall(6.0f), Eigen::Matrix3d::Identity(),
                    std::array<Eigen::Vector3d, 1>{Eigen::Vector3d(p.x(), p.y(), 0.0)});
  EXPECT_LT((result.v_obs_H_mps - column.v_obs_H_mps).norm(), 1e-12);
  EXPECT_EQ(result.v_obs_H_mps.z(), 0.0);
  EXPECT_GT(result.v_obs_H_mps.head<2>().norm(), seen.v_obs_H_mps.head<2>().norm());
  // A face remembered 0.37 m below (beyond the sphere's radius) still pushes: the campaign's
  // back-up collisions came from treating it as floor.
  const std::array<Eigen::Vector3d, 1> low = {Eigen::Vector3d(-0.8, 0.0, 0.37)};
  EXPECT_GT(field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), low).v_obs_H_mps.x(), 0.05);
}

TEST(ObstacleField, RememberedPointsAddToTheViewAndSaturate) {
  ObstacleField field(ObstacleConfig{}, test_camera(), default_R_B_C(), Eigen::Vector3d::Zero());
  // 0.9 m behind the centre is 0.55 m of clearance (vehicle_radius_m 0.35): below saturation.
  const ObstacleConfig config;
  const std::array<Eigen::Vector3d, 1> behind = {Eigen::Vector3d(-0.9, 0.0, 0.0)};
  const ObstacleResult result = field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), behind);
  const double d = 0.9 - config.vehicle_radius_m;
  const double expected = config.gain * (1.0 / d - 1.0 / config.influence_distance_m) / (d * d);
  ASSERT_LT(expected, config.max_repulsive_speed_mps);
  EXPECT_NEAR(result.v_obs_H_mps.x(), expected, 1e-9);  // pushed forward
  EXPECT_NEAR(result.v_obs_H_mps.norm(), expected, 1e-9);
  // Inside the vehicle's sphere (the propellers touch it): saturated.
  const std::array<Eigen::Vector3d, 1> touching = {Eigen::Vector3d(-0.06, 0.0, 0.0)};
  const ObstacleResult saturated = field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), touching);
  EXPECT_NEAR(saturated.v_obs_H_mps.norm(), ObstacleConfig{}.max_repulsive_speed_mps, 1e-9);
}

// eq. of Khatib 1986 on the clearance d = |p| - vehicle_radius_m.
double khatib_speed(const ObstacleConfig& config, double d) {
  return config.gain * (1.0 / d - 1.0 / config.influence_distance_m) / (d * d);
}

TEST(ObstacleField, KhatibLawActsOnTheClearanceToTheVehicleSphere) {
  // A non-default configuration, so that every parameter of the law is exercised.
  ObstacleConfig config;
  config.vehicle_radius_m = 0.2;
  config.influence_distance_m = 1.5;
  config.gain = 0.08;
  config.max_repulsive_speed_mps = 100.0;
  ObstacleField field(config, test_camera(), default_R_B_C(), Eigen::Vector3d::Zero());
  const Eigen::Vector3d directions[] = {Eigen::Vector3d(-1.0, 0.0, 0.0),
                                        Eigen::Vector3d(0.0, 1.0, 0.0),
                                        Eigen::Vector3d(0.6, -0.8, 0.0)};
  // Remembered points probe the law at the vehicle's height (they push on their horizontal
  // offset); off-horizontal view points are covered by the flat-wall test.
  for (const Eigen::Vector3d& direction : directions) {
    for (const double d : {0.1, 0.4, 0.9, 1.4}) {
      // GIVEN one remembered point at |p| = r + d (nothing near in view).
      const std::array<Eigen::Vector3d, 1> point = {(config.vehicle_radius_m + d) * direction};
      const ObstacleResult result = field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), point);
      ASSERT_TRUE(result.valid);
      // THEN v_obs = eta (1/d - 1/d0) / d^2 away from the point.
      const Eigen::Vector3d expected = -khatib_speed(config, d) * direction;
      EXPECT_LT((result.v_obs_H_mps - expected).norm(), 1e-9 * expected.norm())
          << "d " << d << ": " << result.v_obs_H_mps.transpose() << " vs " << expected.transpose();
    }
    // ... AND nothing at d >= d0 of clearance, though |p| itself is then below d0 + r.
    const std::array<Eigen::Vector3d, 1> far = {
        (config.vehicle_radius_m + config.influence_distance_m + 1e-6) * direction};
    const ObstacleResult outside = field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), far);
    EXPECT_TRUE(outside.v_obs_H_mps.isZero());
    EXPECT_EQ(outside.count, 0);
  }
}

TEST(ObstacleField, SaturatesAtTheConfiguredSpeed) {
  const ObstacleConfig config;
  ObstacleField field(config, test_camera(), default_R_B_C(), Eigen::Vector3d::Zero());
  // 0.1 m of clearance gives 45 m/s by the law; 1.5 m/s is the configured ceiling.
  const std::array<Eigen::Vector3d, 1> point = {
      Eigen::Vector3d(0.0, -(config.vehicle_radius_m + 0.1), 0.0)};
  ASSERT_GT(khatib_speed(config, 0.1), config.max_repulsive_speed_mps);
  const ObstacleResult result = field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), point);
  EXPECT_NEAR(result.v_obs_H_mps.norm(), config.max_repulsive_speed_mps, 1e-9);
  EXPECT_NEAR(result.v_obs_H_mps.y(), config.max_repulsive_speed_mps, 1e-9);
}

// Depth of a horizontal floor height_m below the camera (level vehicle, camera at the body
// centre): each pixel's ray meets the plane z_H = height_m.
cv::Mat floor_below(const Eigen::Matrix3d& R_HC, double height_m) {
  const geometry::PinholeCamera camera = test_camera();
  cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(0.0f));
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3d ray_C = camera.ray(u, v);
      const double down = (R_HC * ray_C).z();
      if (down > 0.0) depth.at<float>(v, u) = static_cast<float>(height_m / down);
    }
  }
  return depth;
}

TEST(ObstacleField, FloorBelowPushesOnlyUpwardsWithinSupportInfluence) {
  const ObstacleConfig config;
  const Eigen::Matrix3d R_QC = default_R_B_C();
  ObstacleField field(config, test_camera(), R_QC, Eigen::Vector3d::Zero());
  // GIVEN the floor 0.28 m below (within support_influence_m 0.3): nearest pixels at 0.34 m.
  const double height_m = 0.28;
  ASSERT_LT(height_m, config.support_influence_m);
  const ObstacleResult result =
      field.compute(floor_below(R_QC, height_m), Eigen::Matrix3d::Identity());
  ASSERT_TRUE(result.valid) << result.reason;
  EXPECT_FALSE(result.near_hazard);
  // THEN the push is straight up (NED -z), none sideways (the point law would shove the vehicle
  // back from the floor it looks at) ...
  EXPECT_EQ(result.v_obs_H_mps.x(), 0.0);
  EXPECT_EQ(result.v_obs_H_mps.y(), 0.0);
  ASSERT_LT(result.v_obs_H_mps.z(), 0.0);
  EXPECT_EQ(result.count, 0);
  // ... AND every floor minimum is at that height, so the push is a whole number of support
  // terms eta (1/h - 1/h0) / h^2.
  const double one =
      config.gain * (1.0 / height_m - 1.0 / config.support_influence_m) / (height_m * height_m);
  const double terms = -result.v_obs_H_mps.z() / one;
  EXPECT_GE(terms, 1.0 - 1e-4);
  EXPECT_NEAR(terms, std::round(terms), 1e-3) << terms;

  // WHEN the floor is beyond support_influence_m (0.32 m: its nearest pixels are only 0.04 m
  // from the vehicle's sphere) THEN nothing at all.
  const ObstacleResult beyond = field.compute(floor_below(R_QC, 0.32), Eigen::Matrix3d::Identity());
  ASSERT_TRUE(beyond.valid);
  EXPECT_TRUE(beyond.v_obs_H_mps.isZero()) << beyond.v_obs_H_mps.transpose();
  EXPECT_EQ(beyond.count, 0);
  // ... while a larger support_influence_m reaches it (upwards again).
  ObstacleConfig wide = config;
  wide.support_influence_m = 0.5;
  ObstacleField wide_field(wide, test_camera(), R_QC, Eigen::Vector3d::Zero());
  const ObstacleResult reached =
      wide_field.compute(floor_below(R_QC, 0.32), Eigen::Matrix3d::Identity());
  EXPECT_LT(reached.v_obs_H_mps.z(), 0.0);
  EXPECT_EQ(reached.v_obs_H_mps.head<2>().norm(), 0.0);
}

TEST(ObstacleField, FloorInViewGivesTheHeightAboveItAndATableTopDoesNot) {
  const ObstacleConfig config;
  const Eigen::Matrix3d R_QC = default_R_B_C();
  ObstacleField field(config, test_camera(), R_QC, Eigen::Vector3d::Zero());
  // GIVEN the floor 1.2 m below, seen by the camera looking 30 deg down
  cv::Mat depth = floor_below(R_QC, 1.2);
  ObstacleResult result = field.compute(depth, Eigen::Matrix3d::Identity());
  ASSERT_TRUE(result.valid) << result.reason;
  EXPECT_NEAR(result.floor_height_m, 1.2, 0.01);
  // WHEN a table top 0.5 m below covers the image's lower left quarter, THEN the floor is still
  // the lowest surface seen
  const cv::Mat table = floor_below(R_QC, 0.5);
  table(cv::Rect(0, 240, 320, 240)).copyTo(depth(cv::Rect(0, 240, 320, 240)));
  result = field.compute(depth, Eigen::Matrix3d::Identity());
  EXPECT_NEAR(result.floor_height_m, 1.2, 0.01);
  // WHEN nothing horizontal is in view (a wall), THEN no height, and the wall's clearance
  result = field.compute(wall(1.0F), Eigen::Matrix3d::Identity());
  EXPECT_TRUE(std::isnan(result.floor_height_m));
  EXPECT_NEAR(result.min_clearance_m, 1.0 - config.vehicle_radius_m, 0.02);
  // and a wall far beyond d0 pushes nothing but still gives the clearance the operator sees
  result = field.compute(wall(7.0F), Eigen::Matrix3d::Identity());
  EXPECT_EQ(result.v_obs_H_mps.norm(), 0.0);
  EXPECT_NEAR(result.min_clearance_m, 7.0 - config.vehicle_radius_m, 0.05);
  // and nothing within the sensor's range (max_range_m 8): no clearance
  result = field.compute(wall(9.0F), Eigen::Matrix3d::Identity());
  EXPECT_EQ(result.min_clearance_m, -1.0);
}

TEST(ObstacleField, GroundPhaseIgnoresTheNearHazardAndEverythingBelow) {
  const ObstacleConfig config;
  const Eigen::Matrix3d R_QC = default_R_B_C();
  ObstacleField field(config, test_camera(), R_QC, Eigen::Vector3d::Zero());
  cv::Mat blob = wall(3.0f);
  blob(cv::Rect(200, 140, 240, 200)).setTo(0.0f);
  const cv::Mat floor = floor_below(R_QC, 0.28);
  const std::array<Eigen::Vector3d, 1> below = {Eigen::Vector3d(0.1, 0.0, 0.2)};
  const std::array<Eigen::Vector3d, 1> beside = {Eigen::Vector3d(-0.9, 0.0, 0.0)};
  // GIVEN the same inputs push outside the ground phase ...
  EXPECT_FALSE(field.ground_phase());
  ASSERT_GT(field.compute(blob, Eigen::Matrix3d::Identity()).v_obs_H_mps.norm(), 0.1);
  ASSERT_LT(field.compute(floor, Eigen::Matrix3d::Identity()).v_obs_H_mps.z(), 0.0);
  const ObstacleResult below_air = field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), below);
  ASSERT_GT(below_air.v_obs_H_mps.norm(), 0.1);
  const ObstacleResult beside_air = field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), beside);

  // WHEN taking off or landing
  field.set_ground_phase(true);
  EXPECT_TRUE(field.ground_phase());
  // THEN the near-range hazard is still reported but does not push ...
  const ObstacleResult hazard = field.compute(blob, Eigen::Matrix3d::Identity());
  ASSERT_TRUE(hazard.valid);
  EXPECT_TRUE(hazard.near_hazard);
  EXPECT_EQ(hazard.count, 0);
  EXPECT_TRUE(hazard.v_obs_H_mps.isZero());
  // ... the floor does not push ...
  EXPECT_TRUE(field.compute(floor, Eigen::Matrix3d::Identity()).v_obs_H_mps.isZero());
  // ... nor a remembered point below ...
  const ObstacleResult below_ground = field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), below);
  EXPECT_TRUE(below_ground.v_obs_H_mps.isZero());
  EXPECT_EQ(below_ground.count, 0);
  // ... but one beside the vehicle pushes as in the air.
  const ObstacleResult beside_ground =
      field.compute(wall(6.0f), Eigen::Matrix3d::Identity(), beside);
  EXPECT_GT(beside_ground.v_obs_H_mps.norm(), 0.1);
  EXPECT_LT((beside_ground.v_obs_H_mps - beside_air.v_obs_H_mps).norm(), 1e-12);

  field.set_ground_phase(false);
  EXPECT_GT(field.compute(blob, Eigen::Matrix3d::Identity()).v_obs_H_mps.norm(), 0.1);
}

TEST(ObstacleField, MostlyNanFrameIsCorruptNotAHazard) {
  const Eigen::Matrix3d R_QC = default_R_B_C();
  ObstacleField field(ObstacleConfig{}, test_camera(), R_QC, Eigen::Vector3d::Zero());
  // GIVEN a frame of NaN but for a near patch in a corner.
  cv::Mat corrupt(480, 640, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  corrupt(cv::Rect(0, 0, 64, 64)).setTo(0.6f);
  const ObstacleResult result = field.compute(corrupt, Eigen::Matrix3d::Identity());
  // THEN invalid with the reason, and no push (neither the hazard nor the patch).
  EXPECT_FALSE(result.valid);
  EXPECT_STREQ(result.reason, "depth frame corrupt: mostly NaN");
  EXPECT_GT(result.nan_fraction, 0.5);
  EXPECT_FALSE(result.near_hazard);
  EXPECT_TRUE(result.v_obs_H_mps.isZero());
  EXPECT_EQ(result.count, 0);

  // An all-zero frame is what a sensor returns with a surface inside its minimum range: still
  // the near hazard, pushing back along the optical axis.
  const ObstacleResult zero = field.compute(wall(0.0f), Eigen::Matrix3d::Identity());
  ASSERT_TRUE(zero.valid);
  EXPECT_EQ(zero.nan_fraction, 0.0);
  EXPECT_TRUE(zero.near_hazard);
  ASSERT_GT(zero.v_obs_H_mps.norm(), 0.1);
  EXPECT_GT(zero.v_obs_H_mps.normalized().dot(-R_QC.col(2)), std::cos(0.1 * kDeg));
}

TEST(ObstacleConfig, ClearanceAndSupportKeysAreReadAndRangeChecked) {
  config::StrictMap section(YAML::Load("{vehicle_radius_m: 0.3, support_normal_max_deg: 20, "
                                       "support_influence_m: 0.4}"),
                            "config/onboard.yaml", "obstacles");
  ObstacleConfig config;
  read_config(section, config);
  EXPECT_EQ(config.vehicle_radius_m, 0.3);
  EXPECT_EQ(config.support_normal_max_deg, 20.0);
  EXPECT_EQ(config.support_influence_m, 0.4);
  const auto error = [](const char* yaml) {
    config::StrictMap bad(YAML::Load(yaml), "config/onboard.yaml", "obstacles");
    ObstacleConfig out;
    return hq::testing::input_error_message([&] { read_config(bad, out); });
  };
  EXPECT_THAT(error("{vehicle_radius_m: -0.1}"),
              HasSubstr("obstacles.vehicle_radius_m = -0.1, expected in [0, 5]"));
  EXPECT_THAT(error("{support_normal_max_deg: 95}"),
              HasSubstr("obstacles.support_normal_max_deg = 95, expected in [0, 90]"));
  EXPECT_THAT(error("{support_influence_m: 11}"),
              HasSubstr("obstacles.support_influence_m = 11, expected in [0, 10]"));
}

// A zero gain is no avoidance (1515 collision ticks in the core-paper flight), not a setting.
TEST(ObstacleConfig, ZeroGainIsRejected) {
  config::StrictMap section(YAML::Load("{gain: 0}"), "config/onboard.yaml", "obstacles");
  ObstacleConfig config;
  EXPECT_THAT(hq::testing::input_error_message([&] { read_config(section, config); }),
              HasSubstr("config/onboard.yaml: obstacles.gain = 0, expected > 0"));
}

// A plane seen by a camera at the origin: points z / (n . ray) along each pixel's ray.
struct PlaneDepth {
  geometry::PinholeCamera camera;
  Eigen::Vector3d n_C;  // plane n . p = d
  double d;
  std::vector<int> holes_u;  // columns without depth

  bool operator()(int u, int v, Eigen::Vector3d& p_C) const {
    for (int hole : holes_u) {
      if (u == hole) return false;
    }
    const Eigen::Vector3d ray_C = camera.ray(u, v);
    p_C = camera.unproject(u, v, d / n_C.dot(ray_C));
    return true;
  }
};

TEST(SupportSurface, NormalOfAPlaneIsItsNormalWithEitherStencilAndOneSidedAtHoles) {
  // GIVEN a floor 1 m below a camera looking forward and 30 deg down (H: z down)
  const geometry::PinholeCamera camera = test_camera();
  Eigen::Matrix3d R_forward_optical;
  R_forward_optical << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  const Eigen::Matrix3d R_H_C =
      Eigen::AngleAxisd(-30.0 * kDeg, Eigen::Vector3d::UnitY()).matrix() * R_forward_optical;
  PlaneDepth floor{camera, R_H_C.transpose() * Eigen::Vector3d::UnitZ(), 1.0, {}};
  Eigen::Vector3d p_C;
  ASSERT_TRUE(floor(320, 400, p_C));
  for (const NormalStencil stencil : {NormalStencil::kCentralWhereBoth, NormalStencil::kOneSided}) {
    // WHEN its normal is estimated, with all neighbours and with the +u neighbour missing
    for (const std::vector<int>& holes : {std::vector<int>{}, std::vector<int>{328}}) {
      floor.holes_u = holes;
      Eigen::Vector3d n_C;
      ASSERT_TRUE(
          surface_normal_C(floor, 320, 400, camera.width, camera.height, 8, stencil, p_C, n_C));
      // THEN it is the plane's normal (up to sign), a support surface within 1 deg of vertical
      EXPECT_NEAR(std::abs(n_C.normalized().dot(floor.n_C)), 1.0, 1e-9);
      EXPECT_TRUE(is_support_normal(R_H_C, n_C, std::cos(1.0 * kDeg)));
    }
  }
  // AND a wall (normal horizontal in H) is not one; without neighbours there is no normal.
  PlaneDepth wall{camera, R_H_C.transpose() * Eigen::Vector3d::UnitX(), 2.0, {}};
  ASSERT_TRUE(wall(320, 240, p_C));
  Eigen::Vector3d n_C;
  ASSERT_TRUE(surface_normal_C(wall, 320, 240, camera.width, camera.height, 8,
                               NormalStencil::kCentralWhereBoth, p_C, n_C));
  EXPECT_FALSE(is_support_normal(R_H_C, n_C, std::cos(25.0 * kDeg)));
  wall.holes_u = {312, 328};
  EXPECT_FALSE(surface_normal_C(wall, 320, 240, camera.width, camera.height, 8,
                                NormalStencil::kOneSided, p_C, n_C));
}

TEST(CheckCamera, NamesTheComponentForABadCameraOrMount) {
  geometry::PinholeCamera camera = test_camera();
  EXPECT_NO_THROW(check_camera("x", camera, default_R_B_C(), Eigen::Vector3d::Zero()));
  camera.fy = 0.0;
  EXPECT_THAT(hq::testing::input_error_message(
                  [&] { check_camera("seen", camera, default_R_B_C(), Eigen::Vector3d::Zero()); }),
              HasSubstr("seen: camera 640x480"));
  EXPECT_THAT(hq::testing::input_error_message([&] {
                check_camera("seen", test_camera(), default_R_B_C(),
                             Eigen::Vector3d(std::nan(""), 0.0, 0.0));
              }),
              HasSubstr("seen: R_B_C is not a rotation"));
}

}  // namespace
}  // namespace hq::obstacles
