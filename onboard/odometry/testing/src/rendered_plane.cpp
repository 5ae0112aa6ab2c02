#include "hq/odometry/rendered_plane.hpp"

#include <algorithm>
#include <cmath>

namespace hq::odometry::test {

namespace {
// Several incommensurate frequencies: rich gradients in every direction, no aliasing at the
// sizes used in the tests.
double texture(double x, double y) {
  const double v = 0.35 * std::sin(9.0 * x + 1.0) + 0.25 * std::sin(13.0 * y + 0.3) +
                   0.2 * std::sin(7.0 * (x + y)) + 0.2 * std::cos(17.0 * x - 11.0 * y);
  return 128.0 + 110.0 * v;
}

// Where the ray of pixel (u, v) meets the plane z_G = plane_z_m: its distance s along the
// ray (the depth: the ray's camera z is 1) and the point; false when it does not.
bool ray_meets_plane(const geometry::PinholeCamera& camera, const Eigen::Isometry3d& T_G_C, int u,
                     int v, double plane_z_m, double& s, Eigen::Vector3d& p) {
  const Eigen::Vector3d d_camera((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0);
  const Eigen::Vector3d d_G = T_G_C.linear() * d_camera;
  const Eigen::Vector3d& o = T_G_C.translation();
  s = d_G.z() != 0.0 ? (plane_z_m - o.z()) / d_G.z() : -1.0;
  if (s <= 0.0) return false;
  p = o + s * d_G;
  return true;
}
}  // namespace

void render_textured_plane(const geometry::PinholeCamera& camera, const Eigen::Isometry3d& T_G_C,
                           double plane_z_m, cv::Mat& gray, cv::Mat& depth_m) {
  gray.create(camera.height, camera.width, CV_8UC1);
  depth_m.create(camera.height, camera.width, CV_32FC1);
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      double s = 0.0;
      Eigen::Vector3d p;
      if (!ray_meets_plane(camera, T_G_C, u, v, plane_z_m, s, p)) {
        gray.at<unsigned char>(v, u) = 0;
        depth_m.at<float>(v, u) = 0.0f;
        continue;
      }
      gray.at<unsigned char>(v, u) =
          static_cast<unsigned char>(std::clamp(std::lround(texture(p.x(), p.y())), 0L, 255L));
      depth_m.at<float>(v, u) = static_cast<float>(s);  // d_camera.z() == 1
    }
  }
}

void render_moving_band(const geometry::PinholeCamera& camera, const Eigen::Isometry3d& T_G_C,
                        double band_z_m, double left_m, double width_m, cv::Mat& gray,
                        cv::Mat& depth_m) {
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      double s = 0.0;
      Eigen::Vector3d p;
      if (!ray_meets_plane(camera, T_G_C, u, v, band_z_m, s, p)) continue;
      const double along = p.x() - left_m;
      if (along < 0.0 || along > width_m) continue;
      // Its own pattern, coarser than the plane's and shifted: the band is not the plane.
      gray.at<unsigned char>(v, u) = static_cast<unsigned char>(
          std::clamp(std::lround(texture(0.7 * along + 3.0, 0.7 * p.y() - 2.0)), 0L, 255L));
      depth_m.at<float>(v, u) = static_cast<float>(s);
    }
  }
}

}  // namespace hq::odometry::test
