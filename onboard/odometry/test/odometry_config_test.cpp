// The odometry's configuration: the strict YAML reader and validate(), which the constructor
// runs as well.
#include "hq/config/strict_yaml.hpp"
#include "hq/odometry/dense_odometry.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <limits>

namespace hq::odometry {
namespace {

using ::testing::HasSubstr;

const geometry::PinholeCamera kCamera{525.0, 525.0, 319.5, 239.5, 640, 480};

TEST(OdometryConfig, ReadsKeysAndRejectsBadValues) {
  const YAML::Node good = YAML::Load(
      "{finest_level: 0, reference_mode: frame_to_keyframe, use_motion_prior: true,"
      " use_depth_term: true, depth_point_stride: 3, use_rotation_prior: false,"
      " keyframe_check: true, keyframe_check_max_rotation_deg: 1.0, depth_levels: 2,"
      " estimate_gyro_bias: false, gyro_bias_random_walk: 0.001,"
      " depth_jacobian_from_normals: false, depth_normal_smoothing_levels: 1,"
      " depth_max_incidence_deg: 60, min_translation_information_ratio: 0.02,"
      " degenerate_step_ratio: 0.005,"
      " align_depth_to_colour: false, occlusion_depth_ratio: 0.2, moving_residual_sigmas: 5,"
      " max_moving_ratio: 0.3, drop_moving_keyframe_points: false, dense_moving_marks: true,"
      " moving_min_displacement_px: 0.5, moving_realign_ratio: 0.1, moving_mark_radius_px: 4}");
  config::StrictMap section(good, "onboard.yaml", "odometry");
  OdometryConfig config;
  read_config(section, config);
  EXPECT_EQ(config.finest_level, 0);
  EXPECT_EQ(config.reference_mode, ReferenceMode::kFrameToKeyframe);
  EXPECT_TRUE(config.use_motion_prior);
  EXPECT_TRUE(config.use_depth_term);
  EXPECT_EQ(config.depth_point_stride, 3);
  EXPECT_FALSE(config.use_rotation_prior);
  EXPECT_TRUE(config.keyframe_check);
  EXPECT_DOUBLE_EQ(config.keyframe_check_max_rotation_deg, 1.0);
  EXPECT_EQ(config.depth_levels, 2);
  EXPECT_FALSE(config.estimate_gyro_bias);
  EXPECT_DOUBLE_EQ(config.gyro_bias_random_walk, 0.001);
  EXPECT_FALSE(config.depth_jacobian_from_normals);
  EXPECT_EQ(config.depth_normal_smoothing_levels, 1);
  EXPECT_DOUBLE_EQ(config.depth_max_incidence_deg, 60.0);
  EXPECT_DOUBLE_EQ(config.min_translation_information_ratio, 0.02);
  EXPECT_DOUBLE_EQ(config.degenerate_step_ratio, 0.005);
  EXPECT_FALSE(config.align_depth_to_colour);
  EXPECT_DOUBLE_EQ(config.occlusion_depth_ratio, 0.2);
  EXPECT_DOUBLE_EQ(config.moving_residual_sigmas, 5.0);
  EXPECT_DOUBLE_EQ(config.max_moving_ratio, 0.3);
  EXPECT_FALSE(config.drop_moving_keyframe_points);
  EXPECT_TRUE(config.dense_moving_marks);
  EXPECT_DOUBLE_EQ(config.moving_min_displacement_px, 0.5);
  EXPECT_DOUBLE_EQ(config.moving_realign_ratio, 0.1);
  EXPECT_EQ(config.moving_mark_radius_px, 4);

  const auto expect_error = [](const std::string& yaml, const std::string& expected) {
    config::StrictMap s(YAML::Load(yaml), "onboard.yaml", "odometry");
    OdometryConfig c;
    try {
      read_config(s, c);
      FAIL() << "accepted " << yaml;
    } catch (const InputError& e) {
      EXPECT_THAT(e.what(), HasSubstr(expected));
    }
  };
  expect_error("{min_depth_m: -1}", "onboard.yaml: odometry.min_depth_m = -1, expected > 0");
  expect_error("{finest_level: 5, pyramid_levels: 4}", "odometry.finest_level");
  expect_error("{reference_mode: sideways}", "expected one of frame_to_frame");
  expect_error("{max_iterations: 3}", "odometry.max_iterations is not a known key");
  expect_error("{depth_noise_per_m: 0}", "odometry.depth_noise_per_m = 0, expected > 0");
  expect_error("{depth_point_stride: 0}", "odometry.depth_point_stride");
  expect_error("{depth_levels: 4}",  // 4 levels, finest 1: three optimised levels
               "odometry.depth_levels = 4, expected <= pyramid_levels - finest_level (3)");
  expect_error("{depth_levels: -1}", "odometry.depth_levels = -1");
  expect_error("{occlusion_depth_ratio: -0.1}", "odometry.occlusion_depth_ratio = -0.1");
  expect_error("{moving_residual_sigmas: .nan}", "odometry.moving_residual_sigmas");
  expect_error("{max_moving_ratio: 1.5}", "odometry.max_moving_ratio = 1.5");
  expect_error("{drop_moving_keyframe_points: 3}", "odometry.drop_moving_keyframe_points");
  expect_error("{moving_min_displacement_px: -1}", "odometry.moving_min_displacement_px = -1");
  expect_error("{moving_realign_ratio: 2}", "odometry.moving_realign_ratio = 2");
  expect_error("{moving_mark_radius_px: 0}", "odometry.moving_mark_radius_px = 0");
  expect_error("{gyro_bias_sigma_radps: 0}", "odometry.gyro_bias_sigma_radps = 0, expected > 0");
  expect_error("{gyro_bias_gate_chi2: .nan}", "odometry.gyro_bias_gate_chi2");
  expect_error("{estimate_gyro_bias: maybe}", "odometry.estimate_gyro_bias");
  expect_error("{align_depth_to_colour: 1.5}", "odometry.align_depth_to_colour");
  expect_error("{depth_max_incidence_deg: 90}", "odometry.depth_max_incidence_deg = 90");
  expect_error("{depth_normal_smoothing_levels: -1}", "odometry.depth_normal_smoothing_levels");
  expect_error("{degenerate_step_ratio: -0.1}", "odometry.degenerate_step_ratio = -0.1");
  expect_error("{min_translation_information_ratio: 1.5}",
               "odometry.min_translation_information_ratio = 1.5");
  expect_error("{min_depth_m: 2.0, max_depth_m: 1.5}",
               "onboard.yaml: odometry.max_depth_m = 1.5, expected > min_depth_m (2)");
}

TEST(OdometryConfig, ConstructorRejectsWhatTheReaderRejectsInsteadOfClamping) {
  const geometry::PinholeCamera camera{100.0, 100.0, 31.5, 23.5, 64, 48};
  OdometryConfig too_fine;
  too_fine.pyramid_levels = 3;
  too_fine.finest_level = 3;
  try {
    const DenseOdometry odometry(too_fine, camera);
    FAIL() << "finest_level 3 of 3 levels accepted";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(),
                HasSubstr("OdometryConfig.finest_level = 3, expected < pyramid_levels (3)"));
  }
  OdometryConfig too_deep;
  too_deep.pyramid_levels = 9;
  EXPECT_THROW(DenseOdometry(too_deep, camera), InputError);
  OdometryConfig not_a_number;
  not_a_number.student_t_dof = std::nan("");
  EXPECT_THROW(DenseOdometry(not_a_number, camera), InputError);
}

}  // namespace
}  // namespace hq::odometry
