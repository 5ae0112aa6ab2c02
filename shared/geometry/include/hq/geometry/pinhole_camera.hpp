#pragma once
/// Ideal pinhole intrinsics of an undistorted image, their image-pyramid levels, and projection
/// between the camera frame C and pixels (frames: hq/geometry/frames.hpp).

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

  /// Pixel (u, v) of a point p_C in the camera frame (z > 0 in front of the camera). With
  /// J_uv_p, also the 2x3 Jacobian d(u, v)/d(p_C). The caller checks z > 0 and the image bounds.
  [[nodiscard]] Eigen::Vector2d project(const Eigen::Vector3d& p_C,
                                        Eigen::Matrix<double, 2, 3>* J_uv_p = nullptr) const {
    const double inv_z = 1.0 / p_C.z();
    const double x_n = p_C.x() * inv_z;
    const double y_n = p_C.y() * inv_z;
    if (J_uv_p != nullptr) {
      *J_uv_p << fx * inv_z, 0.0, -fx * x_n * inv_z,  //
          0.0, fy * inv_z, -fy * y_n * inv_z;
    }
    return {fx * x_n + cx, fy * y_n + cy};
  }

  /// The ray through pixel (u, v) on the plane z = 1 in C (normalised image coordinates).
  [[nodiscard]] Eigen::Vector3d ray(double u, double v) const {
    return {(u - cx) / fx, (v - cy) / fy, 1.0};
  }

  /// The point in C seen at pixel (u, v) with depth depth_m along the optical axis (z, not the
  /// range: what RGB-D depth images hold). With J_p_depth, also d(p_C)/d(depth), i.e. the ray.
  [[nodiscard]] Eigen::Vector3d unproject(double u, double v, double depth_m,
                                          Eigen::Vector3d* J_p_depth = nullptr) const {
    const Eigen::Vector3d ray_C = ray(u, v);
    if (J_p_depth != nullptr) *J_p_depth = ray_C;
    return depth_m * ray_C;
  }

  /// Float version of unproject for per-pixel loops over float images.
  [[nodiscard]] Eigen::Vector3f unproject(float u, float v, float depth_m) const {
    return {depth_m * (u - static_cast<float>(cx)) / static_cast<float>(fx),
            depth_m * (v - static_cast<float>(cy)) / static_cast<float>(fy), depth_m};
  }

  [[nodiscard]] Eigen::Matrix3d K() const {
    Eigen::Matrix3d k;
    k << fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0;
    return k;
  }
};

}  // namespace hq::geometry
