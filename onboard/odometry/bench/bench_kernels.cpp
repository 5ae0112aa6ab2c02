// hq-bench-odometry-kernels: Google Benchmark of DenseOdometry's per-point kernels on a
// 320x240 level's worth of points (76800): the warp + intensity sample, the depth residual
// with its Jacobian (whole, and split as the odometry runs it: the gather, then the rows formed
// inside their accumulation), the one-pass normal-equation accumulation, and the depth map
// turned to the colour's exposure beside a plain copy of it. Built, not run by ctest. The
// benchmarks are multi-versioned as the odometry's functions that inline these kernels are, so
// they time the build the odometry runs on this machine.
#include "hq/base/target_clones.hpp"

#include "kernels.hpp"
#include "pyramid.hpp"
#include <Eigen/Geometry>
#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include <cmath>
#include <vector>

namespace {

using namespace hq::odometry::detail;

constexpr int kWidth = 320;
constexpr int kHeight = 240;
constexpr int kPoints = kWidth * kHeight;
const Intrinsics kK{262.5f, 262.5f, 159.5f, 119.5f};
const Warp kWarp{0.9998f,  -0.0175f, 0.0087f, 0.0174f, 0.9998f, 0.0052f,
                 -0.0088f, -0.0050f, 0.9999f, 0.01f,   -0.005f, 0.02f};

struct Scene {
  std::vector<float> image, depth, x, y, z, intensity, r, w, o;
  std::vector<float> J[6];
  Scene()
      : image(kPoints),
        depth(kPoints),
        x(kPoints),
        y(kPoints),
        z(kPoints),
        intensity(kPoints),
        r(kPoints),
        w(kPoints, 1.0f),
        o(kPoints, 0.5f) {
    for (auto& j : J) j.assign(kPoints, 0.1f);
    for (int v = 0; v < kHeight; ++v) {
      for (int u = 0; u < kWidth; ++u) {
        const auto i = static_cast<std::size_t>(v * kWidth + u);
        const auto u_px = static_cast<float>(u);
        const auto v_px = static_cast<float>(v);
        image[i] = 128.0f + 60.0f * std::sin(0.2f * u_px) * std::cos(0.15f * v_px);
        depth[i] = 1.5f + 0.002f * u_px + 0.001f * v_px;
        z[i] = depth[i];
        x[i] = (u_px - kK.cx) * z[i] / kK.fx;
        y[i] = (v_px - kK.cy) * z[i] / kK.fy;
        intensity[i] = image[i];
      }
    }
  }
};

const Scene& scene() {
  static const Scene s;
  return s;
}

HQ_CLONES_X86_64_V3 void BM_WarpAndSampleIntensity(benchmark::State& state) {
  const Scene& s = scene();
  std::vector<float> residual(kPoints);
  for (auto _ : state) {
    for (std::size_t i = 0; i < residual.size(); ++i) {
      float qx, qy, qz;
      kWarp.apply(s.x[i], s.y[i], s.z[i], qx, qy, qz);
      const float u = kK.fx * qx / qz + kK.cx;
      const float v = kK.fy * qy / qz + kK.cy;
      residual[i] = (u >= 0.0f && v >= 0.0f && u < kWidth - 1.001f && v < kHeight - 1.001f)
                        ? sample_bilinear(s.image.data(), kWidth, u, v) - s.intensity[i]
                        : 0.0f;
    }
    benchmark::DoNotOptimize(residual.data());
  }
  state.SetItemsProcessed(state.iterations() * kPoints);
}
BENCHMARK(BM_WarpAndSampleIntensity);

HQ_CLONES_X86_64_V3 void BM_DepthResidualAndJacobian(benchmark::State& state) {
  const Scene& s = scene();
  std::vector<float> residual(kPoints);
  std::vector<float> jacobian(6 * kPoints);
  for (auto _ : state) {
    for (std::size_t i = 0; i < residual.size(); ++i) {
      depth_residual(s.depth.data(), kWidth, kWidth - 1.001f, kHeight - 1.001f, kK, kWarp, s.x[i],
                     s.y[i], s.z[i], 0.15f, 0.0015f, 0.05f, residual[i], &jacobian[6 * i]);
    }
    benchmark::DoNotOptimize(residual.data());
    benchmark::DoNotOptimize(jacobian.data());
  }
  state.SetItemsProcessed(state.iterations() * kPoints);
}
BENCHMARK(BM_DepthResidualAndJacobian);

// The gather half of the depth residual as DenseOdometry runs it: residual and d r / d q only,
// d r / d q from the current depth's gradient (arg 0) or from the reference normal, rotated
// into the current camera (arg 1, depth_jacobian_from_normals).
HQ_CLONES_X86_64_V3 void BM_DepthSample(benchmark::State& state) {
  const Scene& s = scene();
  const bool from_normals = state.range(0) != 0;
  const auto cos_75 = static_cast<float>(std::cos(75.0 * M_PI / 180.0));
  std::vector<float> residual(kPoints);
  std::vector<float> a[3];
  for (auto& c : a) c.assign(kPoints, 0.0f);
  for (auto _ : state) {
    for (std::size_t i = 0; i < static_cast<std::size_t>(kPoints); ++i) {
      float qx, qy, qz;
      kWarp.apply(s.x[i], s.y[i], s.z[i], qx, qy, qz);
      const float u = kK.fx * qx / qz + kK.cx;
      const float v = kK.fy * qy / qz + kK.cy;
      float d[3] = {0.0f, 0.0f, 0.0f};
      if (u >= 0.0f && v >= 0.0f && u < kWidth - 1.001f && v < kHeight - 1.001f) {
        if (from_normals) {
          float nx, ny, nz;
          kWarp.rotate(0.0f, 0.0f, -1.0f, nx, ny, nz);
          depth_sample_on_surface(s.depth.data(), kWidth, qx, qy, qz, u, v, nx, ny, nz, cos_75,
                                  0.0015f, 0.05f, residual[i], d);
        } else {
          depth_sample_at(s.depth.data(), kWidth, kK, qx, qy, qz, u, v, 0.0015f, 0.05f, residual[i],
                          d);
        }
      }
      a[0][i] = d[0];
      a[1][i] = d[1];
      a[2][i] = d[2];
    }
    benchmark::DoNotOptimize(residual.data());
    benchmark::DoNotOptimize(a[0].data());
  }
  state.SetItemsProcessed(state.iterations() * kPoints);
}
BENCHMARK(BM_DepthSample)->Arg(0)->Arg(1);

// The whitened depth rows formed inside their accumulation (the other half of the depth term).
HQ_CLONES_X86_64_V3 void BM_AccumulateDepthRows(benchmark::State& state) {
  const Scene& s = scene();
  DepthRows rows;
  for (int k = 0; k < 3; ++k) rows.d_rz_d_q[k] = s.J[k].data();
  rows.px = s.x.data();
  rows.py = s.y.data();
  rows.pz = s.z.data();
  rows.rz = s.intensity.data();
  rows.ri = s.intensity.data();
  for (int k = 0; k < 6; ++k) rows.ji[k] = s.J[k].data();
  rows.c_z = s.w.data();
  rows.c_i = s.o.data();
  rows.T = kWarp;
  for (auto _ : state) {
    RowSums sums;
    accumulate_depth_rows(rows, s.w.data(), kPoints, sums);
    benchmark::DoNotOptimize(sums);
  }
  state.SetItemsProcessed(state.iterations() * kPoints);
}
BENCHMARK(BM_AccumulateDepthRows);

HQ_CLONES_X86_64_V3 void BM_AccumulateRows(benchmark::State& state) {
  const Scene& s = scene();
  const float* J[6] = {s.J[0].data(), s.J[1].data(), s.J[2].data(),
                       s.J[3].data(), s.J[4].data(), s.J[5].data()};
  const bool offset_rows = state.range(0) != 0;
  for (auto _ : state) {
    RowSums sums;
    accumulate_rows(J, s.intensity.data(), s.w.data(), kPoints, sums,
                    offset_rows ? s.o.data() : nullptr);
    benchmark::DoNotOptimize(sums);
  }
  state.SetItemsProcessed(state.iterations() * kPoints);
}
BENCHMARK(BM_AccumulateRows)->Arg(0)->Arg(1);

// A 320x240 depth map turned by 0.2 deg (Kinect v1's 5 ms at 40 deg/s), and its floor: the
// sanitising copy every frame's depth gets anyway.
void BM_RotateDepth(benchmark::State& state) {
  const Scene& s = scene();
  const cv::Mat src(kHeight, kWidth, CV_32FC1, const_cast<float*>(s.depth.data()));
  cv::Mat dst(kHeight, kWidth, CV_32FC1);
  const Eigen::Matrix3f R =
      Eigen::AngleAxisf(0.0035f, Eigen::Vector3f(0.1f, 1.0f, 0.05f).normalized())
          .toRotationMatrix();
  for (auto _ : state) {
    rotate_depth(src, dst, kK.fx, kK.fy, kK.cx, kK.cy, R, 0.05f);
    benchmark::DoNotOptimize(dst.data);
  }
  state.SetItemsProcessed(state.iterations() * kPoints);
}
BENCHMARK(BM_RotateDepth);

void BM_SanitizeDepth(benchmark::State& state) {
  const Scene& s = scene();
  const cv::Mat src(kHeight, kWidth, CV_32FC1, const_cast<float*>(s.depth.data()));
  cv::Mat dst(kHeight, kWidth, CV_32FC1);
  for (auto _ : state) {
    sanitize_depth(src, dst, 0.3f, 6.0f);
    benchmark::DoNotOptimize(dst.data);
  }
  state.SetItemsProcessed(state.iterations() * kPoints);
}
BENCHMARK(BM_SanitizeDepth);

// One pyramid level down from the 320x240 depth (items: the source's pixels, as the
// sanitising copy above counts them).
void BM_DownsampleDepth(benchmark::State& state) {
  const Scene& s = scene();
  const cv::Mat src(kHeight, kWidth, CV_32FC1, const_cast<float*>(s.depth.data()));
  cv::Mat dst(kHeight / 2, kWidth / 2, CV_32FC1);
  for (auto _ : state) {
    downsample_depth(src, dst, 0.05f);
    benchmark::DoNotOptimize(dst.data);
  }
  state.SetItemsProcessed(state.iterations() * kPoints);
}
BENCHMARK(BM_DownsampleDepth);

}  // namespace

BENCHMARK_MAIN();
