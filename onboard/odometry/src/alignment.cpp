#include "alignment.hpp"

#include "hq/base/target_clones.hpp"
#include "hq/geometry/lie.hpp"

#include "degeneracy.hpp"
#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

namespace hq::odometry::detail {

namespace {

constexpr int kScaleIterations = 5;
// The median |r| is read from a histogram over [0, this range) in intensity units (0-255): a
// median beyond it means nothing is aligned, and the fixed point takes over.
constexpr float kResidualHistogramRange = 64.0f;
constexpr int kResidualHistogramBins = 1024;
constexpr float kMadToSigma = 1.4826f;  // sigma of a normal distribution over its median |r|

// The current frame's side of warping the reference points at one level: T_cur_ref in float,
// the image bounds and the images sampled.
struct WarpSetup {
  Intrinsics k;
  Warp T;
  float max_u, max_v, min_z;
  const float* data;  // current intensity
  int stride;
  const float* depth;  // current depth
  int depth_stride;
  float occlusion_ratio;
  bool reject_occluded;

  // Projects q (the warped point, current camera) to (u, v): true when it lands inside the
  // image and its depth agrees with the current frame's there.
  [[nodiscard]] bool visible(float qx, float qy, float qz, float& u, float& v) const {
    if (!(qz > min_z)) return false;
    const float inv_z = 1.0f / qz;
    u = k.fx * qx * inv_z + k.cx;
    v = k.fy * qy * inv_z + k.cy;
    return u >= 0.0f && v >= 0.0f && u < max_u && v < max_v &&
           !(reject_occluded && depth_disagrees(depth, depth_stride, u, v, qz, occlusion_ratio));
  }
};

// What warping the reference points into the current frame at one level needs. Inlined into
// each clone of the residual passes, as it always was.
[[gnu::always_inline]] inline WarpSetup warp_setup(const OdometryConfig& config,
                                                   const LevelCameras& cameras, int level,
                                                   const FrameSlot& current,
                                                   const Eigen::Isometry3d& T_cur_ref) {
  const geometry::PinholeCamera& cam = cameras.at(level);
  const Eigen::Matrix3f R = T_cur_ref.linear().cast<float>();
  const Eigen::Vector3f t = T_cur_ref.translation().cast<float>();
  const cv::Mat& image = at_level(current.intensity, level);
  const cv::Mat& depth_image = at_level(current.depth_m, level);
  const auto occlusion_ratio = static_cast<float>(config.occlusion_depth_ratio);
  return {cameras.intrinsics(level),
          {R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2), t.x(),
           t.y(), t.z()},
          static_cast<float>(cam.width - 1) - 1e-3f,
          static_cast<float>(cam.height - 1) - 1e-3f,
          static_cast<float>(config.min_depth_m) * 0.5f,
          reinterpret_cast<const float*>(image.data),
          static_cast<int>(image.step1()),
          reinterpret_cast<const float*>(depth_image.data),
          static_cast<int>(depth_image.step1()),
          occlusion_ratio,
          occlusion_ratio > 0.0f};
}

// Stores the accumulated sums, times scale, as normal equations.
void store(const RowSums& sums, double scale, NormalEquations& out) {
  int k = 0;
  for (int r = 0; r < 6; ++r) {
    for (int c = r; c < 6; ++c) {
      out.H(r, c) = sums.H[k] * scale;
      out.H(c, r) = out.H(r, c);
      ++k;
    }
    out.g(r) = sums.g[r] * scale;
    out.H_pose_offset(r) = sums.pose_offset[r] * scale;
  }
  out.H_offset = sums.offset * scale;
  out.g_offset = sums.g_offset * scale;
}

}  // namespace

Aligner::Aligner(const OdometryConfig& config, const LevelCameras& cameras)
    : config_(config),
      cameras_(cameras),
      min_cos_incidence_(min_cos_incidence(config)),
      residual_histogram_(kResidualHistogramBins) {
  int capacity = 0;
  for (int l = cameras_.finest(); l < cameras_.levels(); ++l) {
    capacity = std::max(capacity, cameras_.at(l).width * cameras_.at(l).height);
  }
  const auto size = static_cast<std::size_t>(capacity);
  for (auto* v : {&residual_, &mask_, &weight_, &depth_residual_, &depth_mask_, &depth_weight_,
                  &depth_offset_jacobian_, &depth_whitening_}) {
    v->assign(size, 0.0f);
  }
  for (auto& j : depth_jacobian_) j.assign(size, 0.0f);
}

void Aligner::finest_residuals(const ReferenceSet& reference, const FrameSlot& current,
                               const Alignment& a) {
  reference_ = &reference;
  compute_residuals(cameras_.finest(), current, a.T_cur_ref, a.brightness_offset);
}

// compute_residuals() of a level without the depth term.
HQ_CLONES_X86_64_V3
Counts Aligner::compute_intensity_residuals(int level, const FrameSlot& current,
                                            const Eigen::Isometry3d& T_cur_ref,
                                            float brightness_offset) {
  const WarpSetup w = warp_setup(config_, cameras_, level, current, T_cur_ref);
  const Warp& T = w.T;
  const ReferenceLevel& ref = at_level(*reference_, level);
  const float* photometric = ref.photometric.data();
  Counts counts;
  for (int i = 0; i < ref.count; ++i) {
    float qx, qy, qz;
    T.apply(ref.x[i], ref.y[i], ref.z[i], qx, qy, qz);
    float r = 0.0f;
    float m = 0.0f;
    float u, v;
    if (w.visible(qx, qy, qz, u, v)) {
      r = sample_bilinear(w.data, w.stride, u, v) - ref.intensity[i] - brightness_offset;
      m = photometric[i];
    }
    residual_[i] = r;
    mask_[i] = m;
    counts.photometric += m > 0.0f ? 1 : 0;
  }
  counts.any = counts.photometric;
  return counts;
}

// Warps every reference point with T_cur_ref, samples the current image (and, with the depth
// term, the current depth), stores residuals and masks; points that leave the image, or whose
// depth disagrees with the current one (occlusion_depth_ratio), get mask 0.
HQ_CLONES_X86_64_V3
Counts Aligner::compute_residuals(int level, const FrameSlot& current,
                                  const Eigen::Isometry3d& T_cur_ref, float brightness_offset) {
  if (!depth_term_at(config_, level)) {
    return compute_intensity_residuals(level, current, T_cur_ref, brightness_offset);
  }
  const WarpSetup w = warp_setup(config_, cameras_, level, current, T_cur_ref);
  const Intrinsics& k = w.k;
  const Warp& T = w.T;
  const float* data = w.data;
  const float* depth = w.depth;
  const int stride = w.stride;
  const int depth_stride = w.depth_stride;
  const ReferenceLevel& ref = at_level(*reference_, level);
  const float* photometric = ref.photometric.data();
  Counts counts;
  // Intensity and depth in one pass over the points and one warp; points without gradient
  // skip the intensity sample.
  const auto noise = static_cast<float>(config_.depth_noise_per_m);
  const auto spread = static_cast<float>(config_.depth_max_spread_ratio);
  // The gather only: residuals and d r_Z / d q here; the depth rows' Jacobians are formed
  // vectorised in accumulate_with_depth, which needs this warp's rotation.
  warp_ = T;
  const float* depth_point = ref.depth_point.data();
  const bool from_normals = config_.depth_jacobian_from_normals;
  float* a0 = depth_jacobian_[0].data();
  float* a1 = depth_jacobian_[1].data();
  float* a2 = depth_jacobian_[2].data();
  for (int i = 0; i < ref.count; ++i) {
    float a[3] = {0.0f, 0.0f, 0.0f};
    float rz = 0.0f;
    float r = 0.0f;
    float m = 0.0f;
    bool ok = false;
    float qx, qy, qz;
    T.apply(ref.x[i], ref.y[i], ref.z[i], qx, qy, qz);
    float u, v;
    if (w.visible(qx, qy, qz, u, v)) {
      if (photometric[i] > 0.0f) {
        r = sample_bilinear(data, stride, u, v) - ref.intensity[i] - brightness_offset;
        m = 1.0f;
      }
      if (depth_point[i] > 0.0f) {
        if (from_normals) {
          float nx, ny, nz;
          T.rotate(ref.nx[i], ref.ny[i], ref.nz[i], nx, ny, nz);
          ok = depth_sample_on_surface(depth, depth_stride, qx, qy, qz, u, v, nx, ny, nz,
                                       min_cos_incidence_, noise, spread, rz, a);
        } else {
          ok = depth_sample_at(depth, depth_stride, k, qx, qy, qz, u, v, noise, spread, rz, a);
        }
        if (!ok) a[0] = a[1] = a[2] = 0.0f;
      }
    }
    depth_residual_[i] = ok ? rz : 0.0f;
    depth_mask_[i] = ok ? 1.0f : 0.0f;
    a0[i] = a[0];
    a1[i] = a[1];
    a2[i] = a[2];
    residual_[i] = r;
    mask_[i] = m;
    counts.photometric += m > 0.0f ? 1 : 0;
    counts.depth += ok ? 1 : 0;
    counts.any += (ok || m > 0.0f) ? 1 : 0;
  }
  return counts;
}

// The Student-t weights' scale from the median absolute residual of the points with mask 1
// (sigma = 1.4826 median |r|): it holds while up to half of them belong to something moving
// by itself. Kerl's fixed point (eq. 12) averages every residual into the scale, so a person
// filling a third of the view widened it until their pixels kept their weight and pulled the
// camera along (people.yaml's circle: docs/odometry.md). The median comes
// from a histogram of |r| (one pass, no sort); beyond its range, from the fixed point.
double Aligner::estimate_variance(int count, int valid, double initial_variance) {
  std::fill(residual_histogram_.begin(), residual_histogram_.end(), 0U);
  const float* r = residual_.data();
  const float* m = mask_.data();
  constexpr float kBinsPerUnit =
      static_cast<float>(kResidualHistogramBins) / kResidualHistogramRange;
  int in_use = 0;
  for (int i = 0; i < count; ++i) {
    if (m[i] <= 0.0f) continue;
    ++in_use;
    const float bin = std::abs(r[i]) * kBinsPerUnit;
    if (bin < static_cast<float>(kResidualHistogramBins)) {
      ++residual_histogram_[static_cast<std::size_t>(bin)];
    }
  }
  const auto half = static_cast<std::uint32_t>(in_use / 2);
  std::uint32_t below = 0;
  for (int b = 0; b < kResidualHistogramBins; ++b) {
    const std::uint32_t in_bin = residual_histogram_[static_cast<std::size_t>(b)];
    if (below + in_bin > half) {
      // Linear within the bin.
      const float fraction = (static_cast<float>(half - below) + 0.5f) / static_cast<float>(in_bin);
      const float median = (static_cast<float>(b) + fraction) / kBinsPerUnit;
      const float sigma = kMadToSigma * median;
      return std::max(sigma * sigma, 1e-6f);
    }
    below += in_bin;
  }
  return student_t_variance(count, valid, initial_variance);
}

// Student-t scale by fixed-point iteration (Kerl 2013, eq. 12) over the points with mask 1.
HQ_CLONES_X86_64_V3
double Aligner::student_t_variance(int count, int valid, double initial_variance) const {
  const auto nu = static_cast<float>(config_.student_t_dof);
  const float* r = residual_.data();
  const float* m = mask_.data();
  float variance = static_cast<float>(initial_variance);
  for (int it = 0; it < kScaleIterations; ++it) {
    const float inv_var = 1.0f / variance;
    float sum = 0.0f;
#pragma omp simd reduction(+ : sum)
    for (int i = 0; i < count; ++i) {
      const float r2 = r[i] * r[i];
      sum += m[i] * r2 * (nu + 1.0f) / (nu + r2 * inv_var);
    }
    const float next = std::max(sum / static_cast<float>(valid), 1e-6f);
    const bool converged = std::abs(next - variance) < 1e-3f * variance;
    variance = next;
    if (converged) break;
  }
  return variance;
}

// Scale matrix Sigma of the bivariate t-distribution of (r_I, r_Z) by fixed-point iteration
// (Kerl IROS 2013, eq. 13): Sigma = 1/n sum w r r^T, w = (nu + 2) / (nu + r^T Sigma^-1 r).
// Points with only one residual (no gradient, or no current depth) use that residual's
// marginal, a univariate t with the matching diagonal entry.
HQ_CLONES_X86_64_V3
void Aligner::estimate_scale_matrix(int count) {
  const auto nu = static_cast<float>(config_.student_t_dof);
  const float* ri = residual_.data();
  const float* rz = depth_residual_.data();
  const float* mi = mask_.data();
  const float* mz = depth_mask_.data();
  for (int it = 0; it < kScaleIterations; ++it) {
    const double det = sigma_ii_ * sigma_zz_ - sigma_iz_ * sigma_iz_;
    const auto i_ii = static_cast<float>(sigma_zz_ / det);
    const auto i_iz = static_cast<float>(-sigma_iz_ / det);
    const auto i_zz = static_cast<float>(sigma_ii_ / det);
    const auto inv_ii = static_cast<float>(1.0 / sigma_ii_);
    const auto inv_zz = static_cast<float>(1.0 / sigma_zz_);
    float a_ii = 0, a_iz = 0, a_zz = 0, n_i = 0, n_z = 0, n_b = 0;
#pragma omp simd reduction(+ : a_ii, a_iz, a_zz, n_i, n_z, n_b)
    for (int i = 0; i < count; ++i) {
      const float both = mi[i] * mz[i];
      const float q = ri[i] * ri[i] * i_ii + 2.0f * ri[i] * rz[i] * i_iz + rz[i] * rz[i] * i_zz;
      const float w_b = both * (nu + 2.0f) / (nu + q);
      const float w_i = (mi[i] - both) * (nu + 1.0f) / (nu + ri[i] * ri[i] * inv_ii);
      const float w_z = (mz[i] - both) * (nu + 1.0f) / (nu + rz[i] * rz[i] * inv_zz);
      a_ii += (w_b + w_i) * ri[i] * ri[i];
      a_zz += (w_b + w_z) * rz[i] * rz[i];
      a_iz += w_b * ri[i] * rz[i];
      n_i += mi[i];
      n_z += mz[i];
      n_b += both;
    }
    const double next_ii = n_i > 0 ? std::max<double>(a_ii / n_i, 1e-6) : sigma_ii_;
    const double next_zz = n_z > 0 ? std::max<double>(a_zz / n_z, 1e-6) : sigma_zz_;
    double next_iz = n_b > 0 ? static_cast<double>(a_iz / n_b) : 0.0;
    // Keep Sigma positive definite when few points carry both residuals.
    const double bound = 0.95 * std::sqrt(next_ii * next_zz);
    next_iz = std::clamp(next_iz, -bound, bound);
    const bool converged = std::abs(next_ii - sigma_ii_) < 1e-3 * sigma_ii_ &&
                           std::abs(next_zz - sigma_zz_) < 1e-3 * sigma_zz_;
    sigma_ii_ = next_ii;
    sigma_iz_ = next_iz;
    sigma_zz_ = next_zz;
    if (converged) break;
  }
}

// Normal equations of the intensity residuals alone: Student-t weights then one pass.
HQ_CLONES_X86_64_V3
double Aligner::accumulate(int level, int count, double variance, NormalEquations& out) {
  const auto nu = static_cast<float>(config_.student_t_dof);
  const auto inv_var = static_cast<float>(1.0 / variance);
  const float* r = residual_.data();
  const float* m = mask_.data();
  float* w = weight_.data();
#pragma omp simd
  for (int i = 0; i < count; ++i) w[i] = m[i] * (nu + 1.0f) / (nu + r[i] * r[i] * inv_var);
  const ReferenceLevel& ref = at_level(*reference_, level);
  const float* J[6] = {ref.jacobian[0].data(), ref.jacobian[1].data(), ref.jacobian[2].data(),
                       ref.jacobian[3].data(), ref.jacobian[4].data(), ref.jacobian[5].data()};
  RowSums sums;
  accumulate_rows(J, r, w, count, sums);
  store(sums, 1.0 / variance, out);
  return sums.weighted_error;
}

// Normal equations of intensity and depth residuals under the bivariate t weights. With
// Sigma^-1 = U U^T, U upper triangular, the pair's term w r^T Sigma^-1 r splits into two
// rows: e1 = r_I / sqrt(Sigma_II) (u11^2 = 1 / Sigma_II), which leaves the intensity rows as
// they are and keeps their precomputed Jacobians, and e2 = u12 r_I + u22 r_Z, whose Jacobian
// is formed inside its accumulation (accumulate_depth_rows). Returns sum w r^T Sigma^-1 r
// x Sigma_II (intensity units^2, comparable across iterations as the intensity-only error).
HQ_CLONES_X86_64_V3
double Aligner::accumulate_with_depth(int level, int count, NormalEquations& out) {
  const auto nu = static_cast<float>(config_.student_t_dof);
  const double det = sigma_ii_ * sigma_zz_ - sigma_iz_ * sigma_iz_;
  const auto i_ii = static_cast<float>(sigma_zz_ / det);
  const auto i_iz = static_cast<float>(-sigma_iz_ / det);
  const auto i_zz = static_cast<float>(sigma_ii_ / det);
  const auto inv_ii = static_cast<float>(1.0 / sigma_ii_);
  const auto inv_zz = static_cast<float>(1.0 / sigma_zz_);
  const auto inv_sd_z = static_cast<float>(1.0 / std::sqrt(sigma_zz_));
  const float u22 = std::sqrt(i_zz);
  const float u12 = i_iz / u22;
  const ReferenceLevel& ref = at_level(*reference_, level);
  const float* ri = residual_.data();
  const float* rz = depth_residual_.data();
  const float* mi = mask_.data();
  const float* mz = depth_mask_.data();
  float* wi = weight_.data();
  float* wz = depth_weight_.data();
  float* cz = depth_whitening_.data();
  float* ci = depth_offset_jacobian_.data();
#pragma omp simd
  for (int i = 0; i < count; ++i) {
    const float both = mi[i] * mz[i];
    const float q = ri[i] * ri[i] * i_ii + 2.0f * ri[i] * rz[i] * i_iz + rz[i] * rz[i] * i_zz;
    const float w_b = both * (nu + 2.0f) / (nu + q);
    const float w_i = (mi[i] - both) * (nu + 1.0f) / (nu + ri[i] * ri[i] * inv_ii);
    const float w_z = (mz[i] - both) * (nu + 1.0f) / (nu + rz[i] * rz[i] * inv_zz);
    wi[i] = (w_b + w_i) * inv_ii;
    wz[i] = w_b + w_z;
    // Depth row: both residuals -> u12 r_I + u22 r_Z; depth alone -> r_Z / sqrt(Sigma_ZZ).
    cz[i] = both * u22 + (mz[i] - both) * inv_sd_z;
    ci[i] = both * u12;
  }
  const float* J[6] = {ref.jacobian[0].data(), ref.jacobian[1].data(), ref.jacobian[2].data(),
                       ref.jacobian[3].data(), ref.jacobian[4].data(), ref.jacobian[5].data()};
  RowSums sums;
  accumulate_rows(J, ri, wi, count, sums);
  // The depth rows are formed inside their accumulation, never stored.
  DepthRows rows;
  for (int k = 0; k < 3; ++k) rows.d_rz_d_q[k] = depth_jacobian_[k].data();
  rows.px = ref.x.data();
  rows.py = ref.y.data();
  rows.pz = ref.z.data();
  rows.rz = rz;
  rows.ri = ri;
  for (int k = 0; k < 6; ++k) rows.ji[k] = J[k];
  rows.c_z = cz;
  rows.c_i = ci;
  rows.T = warp_;
  // H's upper triangle is row-major: (0,0) (0,1) (0,2) at 0-2, (1,1) (1,2) at 6-7, (2,2) at 11.
  constexpr int kTranslation[6] = {0, 1, 2, 6, 7, 11};
  double intensity_only[6];
  for (int k = 0; k < 6; ++k) intensity_only[k] = sums.H[kTranslation[k]];
  accumulate_depth_rows(rows, wz, count, sums);
  store(sums, 1.0, out);
  double d[6];
  for (int k = 0; k < 6; ++k) d[k] = sums.H[kTranslation[k]] - intensity_only[k];
  out.H_depth_translation << d[0], d[1], d[2], d[1], d[3], d[4], d[2], d[4], d[5];
  return sums.weighted_error * sigma_ii_;
}

// The data term of one iteration: the robust weights' scale (started from the residuals on a
// level's first iteration, then re-estimated) and the normal equations; returns the mean
// weighted error. variance: the photometric one, kept across levels for the prior's cost.
double Aligner::weigh_and_accumulate(int level, int count, const Counts& counts,
                                     double& level_variance, double& variance,
                                     NormalEquations& out) {
  const int valid = counts.any;
  if (!depth_term_at(config_, level)) {
    if (level_variance == 0.0) {
      double sum = 0.0;
      for (int i = 0; i < count; ++i) sum += static_cast<double>(residual_[i] * residual_[i]);
      level_variance = std::max(sum / valid, 1.0);
    }
    variance = estimate_variance(count, valid, level_variance);
    level_variance = variance;
    return accumulate(level, count, variance, out) / valid;
  }
  if (sigma_ii_ == 0.0) {
    double sum_i = 0.0, sum_z = 0.0;
    for (int i = 0; i < count; ++i) {
      sum_i += static_cast<double>(mask_[i] * residual_[i] * residual_[i]);
      sum_z += static_cast<double>(depth_mask_[i] * depth_residual_[i] * depth_residual_[i]);
    }
    sigma_ii_ = std::max(sum_i / std::max(counts.photometric, 1), 1.0);
    sigma_zz_ = std::max(sum_z / std::max(counts.depth, 1), 1e-3);
    sigma_iz_ = 0.0;
  }
  estimate_scale_matrix(count);
  return accumulate_with_depth(level, count, out) / valid;
}

// The gyro prior's cost in the data term's units (intensity^2 per point): a step towards the
// gyro may raise the data cost and still lower the total.
double Aligner::prior_cost(int level, const Eigen::Isometry3d& T_cur_ref, const Prediction& p,
                           double variance, int valid) const {
  const Eigen::Vector3d d =
      geometry::log_so3(T_cur_ref.linear().transpose() * p.R_ref_prior.transpose());
  const double scale = depth_term_at(config_, level) ? sigma_ii_ : variance;
  return d.dot(p.prior_information * d) * scale / valid;
}

// One Gauss-Newton step (twist delta, brightness offset) from the data term and the priors.
void Aligner::solve_step(const NormalEquations& normal, const Eigen::Isometry3d& T_cur_ref,
                         const Prediction& p, Vector6d& delta, double& delta_offset) const {
  Matrix6d A = normal.H;
  Vector6d b = normal.g;
  if (config_.use_motion_prior && p.predict) {
    // Kerl 2013: a Gaussian prior around the constant-velocity prediction.
    // Scaled to this level's data term: coarse levels have fewer, smaller gradients, and a
    // prior at full finest-level strength would pin them to the prediction.
    const double level_scale = normal.H.trace() / p.last_information.trace();
    const Matrix6d P = config_.motion_prior_precision * level_scale * p.last_information;
    // T_ref_cur moves as exp(delta) T_ref_cur, so its deviation from the prediction is
    // delta + d with d = log(T_ref_cur T_ref_predicted^-1).
    const Vector6d d = geometry::log_se3(T_cur_ref.inverse() * p.T_ref_predicted.inverse());
    A += P;
    b -= P * d;
  }
  if (p.use_prior) {
    // The gyro prior on the rotation part: T_ref_cur's rotation moves as exp(omega) R, so
    // its deviation from the gyro's is omega + log(R R_prior^T).
    const Eigen::Vector3d d =
        geometry::log_so3(T_cur_ref.linear().transpose() * p.R_ref_prior.transpose());
    A.bottomRightCorner<3, 3>() += p.prior_information;
    b.tail<3>() -= p.prior_information * d;
  }
  // Auto-exposure shifts every intensity alike; an offset absorbs it instead of the
  // pose (Engel et al. use an affine model for the same reason). Without it the offset's
  // row is the identity's and its step 0.
  Matrix7d A7 = Matrix7d::Identity();
  Vector7d b7 = Vector7d::Zero();
  A7.topLeftCorner<6, 6>() = A;
  b7.head<6>() = b;
  if (config_.estimate_brightness_offset) {
    A7.topRightCorner<6, 1>() = normal.H_pose_offset;
    A7.bottomLeftCorner<1, 6>() = normal.H_pose_offset.transpose();
    A7(6, 6) = normal.H_offset;
    b7(6) = normal.g_offset;
  }
  const Vector7d x = solve_remapped(A7, b7, config_.degenerate_step_ratio);
  delta = x.head<6>();
  delta_offset = config_.estimate_brightness_offset ? x(6) : 0.0;
}

// brightness_offset; out keeps the last accepted iteration's normal equations and error.
void Aligner::solve_level(int level, const FrameSlot& current, const Prediction& p,
                          Eigen::Isometry3d& T_cur_ref, float& brightness_offset, double& variance,
                          Alignment& out) {
  const int count = at_level(*reference_, level).count;
  double previous_cost = std::numeric_limits<double>::infinity();
  double previous_weighted_error = out.weighted_error;
  Eigen::Isometry3d T_previous = T_cur_ref;
  double level_variance = 0.0;
  sigma_ii_ = 0.0;
  float offset_previous = brightness_offset;
  // A pixel at level l spans 2^l pixels of level 0: a step that moves the image by a fixed
  // fraction of a pixel is worth less at coarse levels, so they stop sooner.
  const double tolerance =
      config_.step_tolerance * static_cast<double>(1 << (level - cameras_.finest()));
  const int max_iterations =
      p.max_iterations > 0 ? p.max_iterations : config_.max_iterations_per_level;
  for (int it = 0; it < max_iterations; ++it) {
    const Counts counts = compute_residuals(level, current, T_cur_ref, brightness_offset);
    out.valid = counts.any;
    if (out.valid < 6) break;
    NormalEquations candidate;
    out.weighted_error =
        weigh_and_accumulate(level, count, counts, level_variance, variance, candidate);
    ++out.iterations;
    double cost = out.weighted_error;
    if (p.use_prior) cost += prior_cost(level, T_cur_ref, p, variance, out.valid);
    if (cost > previous_cost && p.stop_on_rising_cost) {
      // The last step made the fit worse: undo it and stop refining this level.
      T_cur_ref = T_previous;
      brightness_offset = offset_previous;
      out.weighted_error = previous_weighted_error;
      break;
    }
    previous_cost = cost;
    previous_weighted_error = out.weighted_error;
    out.normal = candidate;
    Vector6d delta;
    double delta_offset = 0.0;
    solve_step(out.normal, T_cur_ref, p, delta, delta_offset);
    if (!delta.allFinite() || !std::isfinite(delta_offset)) break;
    T_previous = T_cur_ref;
    offset_previous = brightness_offset;
    brightness_offset += static_cast<float>(delta_offset);
    T_cur_ref = T_cur_ref * geometry::exp_se3(-delta);
    if (delta.squaredNorm() < tolerance * tolerance) break;
  }
}

Alignment Aligner::align(const ReferenceSet& reference, const FrameSlot& current,
                         Eigen::Isometry3d T_cur_ref, const Prediction& p) {
  reference_ = &reference;
  Alignment out;
  for (int level = cameras_.levels() - 1; level >= cameras_.finest(); --level) {
    solve_level(level, current, p, T_cur_ref, out.brightness_offset, out.variance, out);
  }
  out.T_cur_ref = T_cur_ref;
  return out;
}

Alignment Aligner::vision_only(const ReferenceSet& reference, const FrameSlot& current,
                               const Alignment& joint) {
  reference_ = &reference;
  Alignment out = joint;
  Prediction p;
  p.stop_on_rising_cost = false;
  p.max_iterations = config_.vision_only_iterations;
  solve_level(cameras_.finest(), current, p, out.T_cur_ref, out.brightness_offset, out.variance,
              out);
  return out;
}

}  // namespace hq::odometry::detail
