#include "pyramid.hpp"

#include <algorithm>
#include <cmath>

namespace hq::odometry::detail {

namespace {
template <typename T>
void downsample_mean(const cv::Mat& src, cv::Mat& dst) {
  for (int y = 0; y < dst.rows; ++y) {
    const T* row0 = src.ptr<T>(2 * y);
    const T* row1 = src.ptr<T>(2 * y + 1);
    float* out = dst.ptr<float>(y);
    for (int x = 0; x < dst.cols; ++x) {
      const int x2 = 2 * x;
      out[x] = 0.25f * (static_cast<float>(row0[x2]) + static_cast<float>(row0[x2 + 1]) +
                        static_cast<float>(row1[x2]) + static_cast<float>(row1[x2 + 1]));
    }
  }
}
}  // namespace

void downsample_intensity(const cv::Mat& src, cv::Mat& dst) {
  if (src.type() == CV_8UC1) {
    downsample_mean<unsigned char>(src, dst);
  } else {
    downsample_mean<float>(src, dst);
  }
}

void downsample_depth(const cv::Mat& src, cv::Mat& dst, float max_spread_ratio) {
  for (int y = 0; y < dst.rows; ++y) {
    const float* row0 = src.ptr<float>(2 * y);
    const float* row1 = src.ptr<float>(2 * y + 1);
    float* out = dst.ptr<float>(y);
    for (int x = 0; x < dst.cols; ++x) {
      const int x2 = 2 * x;
      const float d[4] = {row0[x2], row0[x2 + 1], row1[x2], row1[x2 + 1]};
      float sum = 0.0f;
      float nearest = 1e30f;
      float farthest = 0.0f;
      int count = 0;
      for (float v : d) {
        if (v > 0.0f) {
          sum += v;
          nearest = std::min(nearest, v);
          farthest = std::max(farthest, v);
          ++count;
        }
      }
      if (count == 0) {
        out[x] = 0.0f;
      } else if (farthest - nearest > max_spread_ratio * nearest) {
        out[x] = nearest;
      } else {
        out[x] = sum / static_cast<float>(count);
      }
    }
  }
}

void sanitize_depth(const cv::Mat& src, cv::Mat& dst, float min_m, float max_m) {
  for (int y = 0; y < src.rows; ++y) {
    const float* in = src.ptr<float>(y);
    float* out = dst.ptr<float>(y);
    for (int x = 0; x < src.cols; ++x) {
      const float v = in[x];
      // Written so that NaN fails the comparison and becomes 0.
      out[x] = (v >= min_m && v <= max_m) ? v : 0.0f;
    }
  }
}

}  // namespace hq::odometry::detail
