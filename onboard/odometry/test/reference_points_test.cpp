// A frame prepared as the reference: which pixels carry a residual, and what is precomputed
// for them.
#include "reference_points.hpp"

#include "kernels.hpp"
#include "prepared_plane.hpp"
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>

namespace hq::odometry::detail {
namespace {

using test::PreparedPlane;

TEST(ReferencePreparer, TexturedPixelsWithDepthBecomePointsWithTheirJacobians) {
  const OdometryConfig config;
  PreparedPlane plane(config);
  plane.prepare_reference(Eigen::Isometry3d::Identity());
  for (int l = config.finest_level; l < config.pyramid_levels; ++l) {
    const ReferenceLevel& ref = at_level(plane.reference, l);
    const geometry::PinholeCamera& cam = plane.cameras.at(l);
    ASSERT_GT(ref.count, cam.width * cam.height / 4) << "level " << l;
    const Intrinsics k = plane.cameras.intrinsics(l);
    for (std::size_t i = 0; i < static_cast<std::size_t>(ref.count); i += 97) {
      // The plane z_G = 2 seen head-on: every point 2 m away, on a pixel of the image.
      EXPECT_NEAR(ref.z[i], test::kPlaneZ, 1e-5);
      EXPECT_EQ(ref.photometric[i], 1.0f);  // intensity only: every point is textured
      const float u = k.fx * ref.x[i] / ref.z[i] + k.cx;
      const float v = k.fy * ref.y[i] / ref.z[i] + k.cy;
      EXPECT_NEAR(u, std::round(u), 1e-3);
      EXPECT_NEAR(v, std::round(v), 1e-3);
      // The Jacobian's translation part is the gradient through the projection: J_x = g_x f/z.
      const cv::Mat& I = at_level(plane.reference_frame.intensity, l);
      const int iu = static_cast<int>(std::lround(u));
      const int iv = static_cast<int>(std::lround(v));
      const float gx = 0.5f * (I.at<float>(iv, iu + 1) - I.at<float>(iv, iu - 1));
      EXPECT_NEAR(ref.jacobian[0][i], gx * k.fx / ref.z[i], 1e-3f * (1.0f + std::abs(gx)));
      EXPECT_EQ(ref.intensity[i], I.at<float>(iv, iu));
    }
  }
}

TEST(ReferencePreparer, FlatImageWithoutTheDepthTermHasNoPoints) {
  const OdometryConfig config;
  PreparedPlane plane(config);
  cv::Mat gray(test::kPlaneCamera.height, test::kPlaneCamera.width, CV_8UC1, cv::Scalar(128));
  cv::Mat depth_m(gray.size(), CV_32FC1, cv::Scalar(2.0f));
  plane.prepare_reference(gray, depth_m);
  EXPECT_EQ(at_level(plane.reference, config.finest_level).count, 0);
}

TEST(ReferencePreparer, FlatImageWithTheDepthTermKeepsTheDepthGrid) {
  OdometryConfig config;
  config.use_depth_term = true;
  config.depth_point_stride = 4;
  PreparedPlane plane(config);
  cv::Mat gray(test::kPlaneCamera.height, test::kPlaneCamera.width, CV_8UC1, cv::Scalar(128));
  cv::Mat depth_m(gray.size(), CV_32FC1, cv::Scalar(2.0f));
  plane.prepare_reference(gray, depth_m);
  const ReferenceLevel& ref = at_level(plane.reference, config.finest_level);
  const geometry::PinholeCamera& cam = plane.cameras.at(config.finest_level);
  // Inner pixels (1 .. size - 2) on the 4-pixel grid: 79 x 59 at 320x240.
  EXPECT_EQ(ref.count, ((cam.width - 2) / 4) * ((cam.height - 2) / 4));
  for (std::size_t i = 0; i < static_cast<std::size_t>(ref.count); ++i) {
    ASSERT_EQ(ref.photometric[i], 0.0f);
    ASSERT_EQ(ref.depth_point[i], 1.0f);
    ASSERT_EQ(ref.jacobian[3][i], 0.0f);
  }
}

TEST(ReferencePreparer, NormalsOfAPlaneFacingTheCameraPointAlongTheRay) {
  OdometryConfig config;
  config.use_depth_term = true;
  config.depth_jacobian_from_normals = true;
  PreparedPlane plane(config);
  plane.prepare_reference(Eigen::Isometry3d::Identity());
  const ReferenceLevel& ref = at_level(plane.reference, config.finest_level);
  int with_normal = 0;
  for (std::size_t i = 0; i < static_cast<std::size_t>(ref.count); ++i) {
    if (ref.depth_point[i] == 0.0f) continue;
    ++with_normal;
    ASSERT_NEAR(std::abs(ref.nz[i]), 1.0f, 1e-3f);
  }
  EXPECT_GT(with_normal, ref.count / 2);
}

TEST(ReferencePreparer, PixelsMarkedMovingAreLeftOut) {
  const OdometryConfig config;
  PreparedPlane plane(config);
  plane.prepare_reference(Eigen::Isometry3d::Identity());
  const int all_points = at_level(plane.reference, config.finest_level).count;
  PerLevel<cv::Mat> moving;
  for (int l = config.finest_level; l < config.pyramid_levels; ++l) {
    const geometry::PinholeCamera& cam = plane.cameras.at(l);
    at_level(moving, l) = cv::Mat::zeros(cam.height, cam.width, CV_8UC1);
    // The left half of every level moved.
    at_level(moving, l)(cv::Rect(0, 0, cam.width / 2, cam.height)) = 1;
  }
  plane.prepare_reference(Eigen::Isometry3d::Identity(), &moving);
  const ReferenceLevel& ref = at_level(plane.reference, config.finest_level);
  EXPECT_LT(ref.count, all_points * 6 / 10);
  EXPECT_GT(ref.count, all_points * 4 / 10);
  const Intrinsics k = plane.cameras.intrinsics(config.finest_level);
  for (std::size_t i = 0; i < static_cast<std::size_t>(ref.count); ++i) {
    ASSERT_GE(k.fx * ref.x[i] / ref.z[i] + k.cx, static_cast<float>(160) - 1e-3f);
  }
}

}  // namespace
}  // namespace hq::odometry::detail
