#pragma once
/// Ideal pinhole intrinsics of an undistorted image, and their image-pyramid levels.

#include <Eigen/Core>

namespace hq::geometry {

/// Pinhole intrinsics in pixels for a width x height image with no distortion.
struct PinholeCamera {
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  int width = 0;
  int height = 0;

  /// Intrinsics of the image downsampled `level` times by 2x2 averaging (pixel centres at
  /// integer coordinates, so c' = (c + 0.5) / 2 - 0.5).
  [[nodiscard]] PinholeCamera at_level(int level) const {
    PinholeCamera c = *this;
    for (int i = 0; i < level; ++i) {
      c.fx *= 0.5;
      c.fy *= 0.5;
      c.cx = (c.cx + 0.5) * 0.5 - 0.5;
      c.cy = (c.cy + 0.5) * 0.5 - 0.5;
      c.width /= 2;
      c.height /= 2;
    }
    return c;
  }

  [[nodiscard]] Eigen::Matrix3d K() const {
    Eigen::Matrix3d k;
    k << fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0;
    return k;
  }
};

}  // namespace hq::geometry
