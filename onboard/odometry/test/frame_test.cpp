// A frame's pyramids, and when its depth is turned to the colour image's exposure.
#include "frame.hpp"

#include "hq/geometry/lie.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace hq::odometry::detail {
namespace {

const geometry::PinholeCamera kCamera{100.0, 100.0, 31.5, 23.5, 64, 48};

TEST(LevelCameras, EachLevelHalvesTheResolution) {
  const LevelCameras cameras(kCamera, 3, 1);
  EXPECT_EQ(cameras.at(1).width, 32);
  EXPECT_EQ(cameras.at(2).height, 12);
  EXPECT_EQ(cameras.finest_pixels(), 32 * 24);
  EXPECT_FLOAT_EQ(cameras.intrinsics(1).fx, 50.0f);
}

TEST(DepthTermAt, ActsOnTheFinestDepthLevels) {
  OdometryConfig config;
  EXPECT_FALSE(depth_term_at(config, 1));
  config.use_depth_term = true;
  EXPECT_TRUE(depth_term_at(config, 3));
  config.depth_levels = 1;  // finest_level 1 only
  EXPECT_TRUE(depth_term_at(config, 1));
  EXPECT_FALSE(depth_term_at(config, 2));
}

class FrameBuilderTest : public ::testing::Test {
 protected:
  OdometryConfig config_ = [] {
    OdometryConfig c;
    c.pyramid_levels = 3;
    return c;
  }();
  LevelCameras cameras_{kCamera, config_.pyramid_levels, config_.finest_level};
  FrameBuilder builder_{config_, cameras_};
};

TEST_F(FrameBuilderTest, LevelsAreBlockMeansAndBadDepthIsNone) {
  FrameSlot slot;
  builder_.allocate(slot);
  cv::Mat gray(kCamera.height, kCamera.width, CV_8UC1);
  for (int v = 0; v < gray.rows; ++v) {
    for (int u = 0; u < gray.cols; ++u)
      gray.at<std::uint8_t>(v, u) = static_cast<std::uint8_t>(u + v);
  }
  cv::Mat depth(gray.size(), CV_32FC1, cv::Scalar(2.0f));
  depth.at<float>(0, 0) = std::numeric_limits<float>::quiet_NaN();
  depth.at<float>(0, 1) = 100.0f;  // beyond max_depth_m
  builder_.build(slot, gray, depth, false);
  // Level 1 (x, y) is the mean of level 0's 2x2 block at (2x, 2y): 2x + 2y + 1.
  EXPECT_FLOAT_EQ(at_level(slot.intensity, 1).at<float>(3, 5), 2.0f * 5 + 2.0f * 3 + 1.0f);
  EXPECT_FLOAT_EQ(at_level(slot.depth_m, 0).at<float>(0, 0), 0.0f);
  EXPECT_FLOAT_EQ(at_level(slot.depth_m, 0).at<float>(0, 1), 0.0f);
  EXPECT_FLOAT_EQ(at_level(slot.depth_m, 2).at<float>(5, 5), 2.0f);
}

TEST_F(FrameBuilderTest, DepthIsTurnedOnlyByARotationThatMovesAPixel) {
  RotationPrior prior;
  EXPECT_FALSE(builder_.should_align_depth(nullptr));
  EXPECT_FALSE(builder_.should_align_depth(&prior));  // identity
  prior.R_depth_colour = geometry::exp_so3(Eigen::Vector3d(0.0, 1e-3, 0.0));
  EXPECT_TRUE(builder_.should_align_depth(&prior));
  prior.R_depth_colour(0, 0) = 2.0;  // not a rotation
  EXPECT_FALSE(builder_.should_align_depth(&prior));
  prior.R_depth_colour(0, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(builder_.should_align_depth(&prior));
  prior.R_depth_colour = -Eigen::Matrix3d::Identity();  // a reflection
  EXPECT_FALSE(builder_.should_align_depth(&prior));
}

TEST_F(FrameBuilderTest, TurnedDepthFollowsTheRotation) {
  FrameSlot slot;
  builder_.allocate(slot);
  cv::Mat gray(kCamera.height, kCamera.width, CV_8UC1, cv::Scalar(100));
  cv::Mat depth(gray.size(), CV_32FC1, cv::Scalar(2.0f));
  depth(cv::Rect(0, 0, kCamera.width / 2, kCamera.height)) = 1.0f;  // left half nearer
  builder_.build(slot, gray, depth, true);
  const cv::Mat before = at_level(slot.depth_m, 1).clone();
  // Turning about the y axis by about 4 pixels of level 1 shifts the depth edge sideways.
  const double angle = std::atan(4.0 / 50.0);
  builder_.align_depth(slot, geometry::exp_so3(Eigen::Vector3d(0.0, angle, 0.0)));
  const cv::Mat& after = at_level(slot.depth_m, 1);
  EXPECT_GT(cv::norm(after, before, cv::NORM_L1), 10.0);
  // The coarser level is rebuilt from the turned one.
  EXPECT_GT(at_level(slot.depth_m, 2).at<float>(6, 4), 0.0f);
}

}  // namespace
}  // namespace hq::odometry::detail
