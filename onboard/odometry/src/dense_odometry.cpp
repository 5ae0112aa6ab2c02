#include "hq/odometry/dense_odometry.hpp"

#include "hq/base/target_clones.hpp"
#include "hq/geometry/lie.hpp"

#include "degeneracy.hpp"
#include "gyro_fusion.hpp"
#include "kernels.hpp"
#include "pyramid.hpp"
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace hq::odometry {

namespace {

constexpr int kMaxLevels = 6;
// Blocks whose depths spread by more than this fraction are treated as occlusion edges.
constexpr float kDepthEdgeSpreadRatio = 0.05f;
constexpr int kScaleIterations = 5;
// The median |r| is read from a histogram over [0, this range) in intensity units (0-255): a
// median beyond it means nothing is aligned, and the fixed point takes over.
constexpr float kResidualHistogramRange = 64.0f;
constexpr int kResidualHistogramBins = 1024;
constexpr float kMadToSigma = 1.4826f;  // sigma of a normal distribution over its median |r|
// A depth turn under this moves no pixel by a thousandth of one at 640x480: skipped.
constexpr double kMinDepthTurnRad = 2e-6;

using detail::GyroObservation;
using detail::GyroSteps;
using detail::Matrix7d;
using detail::NormalEquations;
using detail::Vector6d;
using detail::Vector7d;

// One prepared pyramid level of the reference frame, structure of arrays so that the warp and
// accumulation loops stream through memory.
struct ReferenceLevel {
  std::vector<float> x, y, z;      // 3D point in the reference camera frame, metres
  std::vector<float> intensity;    // I_ref at the pixel
  std::vector<float> photometric;  // 1 if the pixel has gradient (a photometric residual), else 0
  std::vector<float> depth_point;  // 1 if the point may carry a depth residual, else 0
  std::vector<float> nx, ny, nz;   // its surface's unit normal (depth_jacobian_from_normals)
  std::array<std::vector<float>, 6> jacobian;  // d I_ref(pi(exp(xi) p)) / d xi at xi = 0
  int count = 0;

  void reserve(int capacity) {
    for (auto* v : {&x, &y, &z, &intensity, &photometric, &depth_point, &nx, &ny, &nz}) {
      v->assign(capacity, 0.0f);
    }
    for (auto& j : jacobian) j.assign(capacity, 0.0f);
    count = 0;
  }
};

struct FrameSlot {
  std::array<cv::Mat, kMaxLevels> intensity;  // CV_32FC1; level 0 unused if finest_level > 0
  std::array<cv::Mat, kMaxLevels> depth_m;    // CV_32FC1, 0 = no depth
};

double entropy_of(const Matrix6d& information) {
  // Differential entropy of a Gaussian up to a constant: -0.5 ln det(information).
  const Eigen::LLT<Matrix6d> llt(information);
  if (llt.info() != Eigen::Success) return 0.0;
  const auto& L = llt.matrixL();
  double log_det = 0.0;
  for (int i = 0; i < 6; ++i) log_det += 2.0 * std::log(L(i, i));
  return -0.5 * log_det;
}

}  // namespace

struct DenseOdometry::Impl {
  OdometryConfig config;
  geometry::PinholeCamera camera;
  std::array<geometry::PinholeCamera, kMaxLevels> level_camera;
  int levels = 0;
  int finest = 0;

  // Three slots: the reference (keyframe), the previous frame (for the keyframe check) and the
  // current frame; frame to frame the previous frame is the reference.
  std::array<FrameSlot, 3> slots;
  int reference_slot = 0;
  int previous_slot = 0;
  // Prepared points of the reference (set 0) and, with the keyframe check, of the previous
  // frame (set 1); the kernels read the active one.
  static constexpr int kReferenceSet = 0;
  static constexpr int kPreviousSet = 1;
  std::array<std::array<ReferenceLevel, kMaxLevels>, 2> reference_sets;
  int active_set = kReferenceSet;
  bool has_reference = false;
  bool has_previous = false;  // set 1 holds the previous frame

  // Per-point work buffers, sized for the finest optimised level. mask: 1 where the residual
  // exists; weight: its robust weight including the scale.
  // Per level, pixels of the frame about to become the reference that the last alignment saw
  // move on their own (mark_moving_pixels()); prepare_reference() leaves them out. 1 = moving.
  std::array<cv::Mat, kMaxLevels> moving;
  bool moving_known = false;
  std::vector<float> residual;
  std::vector<float> mask;
  std::vector<std::uint32_t> residual_histogram =
      std::vector<std::uint32_t>(kResidualHistogramBins);  // |r| counts for the median scale
  std::vector<float> weight;
  std::vector<float> depth_residual;
  std::vector<float> depth_mask;
  std::vector<float> depth_weight;
  std::vector<float> depth_offset_jacobian;  // d (whitened depth row) / d brightness offset
  // d r_Z / d q per point, from compute_residuals; the depth rows' Jacobians are formed from
  // it inside their accumulation.
  std::array<std::vector<float>, 3> depth_jacobian;
  std::vector<float> depth_whitening;  // c_z of the whitened depth row
  detail::Warp warp{};                 // T_cur_ref of the last compute_residuals
  // Scale matrix of (intensity, depth) residuals (Kerl IROS 2013, eq. 13).
  double sigma_ii = 0.0, sigma_iz = 0.0, sigma_zz = 0.0;

  Eigen::Isometry3d T_O_ref = Eigen::Isometry3d::Identity();
  // Last accepted estimate of the current frame in the reference (constant-velocity guess).
  Eigen::Isometry3d T_ref_last = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d last_motion = Eigen::Isometry3d::Identity();  // T_prev_cur of last frame
  Matrix6d last_information = Matrix6d::Zero();
  bool has_motion = false;
  // The rotation prior, the gyro bias and the vision's honest scale.
  detail::GyroFusion gyro{config};
  std::int64_t last_frame_t_ns = -1;  // any frame's, for the gyro step's interval
  double keyframe_first_entropy = 0.0;
  int keyframe_age = 0;
  float min_cos_incidence = 0.0f;              // of depth_max_incidence_deg
  std::array<cv::Mat, kMaxLevels> normal_map;  // of the reference being prepared
  cv::Mat turned_depth;  // the finest level's depth turned to the colour's exposure

  // Whether the depth residual acts on this level (the finest depth_levels levels).
  bool depth_at(int level) const {
    return config.use_depth_term &&
           (config.depth_levels == 0 || level < finest + config.depth_levels);
  }

  bool keyframe_check() const {
    return config.reference_mode == ReferenceMode::kFrameToKeyframe && config.keyframe_check;
  }

  Impl(const OdometryConfig& c, const geometry::PinholeCamera& cam) : config(c), camera(cam) {
    validate(config);
    min_cos_incidence = static_cast<float>(std::cos(config.depth_max_incidence_deg * M_PI / 180.0));
    levels = config.pyramid_levels;
    finest = config.finest_level;
    int capacity = 0;
    for (int l = 0; l < levels; ++l) {
      level_camera[l] = camera.at_level(l);
      const int w = level_camera[l].width;
      const int h = level_camera[l].height;
      // Each image is written once here: its pages are then mapped before the first frame,
      // not faulted in one by one during the first frames' tracking.
      if (config.depth_jacobian_from_normals && l >= finest) {
        normal_map[l].create(h, w, CV_32FC3);
        normal_map[l] = cv::Scalar::all(0.0);
      }
      if (l == finest) {
        turned_depth.create(h, w, CV_32FC1);
        turned_depth = 0.0f;
      }
      for (auto& slot : slots) {
        slot.intensity[l].create(h, w, CV_32FC1);
        slot.intensity[l] = 0.0f;
        slot.depth_m[l].create(h, w, CV_32FC1);
        slot.depth_m[l] = 0.0f;
      }
      if (l >= finest) {
        moving[l].create(h, w, CV_8UC1);
        moving[l] = 0;
        reference_sets[kReferenceSet][l].reserve(w * h);
        if (keyframe_check()) reference_sets[kPreviousSet][l].reserve(w * h);
        capacity = std::max(capacity, w * h);
      }
    }
    for (auto* v : {&residual, &mask, &weight, &depth_residual, &depth_mask, &depth_weight,
                    &depth_offset_jacobian, &depth_whitening}) {
      v->assign(capacity, 0.0f);
    }
    for (auto& j : depth_jacobian) j.assign(capacity, 0.0f);
  }

  // A depth that align_depth will turn is built only down to the finest level used: the
  // coarser levels are rebuilt from the turned one there.
  void build_pyramid(FrameSlot& slot, const cv::Mat& gray, const cv::Mat& depth_m,
                     bool depth_to_be_turned) {
    const auto min_depth = static_cast<float>(config.min_depth_m);
    const auto max_depth = static_cast<float>(config.max_depth_m);
    detail::sanitize_depth(depth_m, slot.depth_m[0], min_depth, max_depth);
    if (finest == 0) gray.convertTo(slot.intensity[0], CV_32F);
    const int depth_levels_built = depth_to_be_turned ? finest + 1 : levels;
    for (int l = 1; l < levels; ++l) {
      // Level 1 straight from the 8-bit input: one pass instead of convert-then-average.
      const cv::Mat& src = (l == 1) ? gray : slot.intensity[l - 1];
      detail::downsample_intensity(src, slot.intensity[l]);
      if (l < depth_levels_built) {
        detail::downsample_depth(slot.depth_m[l - 1], slot.depth_m[l], kDepthEdgeSpreadRatio);
      }
    }
  }

  // Turns the depth, from the finest level used up, to the colour image's exposure (the
  // rotation between the two; coarser levels rebuilt from the turned one).
  void align_depth(FrameSlot& slot, const Eigen::Matrix3d& R_depth_colour) {
    const detail::Intrinsics k = intrinsics(finest);
    detail::rotate_depth(slot.depth_m[finest], turned_depth, k.fx, k.fy, k.cx, k.cy,
                         R_depth_colour.cast<float>(), kDepthEdgeSpreadRatio);
    std::swap(turned_depth, slot.depth_m[finest]);  // headers only: both stay allocated
    for (int l = finest + 1; l < levels; ++l) {
      detail::downsample_depth(slot.depth_m[l - 1], slot.depth_m[l], kDepthEdgeSpreadRatio);
    }
  }

  // Whether a frame's depth is turned: by a finite rotation matrix that moves a pixel at all.
  bool should_align_depth(const RotationPrior* prior) const {
    if (prior == nullptr || !config.align_depth_to_colour) return false;
    const Eigen::Matrix3d& R = prior->R_depth_colour;
    if (!R.allFinite() || !(R * R.transpose()).isIdentity(1e-6) || R.determinant() < 0.0) {
      return false;
    }
    const double angle = Eigen::AngleAxisd(R).angle();
    return angle > kMinDepthTurnRad;
  }

  // Selects pixels with depth and gradient, and precomputes their points and Jacobians: done
  // once per reference, not per iteration (the inverse compositional trick).
  HQ_CLONES_X86_64_V3
  void prepare_reference(const FrameSlot& slot, int set) {
    const auto min_gradient_sq = static_cast<float>(config.min_gradient * config.min_gradient);
    const auto spread = static_cast<float>(config.depth_max_spread_ratio);
    if (config.depth_jacobian_from_normals) {
      int computed = -1;  // normal_source() never decreases with the level
      for (int l = finest; l < levels; ++l) {
        if (!depth_at(l) || normal_source(l) == computed) continue;
        computed = normal_source(l);
        compute_normals(slot, computed);
      }
    }
    for (int l = finest; l < levels; ++l) {
      // With the depth term, pixels without gradient still constrain the pose through their
      // depth (a textureless wall fixes its normal's translation and two rotations).
      const bool depth_level = depth_at(l);
      const int stride = depth_level ? std::max(1, config.depth_point_stride) : 0;
      const geometry::PinholeCamera& cam = level_camera[l];
      const detail::Intrinsics k = intrinsics(l);
      const cv::Mat& I = slot.intensity[l];
      const cv::Mat& D = slot.depth_m[l];
      ReferenceLevel& ref = reference_sets[set][l];
      const bool skip_moving = moving_known && set == kReferenceSet;
      int n = 0;
      for (int v = 1; v < cam.height - 1; ++v) {
        const float* row = I.ptr<float>(v);
        const float* up = I.ptr<float>(v - 1);
        const float* down = I.ptr<float>(v + 1);
        const float* depth = D.ptr<float>(v);
        const std::uint8_t* moved = moving[l].ptr<std::uint8_t>(v);
        for (int u = 1; u < cam.width - 1; ++u) {
          const float z = depth[u];
          if (z <= 0.0f || (skip_moving && moved[u] != 0)) continue;
          const float gx = 0.5f * (row[u + 1] - row[u - 1]);
          const float gy = 0.5f * (down[u] - up[u]);
          const bool textured = gx * gx + gy * gy >= min_gradient_sq;
          if (!textured && (stride == 0 || u % stride != 0 || v % stride != 0)) continue;
          // A depth residual needs a surface around the reference pixel: at an occlusion edge
          // or beside missing depth, the pixel's depth (often a mixed one) and the current
          // depth's gradient there belong to no surface.
          bool surface = depth_level;
          if (surface) {
            const float neighbours[4] = {depth[u - 1], depth[u + 1], D.ptr<float>(v - 1)[u],
                                         D.ptr<float>(v + 1)[u]};
            for (const float d : neighbours)
              surface = surface && d > 0.0f && std::abs(d - z) <= spread * z;
          }
          const Eigen::Vector3f p_C =
              cam.unproject(static_cast<float>(u), static_cast<float>(v), z);
          Eigen::Vector3f normal = Eigen::Vector3f::Zero();
          if (surface && config.depth_jacobian_from_normals) {
            surface = surface_normal(l, p_C, normal);
          }
          if (!textured && !surface) continue;
          const float x = p_C.x();
          const float y = p_C.y();
          float J[6];
          detail::photometric_jacobian(x, y, z, gx, gy, k, J);
          ref.x[n] = x;
          ref.y[n] = y;
          ref.z[n] = z;
          ref.intensity[n] = row[u];
          ref.photometric[n] = textured ? 1.0f : 0.0f;
          ref.depth_point[n] = surface ? 1.0f : 0.0f;
          ref.nx[n] = normal.x();
          ref.ny[n] = normal.y();
          ref.nz[n] = normal.z();
          for (int j = 0; j < 6; ++j) ref.jacobian[j][n] = textured ? J[j] : 0.0f;
          ++n;
        }
      }
      ref.count = n;
    }
  }

  // Unit surface normals of one level's depth (CV_32FC3, zero where unknown): central
  // differences of its block means, none beside missing depth or across an edge.
  void compute_normals(const FrameSlot& slot, int level) {
    const geometry::PinholeCamera& cam = level_camera[level];
    const cv::Mat& D = slot.depth_m[level];
    cv::Mat& out = normal_map[level];
    for (int v = 0; v < cam.height; ++v) {
      auto* row = out.ptr<cv::Vec3f>(v);
      std::fill(row, row + cam.width, cv::Vec3f(0.0f, 0.0f, 0.0f));
    }
    const auto spread_ratio = static_cast<float>(config.depth_max_spread_ratio);
    for (int v = 1; v < cam.height - 1; ++v) {
      const float* row = D.ptr<float>(v);
      const float* above = D.ptr<float>(v - 1);
      const float* below = D.ptr<float>(v + 1);
      auto* n = out.ptr<cv::Vec3f>(v);
      for (int u = 1; u < cam.width - 1; ++u) {
        const float centre = row[u];
        const float spread = spread_ratio * centre;
        bool surface = centre > 0.0f;
        for (const float d : {row[u - 1], row[u + 1], above[u], below[u]}) {
          surface = surface && d > 0.0f && std::abs(d - centre) <= spread;
        }
        if (!surface) continue;
        const auto fu = static_cast<float>(u);
        const auto fv = static_cast<float>(v);
        const Eigen::Vector3f along_u =
            cam.unproject(fu + 1.0f, fv, row[u + 1]) - cam.unproject(fu - 1.0f, fv, row[u - 1]);
        const Eigen::Vector3f along_v =
            cam.unproject(fu, fv + 1.0f, below[u]) - cam.unproject(fu, fv - 1.0f, above[u]);
        const Eigen::Vector3f normal = along_u.cross(along_v);
        const float length = normal.norm();
        if (length > 0.0f) n[u] = cv::Vec3f(normal.x(), normal.y(), normal.z()) / length;
      }
    }
  }

  // The normal of the surface through the reference point p_C, from the normal map of the
  // level depth_normal_smoothing_levels coarser (block means: less noise); false where it has
  // none or sees the surface more obliquely than depth_max_incidence_deg (the ray-to-plane
  // factor of the Jacobian, 1 / cos, is unbounded).
  bool surface_normal(int level, const Eigen::Vector3f& p_C, Eigen::Vector3f& normal) const {
    const int source = normal_source(level);
    const geometry::PinholeCamera& cam = level_camera[source];
    const double u = cam.fx * static_cast<double>(p_C.x() / p_C.z()) + cam.cx;
    const double v = cam.fy * static_cast<double>(p_C.y() / p_C.z()) + cam.cy;
    const auto iu = static_cast<int>(std::lround(u));
    const auto iv = static_cast<int>(std::lround(v));
    if (iu < 0 || iv < 0 || iu >= cam.width || iv >= cam.height) return false;
    const cv::Vec3f& n = normal_map[source].at<cv::Vec3f>(iv, iu);
    normal = Eigen::Vector3f(n[0], n[1], n[2]);
    return std::abs(normal.dot(p_C)) >= min_cos_incidence * p_C.norm() &&
           normal.squaredNorm() > 0.5f;
  }

  int normal_source(int level) const {
    return std::min(level + config.depth_normal_smoothing_levels, levels - 1);
  }

  detail::Intrinsics intrinsics(int level) const {
    const geometry::PinholeCamera& cam = level_camera[level];
    return {static_cast<float>(cam.fx), static_cast<float>(cam.fy), static_cast<float>(cam.cx),
            static_cast<float>(cam.cy)};
  }

  struct Counts {
    int photometric = 0;  // points with an intensity residual
    int depth = 0;        // points with a depth residual
    int any = 0;          // points with either
  };

  // What warping the reference points into the current frame at one level needs.
  struct WarpSetup {
    detail::Intrinsics k;
    detail::Warp T;
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
             !(reject_occluded &&
               detail::depth_disagrees(depth, depth_stride, u, v, qz, occlusion_ratio));
    }
  };

  WarpSetup warp_setup(int level, const FrameSlot& current,
                       const Eigen::Isometry3d& T_cur_ref) const {
    const geometry::PinholeCamera& cam = level_camera[level];
    const Eigen::Matrix3f R = T_cur_ref.linear().cast<float>();
    const Eigen::Vector3f t = T_cur_ref.translation().cast<float>();
    const cv::Mat& image = current.intensity[level];
    const cv::Mat& depth_image = current.depth_m[level];
    const auto occlusion_ratio = static_cast<float>(config.occlusion_depth_ratio);
    return {intrinsics(level),
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

  // compute_residuals() of a level without the depth term.
  HQ_CLONES_X86_64_V3
  Counts compute_intensity_residuals(int level, const FrameSlot& current,
                                     const Eigen::Isometry3d& T_cur_ref, float brightness_offset) {
    const WarpSetup w = warp_setup(level, current, T_cur_ref);
    const detail::Warp& T = w.T;
    const ReferenceLevel& ref = reference_sets[active_set][level];
    const float* photometric = ref.photometric.data();
    Counts counts;
    for (int i = 0; i < ref.count; ++i) {
      float qx, qy, qz;
      T.apply(ref.x[i], ref.y[i], ref.z[i], qx, qy, qz);
      float r = 0.0f;
      float m = 0.0f;
      float u, v;
      if (w.visible(qx, qy, qz, u, v)) {
        r = detail::sample_bilinear(w.data, w.stride, u, v) - ref.intensity[i] - brightness_offset;
        m = photometric[i];
      }
      residual[i] = r;
      mask[i] = m;
      counts.photometric += m > 0.0f ? 1 : 0;
    }
    counts.any = counts.photometric;
    return counts;
  }

  // Warps every reference point with T_cur_ref, samples the current image (and, with the depth
  // term, the current depth), stores residuals and masks; points that leave the image, or whose
  // depth disagrees with the current one (occlusion_depth_ratio), get mask 0.
  HQ_CLONES_X86_64_V3
  Counts compute_residuals(int level, const FrameSlot& current, const Eigen::Isometry3d& T_cur_ref,
                           float brightness_offset) {
    if (!depth_at(level)) {
      return compute_intensity_residuals(level, current, T_cur_ref, brightness_offset);
    }
    const WarpSetup w = warp_setup(level, current, T_cur_ref);
    const detail::Intrinsics& k = w.k;
    const detail::Warp& T = w.T;
    const float* data = w.data;
    const float* depth = w.depth;
    const int stride = w.stride;
    const int depth_stride = w.depth_stride;
    const ReferenceLevel& ref = reference_sets[active_set][level];
    const float* photometric = ref.photometric.data();
    Counts counts;
    // Intensity and depth in one pass over the points and one warp; points without gradient
    // skip the intensity sample.
    const auto noise = static_cast<float>(config.depth_noise_per_m);
    const auto spread = static_cast<float>(config.depth_max_spread_ratio);
    // The gather only: residuals and d r_Z / d q here; the depth rows' Jacobians are formed
    // vectorised in accumulate_with_depth, which needs this warp's rotation.
    warp = T;
    const float* depth_point = ref.depth_point.data();
    const bool from_normals = config.depth_jacobian_from_normals;
    float* a0 = depth_jacobian[0].data();
    float* a1 = depth_jacobian[1].data();
    float* a2 = depth_jacobian[2].data();
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
          r = detail::sample_bilinear(data, stride, u, v) - ref.intensity[i] - brightness_offset;
          m = 1.0f;
        }
        if (depth_point[i] > 0.0f) {
          if (from_normals) {
            float nx, ny, nz;
            T.rotate(ref.nx[i], ref.ny[i], ref.nz[i], nx, ny, nz);
            ok = detail::depth_sample_on_surface(depth, depth_stride, qx, qy, qz, u, v, nx, ny, nz,
                                                 min_cos_incidence, noise, spread, rz, a);
          } else {
            ok = detail::depth_sample_at(depth, depth_stride, k, qx, qy, qz, u, v, noise, spread,
                                         rz, a);
          }
          if (!ok) a[0] = a[1] = a[2] = 0.0f;
        }
      }
      depth_residual[i] = ok ? rz : 0.0f;
      depth_mask[i] = ok ? 1.0f : 0.0f;
      a0[i] = a[0];
      a1[i] = a[1];
      a2[i] = a[2];
      residual[i] = r;
      mask[i] = m;
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
  double estimate_variance(int count, int valid, double initial_variance) {
    std::fill(residual_histogram.begin(), residual_histogram.end(), 0U);
    const float* r = residual.data();
    const float* m = mask.data();
    constexpr float kBinsPerUnit =
        static_cast<float>(kResidualHistogramBins) / kResidualHistogramRange;
    int in_use = 0;
    for (int i = 0; i < count; ++i) {
      if (m[i] <= 0.0f) continue;
      ++in_use;
      const float bin = std::abs(r[i]) * kBinsPerUnit;
      if (bin < static_cast<float>(kResidualHistogramBins)) {
        ++residual_histogram[static_cast<std::size_t>(bin)];
      }
    }
    const auto half = static_cast<std::uint32_t>(in_use / 2);
    std::uint32_t below = 0;
    for (int b = 0; b < kResidualHistogramBins; ++b) {
      const std::uint32_t in_bin = residual_histogram[static_cast<std::size_t>(b)];
      if (below + in_bin > half) {
        // Linear within the bin.
        const float fraction =
            (static_cast<float>(half - below) + 0.5f) / static_cast<float>(in_bin);
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
  double student_t_variance(int count, int valid, double initial_variance) const {
    const auto nu = static_cast<float>(config.student_t_dof);
    const float* r = residual.data();
    const float* m = mask.data();
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
  void estimate_scale_matrix(int count) {
    const auto nu = static_cast<float>(config.student_t_dof);
    const float* ri = residual.data();
    const float* rz = depth_residual.data();
    const float* mi = mask.data();
    const float* mz = depth_mask.data();
    for (int it = 0; it < kScaleIterations; ++it) {
      const double det = sigma_ii * sigma_zz - sigma_iz * sigma_iz;
      const auto i_ii = static_cast<float>(sigma_zz / det);
      const auto i_iz = static_cast<float>(-sigma_iz / det);
      const auto i_zz = static_cast<float>(sigma_ii / det);
      const auto inv_ii = static_cast<float>(1.0 / sigma_ii);
      const auto inv_zz = static_cast<float>(1.0 / sigma_zz);
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
      const double next_ii = n_i > 0 ? std::max<double>(a_ii / n_i, 1e-6) : sigma_ii;
      const double next_zz = n_z > 0 ? std::max<double>(a_zz / n_z, 1e-6) : sigma_zz;
      double next_iz = n_b > 0 ? static_cast<double>(a_iz / n_b) : 0.0;
      // Keep Sigma positive definite when few points carry both residuals.
      const double bound = 0.95 * std::sqrt(next_ii * next_zz);
      next_iz = std::clamp(next_iz, -bound, bound);
      const bool converged = std::abs(next_ii - sigma_ii) < 1e-3 * sigma_ii &&
                             std::abs(next_zz - sigma_zz) < 1e-3 * sigma_zz;
      sigma_ii = next_ii;
      sigma_iz = next_iz;
      sigma_zz = next_zz;
      if (converged) break;
    }
  }

  // Normal equations of the intensity residuals alone: Student-t weights then one pass.
  HQ_CLONES_X86_64_V3
  double accumulate(int level, int count, double variance, NormalEquations& out) {
    const auto nu = static_cast<float>(config.student_t_dof);
    const auto inv_var = static_cast<float>(1.0 / variance);
    const float* r = residual.data();
    const float* m = mask.data();
    float* w = weight.data();
#pragma omp simd
    for (int i = 0; i < count; ++i) w[i] = m[i] * (nu + 1.0f) / (nu + r[i] * r[i] * inv_var);
    const ReferenceLevel& ref = reference_sets[active_set][level];
    const float* J[6] = {ref.jacobian[0].data(), ref.jacobian[1].data(), ref.jacobian[2].data(),
                         ref.jacobian[3].data(), ref.jacobian[4].data(), ref.jacobian[5].data()};
    detail::RowSums sums;
    detail::accumulate_rows(J, r, w, count, sums);
    store(sums, 1.0 / variance, out);
    return sums.weighted_error;
  }

  // Normal equations of intensity and depth residuals under the bivariate t weights. With
  // Sigma^-1 = U U^T, U upper triangular, the pair's term w r^T Sigma^-1 r splits into two
  // rows: e1 = r_I / sqrt(Sigma_II) (u11^2 = 1 / Sigma_II), which leaves the intensity rows as
  // they are and keeps their precomputed Jacobians, and e2 = u12 r_I + u22 r_Z, whose Jacobian
  // is formed inside its accumulation (detail::accumulate_depth_rows). Returns sum w r^T Sigma^-1 r
  // x Sigma_II (intensity units^2, comparable across iterations as the intensity-only error).
  HQ_CLONES_X86_64_V3
  double accumulate_with_depth(int level, int count, NormalEquations& out) {
    const auto nu = static_cast<float>(config.student_t_dof);
    const double det = sigma_ii * sigma_zz - sigma_iz * sigma_iz;
    const auto i_ii = static_cast<float>(sigma_zz / det);
    const auto i_iz = static_cast<float>(-sigma_iz / det);
    const auto i_zz = static_cast<float>(sigma_ii / det);
    const auto inv_ii = static_cast<float>(1.0 / sigma_ii);
    const auto inv_zz = static_cast<float>(1.0 / sigma_zz);
    const auto inv_sd_z = static_cast<float>(1.0 / std::sqrt(sigma_zz));
    const float u22 = std::sqrt(i_zz);
    const float u12 = i_iz / u22;
    const ReferenceLevel& ref = reference_sets[active_set][level];
    const float* ri = residual.data();
    const float* rz = depth_residual.data();
    const float* mi = mask.data();
    const float* mz = depth_mask.data();
    float* wi = weight.data();
    float* wz = depth_weight.data();
    float* cz = depth_whitening.data();
    float* ci = depth_offset_jacobian.data();
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
    detail::RowSums sums;
    detail::accumulate_rows(J, ri, wi, count, sums);
    // The depth rows are formed inside their accumulation, never stored.
    detail::DepthRows rows;
    for (int k = 0; k < 3; ++k) rows.d_rz_d_q[k] = depth_jacobian[k].data();
    rows.px = ref.x.data();
    rows.py = ref.y.data();
    rows.pz = ref.z.data();
    rows.rz = rz;
    rows.ri = ri;
    for (int k = 0; k < 6; ++k) rows.ji[k] = J[k];
    rows.c_z = cz;
    rows.c_i = ci;
    rows.T = warp;
    // H's upper triangle is row-major: (0,0) (0,1) (0,2) at 0-2, (1,1) (1,2) at 6-7, (2,2) at 11.
    constexpr int kTranslation[6] = {0, 1, 2, 6, 7, 11};
    double intensity_only[6];
    for (int k = 0; k < 6; ++k) intensity_only[k] = sums.H[kTranslation[k]];
    detail::accumulate_depth_rows(rows, wz, count, sums);
    store(sums, 1.0, out);
    double d[6];
    for (int k = 0; k < 6; ++k) d[k] = sums.H[kTranslation[k]] - intensity_only[k];
    out.H_depth_translation << d[0], d[1], d[2], d[1], d[3], d[4], d[2], d[4], d[5];
    return sums.weighted_error * sigma_ii;
  }

  static void store(const detail::RowSums& sums, double scale, NormalEquations& out) {
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

  OdometryResult lost(OdometryResult result, const char* reason) {
    result.status = TrackingStatus::kLost;
    result.reason = reason;
    result.T_ref_cur = Eigen::Isometry3d::Identity();
    result.information.setZero();
    has_motion = false;
    return result;
  }

  bool reference_usable() const {
    const int pixels = level_camera[finest].width * level_camera[finest].height;
    return reference_sets[kReferenceSet][finest].count >=
           std::max(6, static_cast<int>(config.min_valid_ratio * pixels));
  }

  void make_reference(int slot_index, const Eigen::Isometry3d& T_O_C) {
    reference_slot = slot_index;
    prepare_reference(slots[slot_index], kReferenceSet);
    moving_known = false;
    previous_slot = slot_index;
    has_previous = false;
    has_reference = reference_usable();
    T_O_ref = T_O_C;
    T_ref_last.setIdentity();
    gyro.restart_chain();
    keyframe_age = 0;
    keyframe_first_entropy = 0.0;
  }

  struct Alignment {
    Eigen::Isometry3d T_cur_ref = Eigen::Isometry3d::Identity();
    NormalEquations normal;
    float brightness_offset = 0.0f;
    double variance = 0.0;  // the photometric one, as solve_level() keeps it
    int valid = 0;
    int iterations = 0;
    double weighted_error = 0.0;
  };

  // What one alignment starts from and is pulled towards: the constant-velocity prediction
  // (Kerl 2013's motion prior) and the gyro's rotation (the rotation prior).
  struct Prediction {
    bool predict = false;    // the motion prior around T_ref_predicted applies
    bool use_prior = false;  // the gyro prior around R_ref_prior applies
    // A step that raises the cost is undone and ends the level. The cost is re-weighted every
    // iteration, so from a start near the minimum (vision_only()) it may rise on the first step
    // of a good descent; there the step tolerance alone ends it.
    bool stop_on_rising_cost = true;
    int max_iterations = 0;  // per level; 0: config.max_iterations_per_level
    Eigen::Isometry3d T_ref_predicted = Eigen::Isometry3d::Identity();
    Eigen::Matrix3d R_ref_prior = Eigen::Matrix3d::Identity();
    Eigen::Matrix3d prior_information = Eigen::Matrix3d::Zero();
    // The gyro step's alone (data-term units), for the alignment to the previous frame.
    Eigen::Matrix3d step_information = Eigen::Matrix3d::Zero();
  };

  // Marks the pixels of `current` that the final alignment a saw move on their own: where a
  // reference point lands with a photometric residual beyond moving_residual_sigmas of the
  // robust scale, or with a depth that disagrees (odometry.occlusion_depth_ratio), and their
  // four neighbours; coarser levels by the 2x2 maximum. When current becomes the reference,
  // a person already seen walking is left out of it, so that the next frames are not aligned
  // to them. Nothing is marked when more than max_moving_ratio of the points would be: then
  // the alignment itself, not the scene, is in doubt.
  void mark_moving_pixels(const FrameSlot& current, const Alignment& a) {
    moving_known = false;
    if (config.moving_residual_sigmas <= 0.0) return;
    compute_residuals(finest, current, a.T_cur_ref, a.brightness_offset);
    const ReferenceLevel& ref = reference_sets[active_set][finest];
    const WarpSetup w = warp_setup(finest, current, a.T_cur_ref);
    const detail::Intrinsics& k = w.k;
    const detail::Warp& T = w.T;
    const geometry::PinholeCamera& cam = level_camera[finest];
    const auto limit = static_cast<float>(config.moving_residual_sigmas * std::sqrt(a.variance));
    cv::Mat& marks = moving[finest];
    marks = 0;
    int marked = 0;
    int used = 0;
    for (int i = 0; i < ref.count; ++i) {
      if (ref.photometric[i] <= 0.0f) continue;
      float qx, qy, qz;
      T.apply(ref.x[i], ref.y[i], ref.z[i], qx, qy, qz);
      if (qz <= 0.0f) continue;
      const auto u = static_cast<int>(std::lround(k.fx * qx / qz + k.cx));
      const auto v = static_cast<int>(std::lround(k.fy * qy / qz + k.cy));
      if (u < 1 || v < 1 || u >= cam.width - 1 || v >= cam.height - 1) continue;
      ++used;
      // mask 0 inside the image: the depth disagreed (or the sample fell off the last column)
      const bool moved =
          mask[i] > 0.0f ? std::abs(residual[i]) > limit : config.occlusion_depth_ratio > 0.0;
      if (!moved) continue;
      ++marked;
      marks.at<std::uint8_t>(v, u) = 1;
      marks.at<std::uint8_t>(v - 1, u) = 1;
      marks.at<std::uint8_t>(v + 1, u) = 1;
      marks.at<std::uint8_t>(v, u - 1) = 1;
      marks.at<std::uint8_t>(v, u + 1) = 1;
    }
    if (used == 0 || marked > config.max_moving_ratio * used) return;
    for (int l = finest + 1; l < levels; ++l) {
      const cv::Mat& fine = moving[l - 1];
      cv::Mat& coarse = moving[l];
      for (int v = 0; v < coarse.rows; ++v) {
        for (int u = 0; u < coarse.cols; ++u) {
          const int fu = std::min(2 * u, fine.cols - 2);
          const int fv = std::min(2 * v, fine.rows - 2);
          coarse.at<std::uint8_t>(v, u) =
              fine.at<std::uint8_t>(fv, fu) | fine.at<std::uint8_t>(fv, fu + 1) |
              fine.at<std::uint8_t>(fv + 1, fu) | fine.at<std::uint8_t>(fv + 1, fu + 1);
        }
      }
    }
    moving_known = true;
  }

  int finest_pixels() const { return level_camera[finest].width * level_camera[finest].height; }

  // The data term of one iteration: the robust weights' scale (started from the residuals on a
  // level's first iteration, then re-estimated) and the normal equations; returns the mean
  // weighted error. variance: the photometric one, kept across levels for the prior's cost.
  double weigh_and_accumulate(int level, int count, const Counts& counts, double& level_variance,
                              double& variance, NormalEquations& out) {
    const int valid = counts.any;
    if (!depth_at(level)) {
      if (level_variance == 0.0) {
        double sum = 0.0;
        for (int i = 0; i < count; ++i) sum += static_cast<double>(residual[i] * residual[i]);
        level_variance = std::max(sum / valid, 1.0);
      }
      variance = estimate_variance(count, valid, level_variance);
      level_variance = variance;
      return accumulate(level, count, variance, out) / valid;
    }
    if (sigma_ii == 0.0) {
      double sum_i = 0.0, sum_z = 0.0;
      for (int i = 0; i < count; ++i) {
        sum_i += static_cast<double>(mask[i] * residual[i] * residual[i]);
        sum_z += static_cast<double>(depth_mask[i] * depth_residual[i] * depth_residual[i]);
      }
      sigma_ii = std::max(sum_i / std::max(counts.photometric, 1), 1.0);
      sigma_zz = std::max(sum_z / std::max(counts.depth, 1), 1e-3);
      sigma_iz = 0.0;
    }
    estimate_scale_matrix(count);
    return accumulate_with_depth(level, count, out) / valid;
  }

  // The gyro prior's cost in the data term's units (intensity^2 per point): a step towards the
  // gyro may raise the data cost and still lower the total.
  double prior_cost(int level, const Eigen::Isometry3d& T_cur_ref, const Prediction& p,
                    double variance, int valid) const {
    const Eigen::Vector3d d =
        geometry::log_so3(T_cur_ref.linear().transpose() * p.R_ref_prior.transpose());
    const double scale = depth_at(level) ? sigma_ii : variance;
    return d.dot(p.prior_information * d) * scale / valid;
  }

  // One Gauss-Newton step (twist delta, brightness offset) from the data term and the priors.
  void solve_step(const NormalEquations& normal, const Eigen::Isometry3d& T_cur_ref,
                  const Prediction& p, Vector6d& delta, double& delta_offset) const {
    Matrix6d A = normal.H;
    Vector6d b = normal.g;
    if (config.use_motion_prior && p.predict) {
      // Kerl 2013: a Gaussian prior around the constant-velocity prediction.
      // Scaled to this level's data term: coarse levels have fewer, smaller gradients, and a
      // prior at full finest-level strength would pin them to the prediction.
      const double level_scale = normal.H.trace() / last_information.trace();
      const Matrix6d P = config.motion_prior_precision * level_scale * last_information;
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
    if (config.estimate_brightness_offset) {
      A7.topRightCorner<6, 1>() = normal.H_pose_offset;
      A7.bottomLeftCorner<1, 6>() = normal.H_pose_offset.transpose();
      A7(6, 6) = normal.H_offset;
      b7(6) = normal.g_offset;
    }
    const Vector7d x = detail::solve_remapped(A7, b7, config.degenerate_step_ratio);
    delta = x.head<6>();
    delta_offset = config.estimate_brightness_offset ? x(6) : 0.0;
  }

  // Iteratively re-weighted Gauss-Newton on one pyramid level, continuing from T_cur_ref and
  // brightness_offset; out keeps the last accepted iteration's normal equations and error.
  void solve_level(int level, const FrameSlot& current, const Prediction& p,
                   Eigen::Isometry3d& T_cur_ref, float& brightness_offset, double& variance,
                   Alignment& out) {
    const int count = reference_sets[active_set][level].count;
    double previous_cost = std::numeric_limits<double>::infinity();
    double previous_weighted_error = out.weighted_error;
    Eigen::Isometry3d T_previous = T_cur_ref;
    double level_variance = 0.0;
    sigma_ii = 0.0;
    float offset_previous = brightness_offset;
    // A pixel at level l spans 2^l pixels of level 0: a step that moves the image by a fixed
    // fraction of a pixel is worth less at coarse levels, so they stop sooner.
    const double tolerance = config.step_tolerance * static_cast<double>(1 << (level - finest));
    const int max_iterations =
        p.max_iterations > 0 ? p.max_iterations : config.max_iterations_per_level;
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

  // Coarse-to-fine iteratively re-weighted Gauss-Newton of the current frame against the
  // active reference set, from T_cur_ref.
  Alignment align(const FrameSlot& current, Eigen::Isometry3d T_cur_ref, const Prediction& p) {
    Alignment out;
    for (int level = levels - 1; level >= finest; --level) {
      solve_level(level, current, p, T_cur_ref, out.brightness_offset, out.variance, out);
    }
    out.T_cur_ref = T_cur_ref;
    return out;
  }

  // The vision's own minimum near a joint one: the finest level again, without the priors.
  Alignment vision_only(const FrameSlot& current, const Alignment& joint) {
    Alignment out = joint;
    Prediction p;
    p.stop_on_rising_cost = false;
    p.max_iterations = config.vision_only_iterations;
    solve_level(finest, current, p, out.T_cur_ref, out.brightness_offset, out.variance, out);
    return out;
  }

  // Constant-velocity initial guess (and prior mean) for T_ref_cur, with the gyro's rotation.
  Prediction predict_motion(const GyroSteps* steps) const {
    Prediction p;
    // Frame to frame only: against a keyframe, the part of each step that the optimiser leaves
    // uncorrected is carried into the next prediction, so the predicted velocity random-walks
    // (measured on a simulated circle: RPE 69 m/s with it, 1 mm/s without).
    p.predict = has_motion && config.initialize_with_previous_motion &&
                config.reference_mode == ReferenceMode::kFrameToFrame;
    p.T_ref_predicted = p.predict ? T_ref_last * last_motion : T_ref_last;
    // The gyro's rotation since the reference replaces the predicted one: photometric
    // alignment fails first under fast yaw, where the gyro is at its best.
    p.use_prior = config.use_rotation_prior && steps != nullptr;
    if (p.use_prior) {
      p.R_ref_prior = steps->chain.R_ref_cur;
      p.prior_information = gyro.prior_information(steps->chain_covariance);
      p.step_information = gyro.prior_information(steps->step_covariance);
      p.T_ref_predicted.linear() = p.R_ref_prior;
    }
    return p;
  }

  // Keyframe check, first half: aligns the current frame to the previous one (prepared in set
  // 1). Returns whether that alignment is usable as the keyframe alignment's start and check.
  bool align_to_previous(const FrameSlot& current, const Prediction& to_reference,
                         const GyroSteps* steps, Alignment& to_previous) {
    Prediction p;
    p.use_prior = to_reference.use_prior;
    p.prior_information = to_reference.step_information;
    if (p.use_prior) p.R_ref_prior = steps->R_prev_cur;
    p.T_ref_predicted = has_motion && config.initialize_with_previous_motion
                            ? last_motion
                            : Eigen::Isometry3d::Identity();
    if (p.use_prior) p.T_ref_predicted.linear() = steps->R_prev_cur;
    active_set = kPreviousSet;
    to_previous = align(current, p.T_ref_predicted.inverse(), p);
    active_set = kReferenceSet;
    return to_previous.T_cur_ref.matrix().allFinite() && to_previous.normal.H.allFinite() &&
           to_previous.valid >= 6 &&
           static_cast<double>(to_previous.valid) / finest_pixels() >= config.min_valid_ratio;
  }

  // Keyframe check, second half: T_prev_cur through the keyframe chain against the direct one.
  bool keyframe_chain_broke(const Alignment& a, const Alignment& to_previous) const {
    const bool keyframe_ok =
        a.T_cur_ref.matrix().allFinite() && a.valid >= 6 &&
        static_cast<double>(a.valid) / finest_pixels() >= config.min_valid_ratio;
    const Eigen::Isometry3d chain = T_ref_last.inverse() * a.T_cur_ref.inverse();
    const Eigen::Isometry3d difference = to_previous.T_cur_ref * chain;
    return !keyframe_ok ||
           difference.translation().norm() > config.keyframe_check_max_translation_m ||
           geometry::log_so3(difference.linear()).norm() >
               config.keyframe_check_max_rotation_deg * M_PI / 180.0;
  }

  // The information of the pose twist: with the offset estimated, its Schur complement, times
  // vision_information_scale (the data term's honest share of the independent-pixel one).
  Matrix6d pose_information(const NormalEquations& normal) const {
    return gyro.vision_scale() *
           detail::independent_pixel_information(normal, config.estimate_brightness_offset);
  }

  // What the vision's own minimum near the joint one says against the gyro chain.
  bool observe_gyro(const Alignment& vision_alignment, const Prediction& p, const GyroSteps& steps,
                    GyroObservation& out) const {
    return gyro.observe(vision_alignment.T_cur_ref, vision_alignment.normal, p.R_ref_prior, steps,
                        out);
  }

  // The keyframe chain broke (Kerl IROS 2013 re-anchors on such failures): this frame's pose
  // comes from the previous frame, and this frame becomes the keyframe.
  OdometryResult re_anchor_on_previous(OdometryResult result, const Alignment& a,
                                       const Alignment& to_previous, int current_slot) {
    const NormalEquations& normal = to_previous.normal;
    const Eigen::Isometry3d T_prev_cur = to_previous.T_cur_ref.inverse();
    result.iterations = a.iterations + to_previous.iterations;
    result.valid_ratio = static_cast<double>(to_previous.valid) / finest_pixels();
    result.mean_weighted_error = to_previous.weighted_error;
    result.status = TrackingStatus::kOk;
    result.reason = "";
    result.T_ref_cur = T_prev_cur;
    result.information = pose_information(normal);
    result.T_O_C = T_O_ref * T_ref_last * T_prev_cur;
    last_motion = T_prev_cur;
    last_information = normal.H;
    has_motion = true;
    make_reference(current_slot, result.T_O_C);
    result.new_keyframe = has_reference;
    return result;
  }

  // Whether a frame aligned with these normal equations becomes the next reference: frame to
  // frame always; frame to keyframe when the keyframe has aged, its alignments' entropy has
  // fallen by keyframe_entropy_ratio from the first one's (DVO-SLAM), or the alignment used
  // less of the image than keyframe_min_valid_ratio (a keyframe with little in view, as the
  // floor right after take-off, or one the motion has mostly left).
  bool reference_ends_with(const NormalEquations& normal, int valid) const {
    if (config.reference_mode == ReferenceMode::kFrameToFrame) return true;
    const int age = keyframe_age + 1;
    const double entropy = entropy_of(normal.H);
    const double first = age == 1 ? entropy : keyframe_first_entropy;
    const double ratio = first != 0.0 ? entropy / first : 0.0;
    return age >= config.max_keyframe_age || (age > 1 && ratio < config.keyframe_entropy_ratio) ||
           static_cast<double>(valid) / finest_pixels() < config.keyframe_min_valid_ratio;
  }

  // After a good alignment: the next frame's reference is this frame (frame to frame, or a
  // keyframe that has aged or lost too much information) or stays, with this frame prepared
  // as the previous one for the keyframe check.
  void update_reference(int current_slot, const FrameSlot& current,
                        const Eigen::Isometry3d& T_ref_cur, const Alignment& a,
                        OdometryResult& result) {
    const NormalEquations& normal = a.normal;
    const bool new_reference = reference_ends_with(normal, a.valid);
    if (config.reference_mode == ReferenceMode::kFrameToKeyframe) {
      ++keyframe_age;
      if (keyframe_age == 1) keyframe_first_entropy = entropy_of(normal.H);
    }
    if (new_reference) {
      mark_moving_pixels(current, a);
      make_reference(current_slot, result.T_O_C);
      // The motion of this frame relative to its predecessor stays the prediction.
      result.new_keyframe = has_reference;
      return;
    }
    T_ref_last = T_ref_cur;
    previous_slot = current_slot;
    if (keyframe_check()) {
      prepare_reference(current, kPreviousSet);
      has_previous = true;
    }
  }

  // The outcome of the alignment to the reference: lost if it did not converge on enough
  // pixels (the frame then becomes the reference), else the pose and the next reference.
  OdometryResult accept(OdometryResult result, const Alignment& a, int current_slot,
                        const FrameSlot& current) {
    const Eigen::Isometry3d& T_cur_ref = a.T_cur_ref;
    const NormalEquations& normal = a.normal;
    result.iterations = a.iterations;
    result.valid_ratio = static_cast<double>(a.valid) / finest_pixels();
    result.mean_weighted_error = a.weighted_error;
    const bool converged_numbers =
        T_cur_ref.matrix().allFinite() && normal.H.allFinite() && a.valid >= 6;
    if (!converged_numbers || result.valid_ratio < config.min_valid_ratio) {
      // Keep flying on the newest frame: it becomes the reference if it has depth.
      const Eigen::Isometry3d T_O_C = result.T_O_C;
      OdometryResult out = lost(result, "too few reference pixels visible in the current frame");
      make_reference(current_slot, T_O_C);
      return out;
    }
    if (detail::translation_unconstrained(normal, config)) {
      // A textureless wall seen with the depth term: translation along it is not measured,
      // and a pose from it would read as standing still while the vehicle slides.
      const Eigen::Isometry3d T_O_C = result.T_O_C;
      OdometryResult out = lost(
          result, "degenerate: the scene does not constrain the translation in some direction");
      make_reference(current_slot, T_O_C);
      return out;
    }
    const Eigen::Isometry3d T_ref_cur = T_cur_ref.inverse();
    result.status = TrackingStatus::kOk;
    result.reason = "";
    result.T_ref_cur = T_ref_cur;
    result.information = pose_information(normal);
    result.T_O_C = T_O_ref * T_ref_cur;
    last_motion = T_ref_last.inverse() * T_ref_cur;
    last_information = normal.H;
    has_motion = true;
    update_reference(current_slot, current, T_ref_cur, a, result);
    return result;
  }

  OdometryResult track(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m,
                       const RotationPrior* prior) {
    OdometryResult result;
    result.t_ns = t_ns;
    result.T_O_C = T_O_ref * T_ref_last;
    if (gray.type() != CV_8UC1 || depth_m.type() != CV_32FC1 || gray.cols != camera.width ||
        gray.rows != camera.height || depth_m.size() != gray.size()) {
      return lost(result, "input is not CV_8UC1 gray and CV_32FC1 depth of the camera's size");
    }
    int current_slot = 0;
    while (current_slot == reference_slot || current_slot == previous_slot) ++current_slot;
    FrameSlot& current = slots[current_slot];
    const bool turn_depth = should_align_depth(prior);
    build_pyramid(current, gray, depth_m, turn_depth);
    if (turn_depth) align_depth(current, prior->R_depth_colour);
    const double step_s =
        last_frame_t_ns >= 0 ? 1e-9 * static_cast<double>(t_ns - last_frame_t_ns) : 0.0;
    last_frame_t_ns = t_ns;
    result.gyro_bias_radps = gyro.bias();
    result.vision_information_scale = gyro.vision_scale();

    if (!has_reference) {
      make_reference(current_slot, result.T_O_C);
      result.status = has_reference ? TrackingStatus::kFirstFrame : TrackingStatus::kLost;
      result.reason = has_reference ? "first frame: became the reference"
                                    : "no usable depth: too few pixels with depth and gradient";
      result.new_keyframe = has_reference;
      return result;
    }

    // The gyro, with the bias estimate removed and its uncertainty allowed for, before anything
    // uses it. The chain is kept when this frame is accepted against the same reference.
    gyro.propagate(t_ns);
    GyroSteps steps;
    const bool have_gyro = prior != nullptr && gyro.steps(*prior, step_s, steps);
    const GyroSteps* gyro_steps = have_gyro ? &steps : nullptr;

    const Prediction p = predict_motion(gyro_steps);
    Eigen::Isometry3d T_cur_ref_guess = p.T_ref_predicted.inverse();
    // Keyframe check: align to the previous frame as well, start the keyframe alignment from
    // that, and re-anchor on the previous frame when the two disagree.
    Alignment to_previous;
    const bool previous_ok =
        keyframe_check() && has_previous && align_to_previous(current, p, gyro_steps, to_previous);
    if (previous_ok) T_cur_ref_guess = (T_ref_last * to_previous.T_cur_ref.inverse()).inverse();

    Alignment a = align(current, T_cur_ref_guess, p);
    if (previous_ok && keyframe_chain_broke(a, to_previous)) {
      return re_anchor_on_previous(result, a, to_previous, current_slot);
    }
    if (previous_ok) a.iterations += to_previous.iterations;
    // The vision's own rotation costs a few more iterations: found only for what learns from it.
    const bool learn_bias = config.estimate_gyro_bias &&
                            config.reference_mode == ReferenceMode::kFrameToKeyframe &&
                            reference_ends_with(a.normal, a.valid);
    GyroObservation observation;
    const bool observed = (learn_bias || config.adapt_vision_information) && have_gyro &&
                          p.use_prior &&
                          observe_gyro(vision_only(current, a), p, steps, observation);
    // Before accept(): a new reference starts a new chain.
    gyro.keep_chain(gyro_steps);
    result = accept(result, a, current_slot, current);
    if (observed && result.ok()) gyro.learn(observation, learn_bias);
    result.gyro_bias_radps = gyro.bias();
    result.vision_information_scale = gyro.vision_scale();
    return result;
  }
};

DenseOdometry::DenseOdometry(const OdometryConfig& config, const geometry::PinholeCamera& camera)
    : impl_(std::make_unique<Impl>(config, camera)) {}

DenseOdometry::~DenseOdometry() = default;

OdometryResult DenseOdometry::track(std::int64_t t_ns, const cv::Mat& gray,
                                    const cv::Mat& depth_m) {
  return impl_->track(t_ns, gray, depth_m, nullptr);
}

OdometryResult DenseOdometry::track(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m,
                                    const RotationPrior* prior) {
  return impl_->track(t_ns, gray, depth_m, prior);
}

void DenseOdometry::reset() {
  impl_->has_reference = false;
  impl_->has_motion = false;
  impl_->has_previous = false;
  impl_->T_O_ref.setIdentity();
  impl_->T_ref_last.setIdentity();
  impl_->gyro.reset();
  impl_->last_frame_t_ns = -1;
}

const OdometryConfig& DenseOdometry::config() const { return impl_->config; }

}  // namespace hq::odometry
