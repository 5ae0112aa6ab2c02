#pragma once
// The odometry's private parts wired as DenseOdometry wires them, over the rendered textured
// plane: a reference frame prepared, and a current frame built, at chosen camera poses.

#include "hq/geometry/lie.hpp"
#include "hq/odometry/rendered_plane.hpp"

#include "frame.hpp"
#include "reference_points.hpp"

namespace hq::odometry::test {

inline const geometry::PinholeCamera kPlaneCamera{525.0, 525.0, 319.5, 239.5, 640, 480};
inline constexpr double kPlaneZ = 2.0;

/// x, y, z in metres, then the rotation vector (rad).
inline Eigen::Isometry3d pose(double x, double y, double z, double rx, double ry, double rz) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = geometry::exp_so3(Eigen::Vector3d(rx, ry, rz));
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

/// Not copyable: the parts hold references to the configuration and the cameras.
struct PreparedPlane {
  explicit PreparedPlane(const OdometryConfig& c)
      : config(c),
        cameras(kPlaneCamera, config.pyramid_levels, config.finest_level),
        frames(config, cameras),
        preparer(config, cameras) {
    frames.allocate(reference_frame);
    frames.allocate(current);
    preparer.reserve(reference);
  }
  PreparedPlane(const PreparedPlane&) = delete;
  PreparedPlane& operator=(const PreparedPlane&) = delete;

  static void render(const Eigen::Isometry3d& T_G_C, cv::Mat& gray, cv::Mat& depth_m) {
    render_textured_plane(kPlaneCamera, T_G_C, kPlaneZ, gray, depth_m);
  }
  /// The reference seen from T_G_C, its pixels in `moving` left out (nullptr: none).
  void prepare_reference(const Eigen::Isometry3d& T_G_C,
                         const detail::PerLevel<cv::Mat>* moving = nullptr) {
    cv::Mat gray, depth_m;
    render(T_G_C, gray, depth_m);
    prepare_reference(gray, depth_m, moving);
  }
  void prepare_reference(const cv::Mat& gray, const cv::Mat& depth_m,
                         const detail::PerLevel<cv::Mat>* moving = nullptr) {
    frames.build(reference_frame, gray, depth_m, false);
    preparer.prepare(reference_frame, moving, reference);
  }
  void build_current(const Eigen::Isometry3d& T_G_C) {
    cv::Mat gray, depth_m;
    render(T_G_C, gray, depth_m);
    frames.build(current, gray, depth_m, false);
  }

  OdometryConfig config;
  detail::LevelCameras cameras;
  detail::FrameBuilder frames;
  detail::ReferencePreparer preparer;
  detail::FrameSlot reference_frame;
  detail::FrameSlot current;
  detail::ReferenceSet reference;
};

}  // namespace hq::odometry::test
