#include "pyramid.hpp"

#include "hq/base/target_clones.hpp"

#include <algorithm>
#include <cmath>

namespace hq::odometry::detail {

namespace {
// Always inlined into the multi-versioned downsample_intensity, so built for its target.
template <typename T>
[[gnu::always_inline]] inline void downsample_mean(const cv::Mat& src, cv::Mat& dst) {
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

HQ_CLONES_X86_64_V3 void downsample_intensity(const cv::Mat& src, cv::Mat& dst) {
  if (src.type() == CV_8UC1) {
    downsample_mean<unsigned char>(src, dst);
  } else {
    downsample_mean<float>(src, dst);
  }
}

HQ_CLONES_X86_64_V3 void downsample_depth(const cv::Mat& src, cv::Mat& dst,
                                          float max_spread_ratio) {
  for (int y = 0; y < dst.rows; ++y) {
    const float* row0 = src.ptr<float>(2 * y);
    const float* row1 = src.ptr<float>(2 * y + 1);
    float* out = dst.ptr<float>(y);
    // Branch-free (selects, not ifs), so the row vectorises; an invalid depth adds 0 to the
    // sum, counts 0 and is never the nearest.
#pragma omp simd
    for (int x = 0; x < dst.cols; ++x) {
      const int x2 = 2 * x;
      const float d0 = row0[x2], d1 = row0[x2 + 1], d2 = row1[x2], d3 = row1[x2 + 1];
      const float v0 = d0 > 0.0f ? d0 : 0.0f, v1 = d1 > 0.0f ? d1 : 0.0f;
      const float v2 = d2 > 0.0f ? d2 : 0.0f, v3 = d3 > 0.0f ? d3 : 0.0f;
      const float count = (d0 > 0.0f ? 1.0f : 0.0f) + (d1 > 0.0f ? 1.0f : 0.0f) +
                          (d2 > 0.0f ? 1.0f : 0.0f) + (d3 > 0.0f ? 1.0f : 0.0f);
      const float sum = ((v0 + v1) + v2) + v3;
      constexpr float kNone = 1e30f;
      const float n0 = d0 > 0.0f ? d0 : kNone, n1 = d1 > 0.0f ? d1 : kNone;
      const float n2 = d2 > 0.0f ? d2 : kNone, n3 = d3 > 0.0f ? d3 : kNone;
      const float near01 = n0 < n1 ? n0 : n1, near23 = n2 < n3 ? n2 : n3;
      const float nearest = near01 < near23 ? near01 : near23;
      const float far01 = v0 > v1 ? v0 : v1, far23 = v2 > v3 ? v2 : v3;
      const float farthest = far01 > far23 ? far01 : far23;
      const float mean = sum / (count > 0.0f ? count : 1.0f);
      const float kept = (farthest - nearest > max_spread_ratio * nearest) ? nearest : mean;
      out[x] = count > 0.0f ? kept : 0.0f;
    }
  }
}

HQ_CLONES_X86_64_V3 void rotate_depth(const cv::Mat& src, cv::Mat& dst, float fx, float fy,
                                      float cx, float cy, const Eigen::Matrix3f& R_src_dst,
                                      float max_spread_ratio) {
  const auto max_su = static_cast<float>(src.cols - 1);
  const auto max_sv = static_cast<float>(src.rows - 1);
  // The bilinear cell's top-left corner stays one pixel inside, so its four loads are in src.
  const float cell_u = max_su - 1e-3f, cell_v = max_sv - 1e-3f;
  const auto stride = static_cast<int>(src.step1());
  const float* const depth = src.ptr<float>();
  const Eigen::Matrix3f& R = R_src_dst;
  // Each row in blocks of three passes: source positions (vectorised), the four depths of each
  // cell (the only scalar part: a gather), then the interpolation (vectorised).
  constexpr int kBlock = 64;
  float a[kBlock], b[kBlock], scale[kBlock], d00[kBlock], d01[kBlock], d10[kBlock], d11[kBlock];
  int cell[kBlock];
  for (int v = 0; v < dst.rows; ++v) {
    float* out = dst.ptr<float>(v);
    // The ray of (u, v) in src's camera, R (x_n, y_n, 1) with x_n = (u - cx) / fx, is linear
    // in u along the row: a + u b.
    const float y_n = (static_cast<float>(v) - cy) / fy;
    const float x_0 = -cx / fx;
    const float ax = R(0, 0) * x_0 + R(0, 1) * y_n + R(0, 2), bx = R(0, 0) / fx;
    const float ay = R(1, 0) * x_0 + R(1, 1) * y_n + R(1, 2), by = R(1, 0) / fx;
    const float az = R(2, 0) * x_0 + R(2, 1) * y_n + R(2, 2), bz = R(2, 0) / fx;
    for (int start = 0; start < dst.cols; start += kBlock) {
      const int n = std::min(kBlock, dst.cols - start);
#pragma omp simd
      for (int i = 0; i < n; ++i) {
        const auto uf = static_cast<float>(start + i);
        const float rz = az + uf * bz;
        const float inv_z = 1.0f / rz;
        const float su = fx * (ax + uf * bx) * inv_z + cx;
        const float sv = fy * (ay + uf * by) * inv_z + cy;
        // Along the ray (x_n, y_n, 1) of the turned camera, z is src's z over rz; rays that
        // leave src (or point behind it, or are NaN) get 0.
        // (& not &&: no branch, so the loop vectorises)
        const bool inside =
            (rz > 0.0f) & (su >= 0.0f) & (sv >= 0.0f) & (su <= max_su) & (sv <= max_sv);
        scale[i] = inside ? inv_z : 0.0f;
        const float cu = inside ? (su < cell_u ? su : cell_u) : 0.0f;
        const float cv = inside ? (sv < cell_v ? sv : cell_v) : 0.0f;
        const int u0 = static_cast<int>(cu);
        const int v0 = static_cast<int>(cv);
        a[i] = cu - static_cast<float>(u0);
        b[i] = cv - static_cast<float>(v0);
        cell[i] = v0 * stride + u0;
      }
      for (int i = 0; i < n; ++i) {
        const float* c = depth + cell[i];
        d00[i] = c[0];
        d01[i] = c[1];
        d10[i] = c[stride];
        d11[i] = c[stride + 1];
      }
#pragma omp simd
      for (int i = 0; i < n; ++i) {
        const float near_top = d00[i] < d01[i] ? d00[i] : d01[i];
        const float near_bottom = d10[i] < d11[i] ? d10[i] : d11[i];
        const float nearest = near_top < near_bottom ? near_top : near_bottom;
        const float far_top = d00[i] > d01[i] ? d00[i] : d01[i];
        const float far_bottom = d10[i] > d11[i] ? d10[i] : d11[i];
        const float farthest = far_top > far_bottom ? far_top : far_bottom;
        const float bilinear = (1.0f - b[i]) * ((1.0f - a[i]) * d00[i] + a[i] * d01[i]) +
                               b[i] * ((1.0f - a[i]) * d10[i] + a[i] * d11[i]);
        // Across an edge or beside missing depth: the nearest pixel's own depth (or none).
        const float top = a[i] < 0.5f ? d00[i] : d01[i];
        const float bottom = a[i] < 0.5f ? d10[i] : d11[i];
        const float own = b[i] < 0.5f ? top : bottom;
        const bool smooth = (nearest > 0.0f) & (farthest - nearest <= max_spread_ratio * nearest);
        out[start + i] = (smooth ? bilinear : own) * scale[i];
      }
    }
  }
}

HQ_CLONES_X86_64_V3 void sanitize_depth(const cv::Mat& src, cv::Mat& dst, float min_m,
                                        float max_m) {
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
