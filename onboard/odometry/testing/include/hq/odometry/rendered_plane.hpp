#pragma once
// A textured plane rendered exactly by ray casting: frames with known motion for odometry tests.

#include "hq/geometry/pinhole_camera.hpp"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

namespace hq::odometry::test {

/// Renders the plane z_G = plane_z_m, textured with smooth sinusoids, as seen by a camera
/// at T_G_C (optical frame). gray CV_8UC1, depth_m CV_32FC1 (0 where the ray misses).
void render_textured_plane(const geometry::PinholeCamera& camera, const Eigen::Isometry3d& T_G_C,
                           double plane_z_m, cv::Mat& gray, cv::Mat& depth_m);

/// A band x_G in [left_m, left_m + width_m] of the plane z_G = band_z_m, nearer than the
/// textured plane and textured in its own coordinates (so it carries its pattern as it moves),
/// drawn over gray and depth_m: an object moving independently of the scene, e.g. a person.
void render_moving_band(const geometry::PinholeCamera& camera, const Eigen::Isometry3d& T_G_C,
                        double band_z_m, double left_m, double width_m, cv::Mat& gray,
                        cv::Mat& depth_m);

}  // namespace hq::odometry::test
