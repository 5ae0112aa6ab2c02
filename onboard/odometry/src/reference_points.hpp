#pragma once
// A frame prepared as the reference of the alignment: the pixels that carry a residual, their
// points and the photometric Jacobians on the reference, computed once per reference instead
// of once per iteration (the inverse compositional form; private to hq_odometry).

#include "hq/odometry/dense_odometry.hpp"

#include "frame.hpp"
#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <array>
#include <vector>

namespace hq::odometry::detail {

// One prepared pyramid level of the reference frame, structure of arrays so that the warp and
// accumulation loops stream through memory.
struct ReferenceLevel {
  std::vector<float> x, y, z;      // 3D point in the reference camera frame, metres
  std::vector<float> intensity;    // I_ref at the pixel
  std::vector<float> photometric;  // 1 if the pixel has gradient (a photometric residual), else 0
  std::vector<float> gradient;     // |grad I_ref| at the pixel (intensity per pixel)
  std::vector<float> depth_point;  // 1 if the point may carry a depth residual, else 0
  std::vector<float> nx, ny, nz;   // its surface's unit normal (depth_jacobian_from_normals)
  std::array<std::vector<float>, 6> jacobian;  // d I_ref(pi(exp(xi) p)) / d xi at xi = 0
  std::vector<int> pixel;                      // v * width + u of the point's pixel at its level
  int count = 0;

  void reserve(int capacity);
};

using ReferenceSet = PerLevel<ReferenceLevel>;

/// The cosine of depth_max_incidence_deg: surfaces seen more obliquely add no depth residual.
float min_cos_incidence(const OdometryConfig& config);

class ReferencePreparer {
 public:
  ReferencePreparer(const OdometryConfig& config, const LevelCameras& cameras);

  /// Sizes the optimised levels of a set for every pixel (nothing allocates afterwards).
  void reserve(ReferenceSet& set) const;

  /// Selects the pixels of `slot` with depth and gradient (with the depth term, also those
  /// with depth on the depth_point_stride grid and a surface around them), leaving out those
  /// marked in `moving` (1 = moving; nullptr: none), and precomputes their points and
  /// Jacobians into `out`.
  void prepare(const FrameSlot& slot, const PerLevel<cv::Mat>* moving, ReferenceSet& out);

 private:
  const OdometryConfig& config_;
  const LevelCameras& cameras_;
  float min_cos_incidence_;
  PerLevel<cv::Mat> normal_map_;  // of the reference being prepared
};

}  // namespace hq::odometry::detail
