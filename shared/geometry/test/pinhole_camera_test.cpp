#include "hq/geometry/pinhole_camera.hpp"

#include <gtest/gtest.h>

namespace hq::geometry {
namespace {

PinholeCamera kinect() { return {525.0, 520.0, 319.5, 239.5, 640, 480}; }

TEST(PinholeCamera, UnprojectThenProjectReturnsThePixel) {
  const PinholeCamera camera = kinect();
  for (const double u : {0.0, 100.5, 319.5, 639.0}) {
    for (const double v : {0.0, 239.5, 479.0}) {
      for (const double depth_m : {0.4, 2.0, 7.5}) {
        const Eigen::Vector3d p_C = camera.unproject(u, v, depth_m);
        EXPECT_DOUBLE_EQ(p_C.z(), depth_m);
        const Eigen::Vector2d uv = camera.project(p_C);
        EXPECT_NEAR(uv.x(), u, 1e-9);
        EXPECT_NEAR(uv.y(), v, 1e-9);
        const Eigen::Vector3f p_C_float = camera.unproject(
            static_cast<float>(u), static_cast<float>(v), static_cast<float>(depth_m));
        EXPECT_TRUE(p_C_float.cast<double>().isApprox(p_C, 1e-5));
      }
    }
  }
}

TEST(PinholeCamera, ProjectionJacobianMatchesFiniteDifferences) {
  const PinholeCamera camera = kinect();
  const Eigen::Vector3d p_C(0.3, -0.2, 1.7);
  Eigen::Matrix<double, 2, 3> J;
  (void)camera.project(p_C, &J);
  constexpr double kStep = 1e-6;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d step = kStep * Eigen::Vector3d::Unit(i);
    const Eigen::Vector2d numeric =
        (camera.project(p_C + step) - camera.project(p_C - step)) / (2.0 * kStep);
    EXPECT_NEAR((J.col(i) - numeric).norm(), 0.0, 1e-4) << "column " << i;
  }
  Eigen::Vector3d J_depth;
  const Eigen::Vector3d p = camera.unproject(10.0, 20.0, 2.0, &J_depth);
  EXPECT_TRUE((camera.unproject(10.0, 20.0, 2.5) - p).isApprox(0.5 * J_depth, 1e-12));
}

TEST(PinholeCamera, LevelIntrinsicsKeepPixelCentresAligned) {
  const PinholeCamera level1 = kinect().at_level(1);
  EXPECT_DOUBLE_EQ(level1.fx, 262.5);
  EXPECT_DOUBLE_EQ(level1.cx, (319.5 + 0.5) * 0.5 - 0.5);
  EXPECT_EQ(level1.width, 320);
}

}  // namespace
}  // namespace hq::geometry
