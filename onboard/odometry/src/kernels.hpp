#pragma once
// The per-point kernels of DenseOdometry (private to hq_odometry, included by its tests and
// benchmarks): the photometric Jacobian on the reference, the warp, the bilinear samples, the
// depth residual with its Jacobian on the current frame, and the normal-equation accumulation.
//
// Update convention shared by both residuals: the estimate moves as T_cur_ref <- T_cur_ref
// exp(-delta), i.e. T_ref_cur <- exp(delta) T_ref_cur, xi = (v, omega). Each kernel returns J
// such that r(delta) ~ r(0) - J delta, so that delta = (sum w J J^T)^-1 sum w J r for both.

#include <algorithm>
#include <cmath>
#include <limits>

namespace hq::odometry::detail {

struct Intrinsics {
  float fx = 0, fy = 0, cx = 0, cy = 0;
};

/// Row-major 3x4 [R | t] of T_cur_ref in float.
struct Warp {
  float r00, r01, r02, r10, r11, r12, r20, r21, r22, tx, ty, tz;
  void apply(float px, float py, float pz, float& qx, float& qy, float& qz) const {
    qx = r00 * px + r01 * py + r02 * pz + tx;
    qy = r10 * px + r11 * py + r12 * pz + ty;
    qz = r20 * px + r21 * py + r22 * pz + tz;
  }
  void rotate(float px, float py, float pz, float& qx, float& qy, float& qz) const {
    qx = r00 * px + r01 * py + r02 * pz;
    qy = r10 * px + r11 * py + r12 * pz;
    qz = r20 * px + r21 * py + r22 * pz;
  }
};

/// d I_ref(pi(exp(xi) p)) / d xi at xi = 0 (inverse compositional: the reference's gradient
/// (gx, gy) in intensity per pixel, the point p in the reference camera, metres).
inline void photometric_jacobian(float x, float y, float z, float gx, float gy, const Intrinsics& k,
                                 float* d_residual_d_xi) {
  // d I / d p = grad I * d pi / d p; d p / d xi = [I, -[p]x], so the rotational part is
  // p x (d I / d p).
  const float inv_z = 1.0f / z;
  const float a = gx * k.fx * inv_z;
  const float b = gy * k.fy * inv_z;
  const float c = -(a * x + b * y) * inv_z;
  d_residual_d_xi[0] = a;
  d_residual_d_xi[1] = b;
  d_residual_d_xi[2] = c;
  d_residual_d_xi[3] = y * c - z * b;
  d_residual_d_xi[4] = z * a - x * c;
  d_residual_d_xi[5] = x * b - y * a;
}

/// Bilinear sample of a float image at (u, v), 0 <= u < width - 1, 0 <= v < height - 1.
inline float sample_bilinear(const float* data, int stride, float u, float v) {
  const int u0 = static_cast<int>(u);
  const int v0 = static_cast<int>(v);
  const float du = u - static_cast<float>(u0);
  const float dv = v - static_cast<float>(v0);
  const float* p = data + v0 * stride + u0;
  const float top = p[0] + du * (p[1] - p[0]);
  const float bottom = p[stride] + du * (p[stride + 1] - p[stride]);
  return top + dv * (bottom - top);
}

/// True when the warped point's depth q_z lies outside the range of the current frame's four
/// depths around (u, v) (already checked to lie in the image; missing ones skipped), widened by
/// max_ratio: the point is hidden behind something nearer, or was on something that has moved.
/// The range, not one sample, so that a slanted surface (the floor seen from close by, where a
/// coarse level's pixel spans centimetres of depth) is not taken for an occlusion.
inline bool depth_disagrees(const float* depth, int stride, float u, float v, float qz,
                            float max_ratio) {
  const float* p = depth + static_cast<int>(v) * stride + static_cast<int>(u);
  const float d[4] = {p[0], p[1], p[stride], p[stride + 1]};
  float lo = std::numeric_limits<float>::max();
  float hi = 0.0f;
  for (const float z : d) {
    if (z > 0.0f) {
      lo = std::min(lo, z);
      hi = std::max(hi, z);
    }
  }
  return hi > 0.0f && (qz < lo * (1.0f - max_ratio) || qz > hi * (1.0f + max_ratio));
}

/// D_cur bilinearly interpolated at (u, v) (already checked to lie in the image), and the
/// interpolant's gradient in pixels. False (outputs untouched) when a depth of the four is
/// missing or they spread by more than max_spread_ratio (an occlusion edge, where neither the
/// interpolated depth nor its gradient belongs to a surface).
struct DepthSample {
  float depth, d_du, d_dv;
};
inline bool sample_depth_surface(const float* depth, int stride, float u, float v,
                                 float max_spread_ratio, DepthSample& out) {
  const int u0 = static_cast<int>(u);
  const int v0 = static_cast<int>(v);
  const float du = u - static_cast<float>(u0);
  const float dv = v - static_cast<float>(v0);
  const float* p = depth + v0 * stride + u0;
  const float d00 = p[0], d01 = p[1], d10 = p[stride], d11 = p[stride + 1];
  const float lo = std::min(std::min(d00, d01), std::min(d10, d11));
  const float hi = std::max(std::max(d00, d01), std::max(d10, d11));
  if (!(lo > 0.0f) || hi - lo > max_spread_ratio * lo) return false;
  const float top = d00 + du * (d01 - d00);
  const float bottom = d10 + du * (d11 - d10);
  out.depth = top + dv * (bottom - top);
  out.d_du = (d01 - d00) + dv * ((d11 - d10) - (d01 - d00));
  out.d_dv = bottom - top;
  return true;
}

/// Depth residual of DVO-SLAM (Kerl, Sturm, Cremers, IROS 2013, eq. 11): the current depth at
/// the warped reference point against that point's depth, r = (D_cur(pi(q)) - q_z) / sigma_z
/// with q = T_cur_ref p and sigma_z = noise_per_m * q_z^2 (Kinect depth noise grows with z^2).
/// Its Jacobian needs D_cur's gradient at pi(q), so it is taken forward, on the current frame:
/// J = (grad D * d pi / d q - e_z^T) R [I, -[p]x] / sigma_z, with grad D the gradient of the
/// bilinear interpolant, so J is the exact derivative of the sampled residual.
///
/// In two parts, so that the gather (this one) stays small and the Jacobian's products run
/// vectorised over all points afterwards (depth_jacobian_from): this samples D_cur around the
/// projection (u, v) of q (already checked to lie in the image) and returns r and d r / d q (a
/// row in the current camera). Returns false (outputs untouched) when a depth of the four is
/// missing or they spread by more than max_spread_ratio (an occlusion edge, where neither the
/// interpolated depth nor its gradient belongs to a surface).
inline bool depth_sample_at(const float* depth, int stride, const Intrinsics& k, float qx, float qy,
                            float qz, float u, float v, float noise_per_m, float max_spread_ratio,
                            float& residual, float* d_residual_d_q) {
  DepthSample d;
  if (!sample_depth_surface(depth, stride, u, v, max_spread_ratio, d)) return false;
  const float inv_z = 1.0f / qz;
  const float inv_sigma = 1.0f / (noise_per_m * qz * qz);
  residual = (d.depth - qz) * inv_sigma;
  const float ax = d.d_du * k.fx * inv_z;
  const float ay = d.d_dv * k.fy * inv_z;
  d_residual_d_q[0] = ax * inv_sigma;
  d_residual_d_q[1] = ay * inv_sigma;
  d_residual_d_q[2] = (-(ax * qx + ay * qy) * inv_z - 1.0f) * inv_sigma;
  return true;
}

/// As depth_sample_at, with d r / d q from the surface's unit normal n (current camera axes)
/// instead of D_cur's gradient: where the current surface is the plane n.x = n.q through q, the
/// depth it shows at pi(x) is z_x (n.q) / (n.x), so r(x) = z_x (n.q - n.x) / (n.x) and d r / d q
/// = -(q_z / n.q) n^T, divided by sigma_z. Exact on a plane, and free of the depth map's noise,
/// which the gradient of a single depth map is mostly made of. Returns false (outputs
/// untouched) as depth_sample_at, and where the surface is seen at more than the angle whose
/// cosine is min_cos_incidence (the factor q_z / n.q grows without bound).
inline bool depth_sample_on_surface(const float* depth, int stride, float qx, float qy, float qz,
                                    float u, float v, float nx, float ny, float nz,
                                    float min_cos_incidence, float noise_per_m,
                                    float max_spread_ratio, float& residual,
                                    float* d_residual_d_q) {
  const float n_dot_q = nx * qx + ny * qy + nz * qz;
  if (!(std::abs(n_dot_q) >= min_cos_incidence * std::sqrt(qx * qx + qy * qy + qz * qz))) {
    return false;
  }
  DepthSample d;
  if (!sample_depth_surface(depth, stride, u, v, max_spread_ratio, d)) return false;
  const float inv_sigma = 1.0f / (noise_per_m * qz * qz);
  residual = (d.depth - qz) * inv_sigma;
  const float factor = -qz / n_dot_q * inv_sigma;
  d_residual_d_q[0] = factor * nx;
  d_residual_d_q[1] = factor * ny;
  d_residual_d_q[2] = factor * nz;
  return true;
}

/// The depth residual's Jacobian from depth_sample_at's d r / d q: b = (d r / d q) R is the
/// derivative with respect to the reference point p, and r(delta) = r(T exp(-delta) p) ~ r - b
/// [I, -[p]x] delta gives J = [b, p x b].
inline void depth_jacobian_from(float ax, float ay, float az, const Warp& T, float px, float py,
                                float pz, float* d_residual_d_xi) {
  const float bx = ax * T.r00 + ay * T.r10 + az * T.r20;
  const float by = ax * T.r01 + ay * T.r11 + az * T.r21;
  const float bz = ax * T.r02 + ay * T.r12 + az * T.r22;
  d_residual_d_xi[0] = bx;
  d_residual_d_xi[1] = by;
  d_residual_d_xi[2] = bz;
  d_residual_d_xi[3] = py * bz - pz * by;
  d_residual_d_xi[4] = pz * bx - px * bz;
  d_residual_d_xi[5] = px * by - py * bx;
}

/// Both parts at once: r and J of the warped point q = T p whose projection is (u, v).
inline bool depth_residual_at(const float* depth, int stride, const Intrinsics& k, const Warp& T,
                              float px, float py, float pz, float qx, float qy, float qz, float u,
                              float v, float noise_per_m, float max_spread_ratio, float& residual,
                              float* d_residual_d_xi) {
  float a[3];
  if (!depth_sample_at(depth, stride, k, qx, qy, qz, u, v, noise_per_m, max_spread_ratio, residual,
                       a)) {
    return false;
  }
  depth_jacobian_from(a[0], a[1], a[2], T, px, py, pz, d_residual_d_xi);
  return true;
}

/// As depth_residual_at, warping and projecting p itself.
inline bool depth_residual(const float* depth, int stride, float max_u, float max_v,
                           const Intrinsics& k, const Warp& T, float px, float py, float pz,
                           float min_z, float noise_per_m, float max_spread_ratio, float& residual,
                           float* d_residual_d_xi) {
  float qx, qy, qz;
  T.apply(px, py, pz, qx, qy, qz);
  if (!(qz > min_z)) return false;
  const float inv_z = 1.0f / qz;
  const float u = k.fx * qx * inv_z + k.cx;
  const float v = k.fy * qy * inv_z + k.cy;
  if (!(u >= 0.0f && v >= 0.0f && u < max_u && v < max_v)) return false;
  return depth_residual_at(depth, stride, k, T, px, py, pz, qx, qy, qz, u, v, noise_per_m,
                           max_spread_ratio, residual, d_residual_d_xi);
}

/// Sums of one pass over weighted rows: H = sum w J J^T (upper triangle, row-major), g = sum w
/// J r, and for a seventh parameter with Jacobian c (the brightness offset) its cross terms.
struct RowSums {
  double H[21] = {};
  double g[6] = {};
  double pose_offset[6] = {};
  double offset = 0.0;
  double g_offset = 0.0;
  double weighted_error = 0.0;  ///< sum w r^2
};

/// One row of the normal equations: d r / d xi, the residual and the brightness offset's
/// Jacobian.
struct Row {
  float j0, j1, j2, j3, j4, j5, r, offset_jacobian;
};

// Rows accumulate in float within a block, then into double: float alone loses digits over
// 10^5 pixels, double everywhere halves the throughput of the inner loop.
inline constexpr int kAccumulationBlock = 256;

/// Accumulates the rows form_row(i), i < count, with weights w[i] into `out` in one pass; 36
/// independent sums let the compiler vectorise across rows once form_row is inlined, so a row
/// formed from stored arrays is never stored itself. Always inlined, so it is built for the
/// target of the (multi-versioned, hq/base/target_clones.hpp) function that accumulates.
template <class FormRow>
[[gnu::always_inline]] inline void accumulate_formed_rows(const float* w_in, int count,
                                                          RowSums& out, FormRow form_row) {
  for (int start = 0; start < count; start += kAccumulationBlock) {
    const int end = std::min(count, start + kAccumulationBlock);
    float h00 = 0, h01 = 0, h02 = 0, h03 = 0, h04 = 0, h05 = 0, h11 = 0, h12 = 0, h13 = 0, h14 = 0,
          h15 = 0, h22 = 0, h23 = 0, h24 = 0, h25 = 0, h33 = 0, h34 = 0, h35 = 0, h44 = 0, h45 = 0,
          h55 = 0, g0 = 0, g1 = 0, g2 = 0, g3 = 0, g4 = 0, g5 = 0, e = 0, o0 = 0, o1 = 0, o2 = 0,
          o3 = 0, o4 = 0, o5 = 0, oo = 0, go = 0;
#pragma omp simd reduction(+ : h00, h01, h02, h03, h04, h05, h11, h12, h13, h14, h15, h22, h23, \
                               h24, h25, h33, h34, h35, h44, h45, h55, g0, g1, g2, g3, g4, g5, e, \
                               o0, o1, o2, o3, o4, o5, oo, go)
    for (int i = start; i < end; ++i) {
      const Row row = form_row(i);
      const float a0 = row.j0, a1 = row.j1, a2 = row.j2, a3 = row.j3, a4 = row.j4, a5 = row.j5;
      const float r = row.r;
      const float c = row.offset_jacobian;
      const float w = w_in[i];
      const float w0 = w * a0, w1 = w * a1, w2 = w * a2, w3 = w * a3, w4 = w * a4, w5 = w * a5;
      h00 += w0 * a0;
      h01 += w0 * a1;
      h02 += w0 * a2;
      h03 += w0 * a3;
      h04 += w0 * a4;
      h05 += w0 * a5;
      h11 += w1 * a1;
      h12 += w1 * a2;
      h13 += w1 * a3;
      h14 += w1 * a4;
      h15 += w1 * a5;
      h22 += w2 * a2;
      h23 += w2 * a3;
      h24 += w2 * a4;
      h25 += w2 * a5;
      h33 += w3 * a3;
      h34 += w3 * a4;
      h35 += w3 * a5;
      h44 += w4 * a4;
      h45 += w4 * a5;
      h55 += w5 * a5;
      g0 += w0 * r;
      g1 += w1 * r;
      g2 += w2 * r;
      g3 += w3 * r;
      g4 += w4 * r;
      g5 += w5 * r;
      e += w * r * r;
      o0 += c * w0;
      o1 += c * w1;
      o2 += c * w2;
      o3 += c * w3;
      o4 += c * w4;
      o5 += c * w5;
      oo += c * c * w;
      go += c * w * r;
    }
    const float block[21] = {h00, h01, h02, h03, h04, h05, h11, h12, h13, h14, h15,
                             h22, h23, h24, h25, h33, h34, h35, h44, h45, h55};
    for (int k = 0; k < 21; ++k) out.H[k] += static_cast<double>(block[k]);
    const float gb[6] = {g0, g1, g2, g3, g4, g5};
    const float ob[6] = {o0, o1, o2, o3, o4, o5};
    for (int k = 0; k < 6; ++k) {
      out.g[k] += static_cast<double>(gb[k]);
      out.pose_offset[k] += static_cast<double>(ob[k]);
    }
    out.weighted_error += static_cast<double>(e);
    out.offset += static_cast<double>(oo);
    out.g_offset += static_cast<double>(go);
  }
}

/// Accumulates `count` stored rows J[k][i], r[i] with weights w[i] into `out` in one pass. The
/// brightness offset's Jacobian is offset_jacobian[i], or 1 for every row when it is null.
/// Always inlined, as accumulate_formed_rows.
[[gnu::always_inline]] inline void accumulate_rows(const float* const* J, const float* r,
                                                   const float* w, int count, RowSums& out,
                                                   const float* offset_jacobian = nullptr) {
  const float *j0 = J[0], *j1 = J[1], *j2 = J[2], *j3 = J[3], *j4 = J[4], *j5 = J[5];
  if (offset_jacobian != nullptr) {
    accumulate_formed_rows(w, count, out, [=](int i) {
      return Row{j0[i], j1[i], j2[i], j3[i], j4[i], j5[i], r[i], offset_jacobian[i]};
    });
  } else {
    accumulate_formed_rows(w, count, out, [=](int i) {
      return Row{j0[i], j1[i], j2[i], j3[i], j4[i], j5[i], r[i], 1.0f};
    });
  }
}

/// The whitened depth rows of the bivariate t (Aligner::accumulate_with_depth, alignment.cpp),
/// formed in the accumulation instead of stored: row i is c_z[i] (r_Z, J_Z) + c_i[i] (r_I, J_I),
/// with J_Z = depth_jacobian_from(d_rz_d_q[.][i], T, p_i) and c_i[i] also the offset's Jacobian.
struct DepthRows {
  const float* d_rz_d_q[3];   ///< d r_Z / d q per point (depth_sample_at), 0 without depth
  const float *px, *py, *pz;  ///< reference points
  const float* rz;            ///< depth residuals
  const float* ri;            ///< intensity residuals
  const float* ji[6];         ///< intensity Jacobians
  const float* c_z;           ///< whitening coefficient of the depth residual
  const float* c_i;           ///< whitening coefficient of the intensity residual
  Warp T{};                   ///< T_cur_ref of the residuals
};

[[gnu::always_inline]] inline void accumulate_depth_rows(const DepthRows& d, const float* w,
                                                         int count, RowSums& out) {
  const float* qx = d.d_rz_d_q[0];
  const float* qy = d.d_rz_d_q[1];
  const float* qz = d.d_rz_d_q[2];
  const float *px = d.px, *py = d.py, *pz = d.pz, *rz = d.rz, *ri = d.ri, *c_z = d.c_z,
              *c_i = d.c_i;
  const float *j0 = d.ji[0], *j1 = d.ji[1], *j2 = d.ji[2], *j3 = d.ji[3], *j4 = d.ji[4],
              *j5 = d.ji[5];
  const Warp T = d.T;
  accumulate_formed_rows(w, count, out, [=](int i) {
    // b = (d r_Z / d q) R, J_Z = [b, p x b] (depth_jacobian_from, written out), and the
    // whitened row c_z (r_Z, J_Z) + c_i (r_I, J_I) whose offset Jacobian is c_i.
    const float bx = qx[i] * T.r00 + qy[i] * T.r10 + qz[i] * T.r20;
    const float by = qx[i] * T.r01 + qy[i] * T.r11 + qz[i] * T.r21;
    const float bz = qx[i] * T.r02 + qy[i] * T.r12 + qz[i] * T.r22;
    const float cz = c_z[i];
    const float c = c_i[i];
    return Row{cz * bx + c * j0[i],
               cz * by + c * j1[i],
               cz * bz + c * j2[i],
               cz * (py[i] * bz - pz[i] * by) + c * j3[i],
               cz * (pz[i] * bx - px[i] * bz) + c * j4[i],
               cz * (px[i] * by - py[i] * bx) + c * j5[i],
               cz * rz[i] + c * ri[i],
               c};
  });
}

}  // namespace hq::odometry::detail
