#pragma once
// Image and depth pyramids built into preallocated cv::Mat levels (private to hq_odometry).

#include <opencv2/core.hpp>

namespace hq::odometry::detail {

/// dst(y, x) = mean of the 2x2 block of src at (2y, 2x). src CV_8UC1 or CV_32FC1, dst CV_32FC1
/// of size src/2 (already allocated).
void downsample_intensity(const cv::Mat& src, cv::Mat& dst);

/// Mean of the valid depths (> 0) of each 2x2 block, 0 when none is valid. Blocks whose valid
/// depths differ by more than `max_spread_ratio` of the nearest keep the nearest: averaging
/// across an occlusion edge would invent a surface floating between the two.
void downsample_depth(const cv::Mat& src, cv::Mat& dst, float max_spread_ratio);

/// Copies depth, mapping NaN, Inf and values outside [min_m, max_m] to 0 (no depth).
void sanitize_depth(const cv::Mat& src, cv::Mat& dst, float min_m, float max_m);

}  // namespace hq::odometry::detail
