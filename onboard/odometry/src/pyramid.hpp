#pragma once
// Image and depth pyramids built into preallocated cv::Mat levels (private to hq_odometry).

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace hq::odometry::detail {

/// dst(y, x) = mean of the 2x2 block of src at (2y, 2x). src CV_8UC1 or CV_32FC1, dst CV_32FC1
/// of size src/2 (already allocated).
void downsample_intensity(const cv::Mat& src, cv::Mat& dst);

/// Mean of the valid depths (> 0) of each 2x2 block, 0 when none is valid. Blocks whose valid
/// depths differ by more than `max_spread_ratio` of the nearest keep the nearest: averaging
/// across an occlusion edge would invent a surface floating between the two.
void downsample_depth(const cv::Mat& src, cv::Mat& dst, float max_spread_ratio);

/// The depth map src seen by the same camera turned by a pure rotation: dst(x) is the depth,
/// along the turned camera's ray of pixel x, of the surface src saw; R_src_dst maps that ray
/// into src's camera. A rotation moves pixels independently of depth (a homography), so the
/// resampling is exact but for the interpolation: bilinear between four valid depths within
/// max_spread_ratio of the nearest, else the nearest pixel's; 0 where the ray leaves src or
/// meets no depth. fx, fy, cx, cy are src's and dst's intrinsics (same size).
void rotate_depth(const cv::Mat& src, cv::Mat& dst, float fx, float fy, float cx, float cy,
                  const Eigen::Matrix3f& R_src_dst, float max_spread_ratio);

/// Copies depth, mapping NaN, Inf and values outside [min_m, max_m] to 0 (no depth).
void sanitize_depth(const cv::Mat& src, cv::Mat& dst, float min_m, float max_m);

}  // namespace hq::odometry::detail
