// The per-point kernels against numeric derivatives (as basalt tests its camera models and
// Sophus its Lie groups): both residuals' analytic Jacobians must match central differences
// of the residual itself under the shared update T_cur_ref <- T_cur_ref exp(-delta).
#include "kernels.hpp"

#include "hq/geometry/lie.hpp"

#include "pyramid.hpp"
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace hq::odometry::detail {
namespace {

constexpr int kWidth = 64;
constexpr int kHeight = 48;
const Intrinsics kK{50.0f, 52.0f, 31.5f, 23.5f};
// kK in double, for the reference projections the kernels are checked against.
const auto kFx = static_cast<double>(kK.fx);
const auto kFy = static_cast<double>(kK.fy);
const auto kCx = static_cast<double>(kK.cx);
const auto kCy = static_cast<double>(kK.cy);

Warp warp_of(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d& R = T.linear();
  const Eigen::Vector3d& t = T.translation();
  return {static_cast<float>(R(0, 0)), static_cast<float>(R(0, 1)), static_cast<float>(R(0, 2)),
          static_cast<float>(R(1, 0)), static_cast<float>(R(1, 1)), static_cast<float>(R(1, 2)),
          static_cast<float>(R(2, 0)), static_cast<float>(R(2, 1)), static_cast<float>(R(2, 2)),
          static_cast<float>(t.x()),   static_cast<float>(t.y()),   static_cast<float>(t.z())};
}

Eigen::Isometry3d some_pose() {
  geometry::Vector6d xi;
  xi << 0.03, -0.02, 0.05, 0.02, -0.03, 0.04;
  return geometry::exp_se3(xi);
}

// A smooth surface z(u, v) = 2 + 0.01 u - 0.005 v + 0.0002 u v, sampled on the pixel grid.
std::vector<float> smooth_depth() {
  std::vector<float> d(kWidth * kHeight);
  for (int v = 0; v < kHeight; ++v) {
    for (int u = 0; u < kWidth; ++u) {
      const auto u_px = static_cast<float>(u);
      const auto v_px = static_cast<float>(v);
      d[static_cast<std::size_t>(v * kWidth + u)] =
          2.0f + 0.01f * u_px - 0.005f * v_px + 0.0002f * u_px * v_px;
    }
  }
  return d;
}

// residual_at(delta, J) is the residual under T_cur_ref exp(-delta), and its analytic
// Jacobian into J when J is not null; at delta = 0 the point lies on the surface (r = 0, so the
// noise model's 1 / z^2, held fixed within an iteration, does not enter the derivative). Checks
// J against central differences, r(delta) ~ r(0) - J delta; returns the axes checked.
template <typename ResidualAt>
int expect_jacobian_matches_numeric(const ResidualAt& residual_at, double relative_tolerance) {
  float J[6];
  const double r0 = residual_at(geometry::Vector6d::Zero(), J);
  EXPECT_TRUE(std::isfinite(r0));
  EXPECT_NEAR(r0, 0.0, 0.05);
  constexpr double kStep = 1e-3;
  for (int k = 0; k < 6; ++k) {
    geometry::Vector6d e = geometry::Vector6d::Zero();
    e(k) = kStep;
    const double numeric = -(residual_at(e, nullptr) - residual_at(-e, nullptr)) / (2 * kStep);
    EXPECT_NEAR(J[k], numeric, relative_tolerance * std::max(1.0, std::abs(numeric)))
        << "axis " << k;
  }
  return 6;
}

TEST(DepthResidual, AnalyticJacobianMatchesNumericDerivative) {
  const std::vector<float> depth = smooth_depth();
  const Eigen::Isometry3d T = some_pose();
  const float max_u = kWidth - 1 - 1e-3f;
  const float max_v = kHeight - 1 - 1e-3f;
  int checked = 0;
  // Points that T maps onto the surface, inside pixel cells: r = 0 there, so the noise model's
  // 1 / z^2, held fixed within an iteration (IRLS), does not enter the derivative.
  for (const Eigen::Vector2d& uv :
       {Eigen::Vector2d(20.3, 15.6), Eigen::Vector2d(40.7, 30.4), Eigen::Vector2d(12.45, 35.55)}) {
    const double z = 2.0 + 0.01 * uv.x() - 0.005 * uv.y() + 0.0002 * uv.x() * uv.y();
    const Eigen::Vector3d q((uv.x() - kCx) * z / kFx, (uv.y() - kCy) * z / kFy, z);
    const Eigen::Vector3d p = T.inverse() * q;
    const auto residual_at = [&](const geometry::Vector6d& delta, float* J) {
      float r = 0.0f;
      float scratch[6];
      const bool ok = depth_residual(
          depth.data(), kWidth, max_u, max_v, kK, warp_of(T * geometry::exp_se3(-delta)),
          static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()), 0.1f,
          0.0015f, 0.5f, r, J != nullptr ? J : scratch);
      EXPECT_TRUE(ok);
      return static_cast<double>(r);
    };
    checked += expect_jacobian_matches_numeric(residual_at, 1e-2);
  }
  EXPECT_EQ(checked, 18);
}

TEST(DepthResidual, MissingDepthOrEdgeIsRejected) {
  std::vector<float> depth = smooth_depth();
  const Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  float r = 0.0f;
  float J[6];
  // p projects to pixel (31.5 + 50 x / z, 23.5 + 52 y / z) = (34, 26): punch a hole there.
  const float px = 2.5f * 2.0f / 50.0f, py = 2.5f * 2.0f / 52.0f, pz = 2.0f;
  EXPECT_TRUE(depth_residual(depth.data(), kWidth, kWidth - 1.001f, kHeight - 1.001f, kK,
                             warp_of(T), px, py, pz, 0.1f, 0.0015f, 0.05f, r, J));
  depth[26 * kWidth + 34] = 0.0f;
  EXPECT_FALSE(depth_residual(depth.data(), kWidth, kWidth - 1.001f, kHeight - 1.001f, kK,
                              warp_of(T), px, py, pz, 0.1f, 0.0015f, 0.05f, r, J));
  depth[26 * kWidth + 34] = 4.0f;  // an occlusion edge: 2 m against 4 m
  EXPECT_FALSE(depth_residual(depth.data(), kWidth, kWidth - 1.001f, kHeight - 1.001f, kK,
                              warp_of(T), px, py, pz, 0.1f, 0.0015f, 0.05f, r, J));
}

// The depth a camera at the origin sees of the plane n.x = c at every pixel: c / (n . ray).
std::vector<float> plane_depth(const Eigen::Vector3d& n, double c) {
  std::vector<float> d(kWidth * kHeight);
  for (int v = 0; v < kHeight; ++v) {
    for (int u = 0; u < kWidth; ++u) {
      const Eigen::Vector3d ray((u - kCx) / kFx, (v - kCy) / kFy, 1.0);
      d[static_cast<std::size_t>(v * kWidth + u)] = static_cast<float>(c / n.dot(ray));
    }
  }
  return d;
}

TEST(DepthConsistency, OnlyAPointOutsideTheFourDepthsRangeDisagrees) {
  // GIVEN a 2x2 patch of a slanted surface (1.0 to 1.3 m) and one with a depth missing
  const std::vector<float> slanted = {1.0f, 1.1f, 1.2f, 1.3f};
  const std::vector<float> one_missing = {0.0f, 2.0f, 2.0f, 2.0f};
  const std::vector<float> none = {0.0f, 0.0f, 0.0f, 0.0f};
  // WHEN points at various depths are warped into it (10 % allowed beyond the range)
  // THEN anything within the range widened by 10 % agrees, however steep the slant
  EXPECT_FALSE(depth_disagrees(slanted.data(), 2, 0.5f, 0.5f, 1.25f, 0.1f));
  EXPECT_FALSE(depth_disagrees(slanted.data(), 2, 0.5f, 0.5f, 0.91f, 0.1f));
  EXPECT_FALSE(depth_disagrees(slanted.data(), 2, 0.5f, 0.5f, 1.42f, 0.1f));
  // AND a point hidden behind the surface, or in front of it (it moved), disagrees
  EXPECT_TRUE(depth_disagrees(slanted.data(), 2, 0.5f, 0.5f, 1.45f, 0.1f));
  EXPECT_TRUE(depth_disagrees(slanted.data(), 2, 0.5f, 0.5f, 0.85f, 0.1f));
  // AND missing depths are skipped; with none, nothing can disagree
  EXPECT_TRUE(depth_disagrees(one_missing.data(), 2, 0.2f, 0.2f, 1.0f, 0.1f));
  EXPECT_FALSE(depth_disagrees(one_missing.data(), 2, 0.2f, 0.2f, 2.1f, 0.1f));
  EXPECT_FALSE(depth_disagrees(none.data(), 2, 0.5f, 0.5f, 1.0f, 0.1f));
}

TEST(DepthResidual, SurfaceNormalJacobianMatchesNumericDerivativeOnAPlane) {
  // A plane tilted against the view, 2 m ahead; its normal in the current camera's axes.
  const Eigen::Vector3d n_cur = Eigen::Vector3d(0.3, -0.2, -1.0).normalized();
  const double c = n_cur.dot(Eigen::Vector3d(0.0, 0.0, 2.0));
  const std::vector<float> depth = plane_depth(n_cur, c);
  const Eigen::Isometry3d T = some_pose();
  const Eigen::Vector3d n_ref = T.linear().transpose() * n_cur;  // as the reference holds it
  const auto cos_75 = static_cast<float>(std::cos(75.0 * M_PI / 180.0));
  int checked = 0;
  for (const Eigen::Vector2d& uv :
       {Eigen::Vector2d(20.3, 15.6), Eigen::Vector2d(40.7, 30.4), Eigen::Vector2d(12.45, 35.55)}) {
    const Eigen::Vector3d ray((uv.x() - kCx) / kFx, (uv.y() - kCy) / kFy, 1.0);
    const Eigen::Vector3d p = T.inverse() * (ray * c / n_cur.dot(ray));
    const auto residual_at = [&](const geometry::Vector6d& delta, float* J) {
      const Warp W = warp_of(T * geometry::exp_se3(-delta));
      float qx, qy, qz, nx, ny, nz;
      W.apply(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()), qx,
              qy, qz);
      W.rotate(static_cast<float>(n_ref.x()), static_cast<float>(n_ref.y()),
               static_cast<float>(n_ref.z()), nx, ny, nz);
      const float u = kK.fx * qx / qz + kK.cx;
      const float v = kK.fy * qy / qz + kK.cy;
      float r = 0.0f;
      float a[3] = {0.0f, 0.0f, 0.0f};
      EXPECT_TRUE(depth_sample_on_surface(depth.data(), kWidth, qx, qy, qz, u, v, nx, ny, nz,
                                          cos_75, 0.0015f, 0.5f, r, a));
      if (J != nullptr) {
        depth_jacobian_from(a[0], a[1], a[2], W, static_cast<float>(p.x()),
                            static_cast<float>(p.y()), static_cast<float>(p.z()), J);
      }
      return static_cast<double>(r);
    };
    // The bilinear interpolant of a plane's depth is the plane only at the pixels.
    checked += expect_jacobian_matches_numeric(residual_at, 2e-2);
  }
  EXPECT_EQ(checked, 18);
}

TEST(DepthResidual, SurfaceSeenAtGrazingIncidenceIsRejected) {
  const std::vector<float> depth = smooth_depth();
  float r = 0.0f;
  float a[3];
  // q straight ahead at 2 m: a fronto-parallel normal is accepted, one at 80 deg is not.
  const auto cos_75 = static_cast<float>(std::cos(75.0 * M_PI / 180.0));
  const float qx = 0.0f, qy = 0.0f, qz = 2.0f, u = 31.5f, v = 23.5f;
  EXPECT_TRUE(depth_sample_on_surface(depth.data(), kWidth, qx, qy, qz, u, v, 0.0f, 0.0f, -1.0f,
                                      cos_75, 0.0015f, 0.5f, r, a));
  const auto s80 = static_cast<float>(std::sin(80.0 * M_PI / 180.0));
  const auto c80 = static_cast<float>(std::cos(80.0 * M_PI / 180.0));
  EXPECT_FALSE(depth_sample_on_surface(depth.data(), kWidth, qx, qy, qz, u, v, s80, 0.0f, -c80,
                                       cos_75, 0.0015f, 0.5f, r, a));
}

// A depth map taken a moment before the colour image, turned to the colour's exposure: on a
// plane the result is the plane as the turned camera sees it (a rotation is a homography).
TEST(RotateDepth, PlaneSeenByTheTurnedCameraIsThePlane) {
  const Eigen::Vector3d n_src = Eigen::Vector3d(0.3, -0.2, -1.0).normalized();
  const double c = n_src.dot(Eigen::Vector3d(0.0, 0.0, 2.0));
  // 0.6 deg about a tilted axis: about 0.5 px here, 2 px at 640x480 (Kinect v1's 5 ms at
  // 120 deg/s).
  const Eigen::Matrix3d R_src_dst = geometry::exp_so3(Eigen::Vector3d(0.006, -0.008, 0.004));
  std::vector<float> src_depth = plane_depth(n_src, c);
  const std::vector<float> expected = plane_depth(R_src_dst.transpose() * n_src, c);
  const cv::Mat src(kHeight, kWidth, CV_32FC1, src_depth.data());
  cv::Mat dst(kHeight, kWidth, CV_32FC1, cv::Scalar(-1.0f));
  rotate_depth(src, dst, kK.fx, kK.fy, kK.cx, kK.cy, R_src_dst.cast<float>(), 0.05f);
  int valid = 0;
  double worst = 0.0;
  for (int v = 0; v < kHeight; ++v) {
    for (int u = 0; u < kWidth; ++u) {
      const float z = dst.at<float>(v, u);
      ASSERT_GE(z, 0.0f) << u << "," << v;  // every pixel written
      if (z == 0.0f) continue;
      ++valid;
      const double truth = static_cast<double>(expected[static_cast<std::size_t>(v * kWidth + u)]);
      worst = std::max(worst, std::abs(static_cast<double>(z) - truth) / truth);
    }
  }
  // Only rays leaving the source image have no depth: a border of about a pixel.
  EXPECT_GT(valid, (kWidth - 3) * (kHeight - 3));
  EXPECT_LT(worst, 2e-4);
  // Without the turn, the depth is off by the rotation's share of the plane's slope.
  double unturned = 0.0;
  for (std::size_t i = 0; i < expected.size(); ++i) {
    unturned = std::max(unturned, std::abs(static_cast<double>(src_depth[i] - expected[i])) /
                                      static_cast<double>(expected[i]));
  }
  EXPECT_GT(unturned, 20.0 * worst);
}

TEST(RotateDepth, OcclusionEdgeGetsNoSurfaceInBetweenAndNoDepthStaysNone) {
  // A box edge: 1 m on the left, 3 m on the right, and a hole without depth.
  cv::Mat src(kHeight, kWidth, CV_32FC1, cv::Scalar(3.0f));
  src.colRange(0, kWidth / 2).setTo(1.0f);
  src(cv::Rect(10, 10, 6, 6)).setTo(0.0f);
  const Eigen::Matrix3d R_src_dst = geometry::exp_so3(Eigen::Vector3d(0.003, 0.013, 0.0));
  cv::Mat dst(kHeight, kWidth, CV_32FC1);
  rotate_depth(src, dst, kK.fx, kK.fy, kK.cx, kK.cy, R_src_dst.cast<float>(), 0.05f);
  int near = 0, far = 0;
  for (int v = 0; v < kHeight; ++v) {
    for (int u = 0; u < kWidth; ++u) {
      const float z = dst.at<float>(v, u);
      // Turned, a fronto-parallel surface is tilted by the turn: its depth within 1 % here.
      const bool is_near = std::abs(z - 1.0f) < 0.01f;
      const bool is_far = std::abs(z - 3.0f) < 0.03f;
      EXPECT_TRUE(z == 0.0f || is_near || is_far) << u << "," << v << ": " << z;
      near += is_near ? 1 : 0;
      far += is_far ? 1 : 0;
    }
  }
  EXPECT_GT(near, kWidth * kHeight / 3);
  EXPECT_GT(far, kWidth * kHeight / 3);
  // The hole moved with the view (0.65 px right and 0.15 px down) but is still there.
  EXPECT_EQ(dst.at<float>(12, 12), 0.0f);
}

// Each 2x2 block, every case the pyramid meets: all valid, some missing, none, and an
// occlusion edge, where the nearest surface is kept instead of a depth floating between.
TEST(DownsampleDepth, BlockMeanOfValidDepthsNearestAcrossAnEdgeNoneWhenEmpty) {
  cv::Mat src(4, 10, CV_32FC1);
  const float blocks[5][4] = {{1.0f, 1.02f, 0.98f, 1.0f},  // one surface: the mean
                              {2.0f, 0.0f, 2.04f, 0.0f},   // half missing: the valid ones' mean
                              {0.0f, 0.0f, 0.0f, 0.0f},    // none: no depth
                              {3.0f, 1.0f, 3.0f, 3.0f},    // an edge: the nearest
                              {0.0f, 4.0f, 0.0f, 0.0f}};   // one left: itself
  for (int b = 0; b < 5; ++b) {
    src.at<float>(0, 2 * b) = blocks[b][0];
    src.at<float>(0, 2 * b + 1) = blocks[b][1];
    src.at<float>(1, 2 * b) = blocks[b][2];
    src.at<float>(1, 2 * b + 1) = blocks[b][3];
  }
  src.row(0).copyTo(src.row(2));
  src.row(1).copyTo(src.row(3));
  cv::Mat dst(2, 5, CV_32FC1, cv::Scalar(-1.0f));
  downsample_depth(src, dst, 0.05f);
  for (int y = 0; y < 2; ++y) {
    EXPECT_FLOAT_EQ(dst.at<float>(y, 0), 1.0f);
    EXPECT_FLOAT_EQ(dst.at<float>(y, 1), 2.02f);
    EXPECT_EQ(dst.at<float>(y, 2), 0.0f);
    EXPECT_EQ(dst.at<float>(y, 3), 1.0f);
    EXPECT_EQ(dst.at<float>(y, 4), 4.0f);
  }
  // Within the spread the far pixels are averaged in: a wider ratio is a mean again.
  downsample_depth(src, dst, 5.0f);
  EXPECT_FLOAT_EQ(dst.at<float>(0, 3), 2.5f);
}

// I_ref smooth enough that central differences are its exact gradient at the pixel.
double intensity(double u, double v) { return 100.0 + 2.0 * u - 1.5 * v; }

TEST(PhotometricJacobian, MatchesNumericDerivativeOfTheWarpedReference) {
  // Inverse compositional: J = d I_ref(pi(exp(xi) p)) / d xi at 0.
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(0.1, 0.05, 2.1), Eigen::Vector3d(-0.4, 0.2, 1.9)}) {
    const auto I_at = [&](const geometry::Vector6d& xi) {
      const Eigen::Vector3d q = geometry::exp_se3(xi) * p;
      return intensity(kFx * q.x() / q.z() + kCx, kFy * q.y() / q.z() + kCy);
    };
    const double u = kFx * p.x() / p.z() + kCx;
    const double v = kFy * p.y() / p.z() + kCy;
    const auto gx = static_cast<float>(0.5 * (intensity(u + 1, v) - intensity(u - 1, v)));
    const auto gy = static_cast<float>(0.5 * (intensity(u, v + 1) - intensity(u, v - 1)));
    float J[6];
    photometric_jacobian(static_cast<float>(p.x()), static_cast<float>(p.y()),
                         static_cast<float>(p.z()), gx, gy, kK, J);
    constexpr double kStep = 1e-5;
    for (int k = 0; k < 6; ++k) {
      geometry::Vector6d e = geometry::Vector6d::Zero();
      e(k) = kStep;
      const double numeric = (I_at(e) - I_at(-e)) / (2 * kStep);
      EXPECT_NEAR(J[k], numeric, 1e-3 * std::max(1.0, std::abs(numeric))) << "axis " << k;
    }
  }
}

TEST(AccumulateRows, MatchesDenseSums) {
  // 600 rows (more than one accumulation block) against a double-precision reference.
  constexpr int kRows = 600;
  std::vector<float> j[6], r(kRows), w(kRows), o(kRows);
  for (auto& c : j) c.resize(kRows);
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
  double oo = 0.0;
  for (int i = 0; i < kRows; ++i) {
    const auto n = static_cast<std::size_t>(i);
    Eigen::Matrix<double, 6, 1> row;
    for (int k = 0; k < 6; ++k) {
      j[k][n] = std::sin(0.1f * static_cast<float>(i * (k + 1)));
      row(k) = j[k][n];
    }
    r[n] = std::cos(0.05f * static_cast<float>(i));
    w[n] = 0.5f +
           0.5f * std::sin(0.3f * static_cast<float>(i)) * std::sin(0.3f * static_cast<float>(i));
    o[n] = 0.25f;
    H += w[n] * row * row.transpose();
    g += w[n] * row * r[n];
    oo += static_cast<double>(w[n] * o[n] * o[n]);
  }
  const float* J[6] = {j[0].data(), j[1].data(), j[2].data(),
                       j[3].data(), j[4].data(), j[5].data()};
  RowSums sums;
  accumulate_rows(J, r.data(), w.data(), kRows, sums, o.data());
  int k = 0;
  for (int a = 0; a < 6; ++a) {
    for (int b = a; b < 6; ++b) EXPECT_NEAR(sums.H[k++], H(a, b), 1e-3 * std::abs(H(a, a)));
    EXPECT_NEAR(sums.g[a], g(a), 1e-3);
  }
  EXPECT_NEAR(sums.offset, oo, 1e-3 * oo);
}

TEST(AccumulateDepthRows, MatchesRowsFormedExplicitly) {
  // The fused depth rows against the same rows built with depth_jacobian_from and summed by
  // accumulate_rows: the whitened row c_z (r_Z, J_Z) + c_i (r_I, J_I), offset Jacobian c_i.
  constexpr int kRows = 600;
  const Warp T{0.9998f,  -0.0175f, 0.0087f, 0.0174f, 0.9998f, 0.0052f,
               -0.0088f, -0.0050f, 0.9999f, 0.01f,   -0.005f, 0.02f};
  std::vector<float> q[3], p[3], ji[6], jrow[6], rz(kRows), ri(kRows), cz(kRows), ci(kRows),
      w(kRows), r(kRows);
  for (auto* v : {&q[0], &q[1], &q[2], &p[0], &p[1], &p[2]}) v->resize(kRows);
  for (int k = 0; k < 6; ++k) {
    ji[k].resize(kRows);
    jrow[k].resize(kRows);
  }
  for (std::size_t i = 0; i < static_cast<std::size_t>(kRows); ++i) {
    const auto f = static_cast<float>(i);
    for (int k = 0; k < 3; ++k) {
      q[k][i] = std::sin(0.07f * f * static_cast<float>(k + 1));
      p[k][i] = (k == 2 ? 2.0f : 0.0f) + std::cos(0.11f * f * static_cast<float>(k + 2));
    }
    for (int k = 0; k < 6; ++k) ji[k][i] = std::cos(0.03f * f * static_cast<float>(k + 1));
    rz[i] = std::sin(0.05f * f);
    ri[i] = std::cos(0.09f * f);
    cz[i] = (i % 7 == 0) ? 0.0f : 0.8f;   // some rows without depth
    ci[i] = (i % 3 == 0) ? 0.0f : -0.3f;  // some with depth alone
    w[i] = 0.5f + 0.4f * std::sin(0.3f * f);
    float jz[6];
    depth_jacobian_from(q[0][i], q[1][i], q[2][i], T, p[0][i], p[1][i], p[2][i], jz);
    for (int k = 0; k < 6; ++k) jrow[k][i] = cz[i] * jz[k] + ci[i] * ji[k][i];
    r[i] = cz[i] * rz[i] + ci[i] * ri[i];
  }
  const float* J[6] = {jrow[0].data(), jrow[1].data(), jrow[2].data(),
                       jrow[3].data(), jrow[4].data(), jrow[5].data()};
  RowSums expected;
  accumulate_rows(J, r.data(), w.data(), kRows, expected, ci.data());
  DepthRows rows;
  for (int k = 0; k < 3; ++k) rows.d_rz_d_q[k] = q[k].data();
  rows.px = p[0].data();
  rows.py = p[1].data();
  rows.pz = p[2].data();
  rows.rz = rz.data();
  rows.ri = ri.data();
  for (int k = 0; k < 6; ++k) rows.ji[k] = ji[k].data();
  rows.c_z = cz.data();
  rows.c_i = ci.data();
  rows.T = T;
  RowSums fused;
  accumulate_depth_rows(rows, w.data(), kRows, fused);
  for (int k = 0; k < 21; ++k)
    EXPECT_NEAR(fused.H[k], expected.H[k], 1e-4 * (1.0 + std::abs(expected.H[k])));
  for (int k = 0; k < 6; ++k) {
    EXPECT_NEAR(fused.g[k], expected.g[k], 1e-4 * (1.0 + std::abs(expected.g[k])));
    EXPECT_NEAR(fused.pose_offset[k], expected.pose_offset[k],
                1e-4 * (1.0 + std::abs(expected.pose_offset[k])));
  }
  EXPECT_NEAR(fused.offset, expected.offset, 1e-4 * (1.0 + expected.offset));
  EXPECT_NEAR(fused.g_offset, expected.g_offset, 1e-4 * (1.0 + std::abs(expected.g_offset)));
  EXPECT_NEAR(fused.weighted_error, expected.weighted_error,
              1e-4 * (1.0 + expected.weighted_error));
  EXPECT_GT(expected.H[0], 1.0);  // the rows are not all zero
}

}  // namespace
}  // namespace hq::odometry::detail
