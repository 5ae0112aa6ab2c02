#pragma once
// One frame as the odometry holds it: intensity and depth pyramids in preallocated levels, the
// camera of each level, and the depth turned to the colour image's exposure (private to
// hq_odometry).

#include "hq/geometry/pinhole_camera.hpp"
#include "hq/odometry/dense_odometry.hpp"

#include "kernels.hpp"
#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <array>
#include <cstddef>

namespace hq::odometry::detail {

inline constexpr int kMaxLevels = 6;
// Blocks whose depths spread by more than this fraction are treated as occlusion edges.
inline constexpr float kDepthEdgeSpreadRatio = 0.05f;

/// One per pyramid level; levels are ints in the configuration and in every loop over them.
template <class T>
using PerLevel = std::array<T, kMaxLevels>;

template <class T>
T& at_level(PerLevel<T>& levels, int level) {
  return levels[static_cast<std::size_t>(level)];
}
template <class T>
const T& at_level(const PerLevel<T>& levels, int level) {
  return levels[static_cast<std::size_t>(level)];
}

struct FrameSlot {
  PerLevel<cv::Mat> intensity;  // CV_32FC1; level 0 unused if finest_level > 0
  PerLevel<cv::Mat> depth_m;    // CV_32FC1, 0 = no depth
};

/// The camera of each pyramid level and which levels are optimised (finest .. levels - 1).
class LevelCameras {
 public:
  LevelCameras(const geometry::PinholeCamera& camera, int levels, int finest);

  [[nodiscard]] const geometry::PinholeCamera& at(int level) const {
    return at_level(cameras_, level);
  }
  /// Float intrinsics of a level, as the per-point kernels take them.
  [[nodiscard]] Intrinsics intrinsics(int level) const {
    const geometry::PinholeCamera& cam = at(level);
    return {static_cast<float>(cam.fx), static_cast<float>(cam.fy), static_cast<float>(cam.cx),
            static_cast<float>(cam.cy)};
  }
  [[nodiscard]] int levels() const { return levels_; }
  [[nodiscard]] int finest() const { return finest_; }
  /// valid_ratio's denominator.
  [[nodiscard]] int finest_pixels() const { return at(finest_).width * at(finest_).height; }

 private:
  PerLevel<geometry::PinholeCamera> cameras_;
  int levels_;
  int finest_;
};

/// Whether the depth residual acts on this level (the finest depth_levels levels).
inline bool depth_term_at(const OdometryConfig& config, int level) {
  return config.use_depth_term &&
         (config.depth_levels == 0 || level < config.finest_level + config.depth_levels);
}

/// Builds a frame's pyramids into preallocated slots, turning its depth to the colour image's
/// exposure when the gyro says how.
class FrameBuilder {
 public:
  FrameBuilder(const OdometryConfig& config, const LevelCameras& cameras);

  /// Allocates and clears every level of a slot (its pages mapped before the first frame).
  void allocate(FrameSlot& slot) const;

  /// Whether a frame's depth is turned: by a finite rotation matrix that moves a pixel at all.
  [[nodiscard]] bool should_align_depth(const RotationPrior* prior) const;

  /// A depth that align_depth will turn is built only down to the finest level used: the
  /// coarser levels are rebuilt from the turned one there.
  void build(FrameSlot& slot, const cv::Mat& gray, const cv::Mat& depth_m,
             bool depth_to_be_turned) const;

  /// Turns the depth, from the finest level used up, to the colour image's exposure (the
  /// rotation between the two; coarser levels rebuilt from the turned one).
  void align_depth(FrameSlot& slot, const Eigen::Matrix3d& R_depth_colour);

 private:
  const OdometryConfig& config_;
  const LevelCameras& cameras_;
  cv::Mat turned_depth_;  // the finest level's depth turned to the colour's exposure
};

}  // namespace hq::odometry::detail
