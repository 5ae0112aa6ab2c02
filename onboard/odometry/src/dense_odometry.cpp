#include "hq/odometry/dense_odometry.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Cholesky>

#include "hq/config/strict_yaml.hpp"
#include "hq/geometry/lie.hpp"
#include "pyramid.hpp"

namespace hq::odometry {

namespace {

constexpr int kMaxLevels = 6;
// Blocks whose depths spread by more than this fraction are treated as occlusion edges.
constexpr float kDepthEdgeSpreadRatio = 0.05f;
// Points accumulate in float within a block, then into double: float alone loses digits over
// 10^5 pixels, double everywhere halves the throughput of the inner loop.
constexpr int kAccumulationBlock = 256;
constexpr int kScaleIterations = 5;

using Vector6d = geometry::Vector6d;

// One prepared pyramid level of the reference frame, structure of arrays so that the warp and
// accumulation loops stream through memory.
struct ReferenceLevel {
  std::vector<float> x, y, z;    // 3D point in the reference camera frame, metres
  std::vector<float> intensity;  // I_ref at the pixel
  std::array<std::vector<float>, 6> jacobian;  // d I_ref(pi(exp(xi) p)) / d xi at xi = 0
  int count = 0;

  void reserve(int capacity) {
    for (auto* v : {&x, &y, &z, &intensity}) v->assign(capacity, 0.0f);
    for (auto& j : jacobian) j.assign(capacity, 0.0f);
    count = 0;
  }
};

struct FrameSlot {
  std::array<cv::Mat, kMaxLevels> intensity;  // CV_32FC1; level 0 unused if finest_level > 0
  std::array<cv::Mat, kMaxLevels> depth_m;    // CV_32FC1, 0 = no depth
};

// Normal equations of the pose twist and the brightness offset b (a seventh parameter with
// Jacobian 1), kept in blocks so that the pose-only system needs no copy.
struct NormalEquations {
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  Vector6d g = Vector6d::Zero();
  Vector6d H_pose_offset = Vector6d::Zero();
  double H_offset = 0.0;
  double g_offset = 0.0;
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

const char* to_string(TrackingStatus status) {
  switch (status) {
    case TrackingStatus::kFirstFrame:
      return "first_frame";
    case TrackingStatus::kOk:
      return "ok";
    case TrackingStatus::kLost:
      return "lost";
  }
  return "unknown";
}

void read_config(config::StrictMap& section, OdometryConfig& out) {
  section.read("pyramid_levels", out.pyramid_levels, 1, kMaxLevels);
  section.read("finest_level", out.finest_level, 0, kMaxLevels - 1);
  if (out.finest_level >= out.pyramid_levels) {
    throw InputError(section.describe("finest_level") + " = " + std::to_string(out.finest_level) +
                     ", expected < pyramid_levels (" + std::to_string(out.pyramid_levels) + ")");
  }
  section.read("max_iterations_per_level", out.max_iterations_per_level, 1, 200);
  section.read_positive("step_tolerance", out.step_tolerance, 1.0);
  section.read_positive("min_depth_m", out.min_depth_m, 100.0);
  section.read_positive("max_depth_m", out.max_depth_m, 1000.0);
  if (out.max_depth_m <= out.min_depth_m) {
    throw InputError(section.describe("max_depth_m") + ", expected > min_depth_m");
  }
  section.read("min_gradient", out.min_gradient, 0.0, 255.0);
  section.read_positive("student_t_dof", out.student_t_dof, 1000.0);
  section.read("min_valid_ratio", out.min_valid_ratio, 0.0, 1.0);
  section.read("use_motion_prior", out.use_motion_prior);
  section.read("motion_prior_precision", out.motion_prior_precision, 0.0, 1e6);
  section.read("initialize_with_previous_motion", out.initialize_with_previous_motion);
  section.read("estimate_brightness_offset", out.estimate_brightness_offset);
  std::string mode = out.reference_mode == ReferenceMode::kFrameToFrame ? "frame_to_frame"
                                                                         : "frame_to_keyframe";
  section.read("reference_mode", mode, {"frame_to_frame", "frame_to_keyframe"});
  out.reference_mode =
      mode == "frame_to_frame" ? ReferenceMode::kFrameToFrame : ReferenceMode::kFrameToKeyframe;
  section.read("keyframe_entropy_ratio", out.keyframe_entropy_ratio, 0.0, 1.0);
  section.read("max_keyframe_age", out.max_keyframe_age, 1, 100000);
  section.finish();
}

struct DenseOdometry::Impl {
  OdometryConfig config;
  geometry::PinholeCamera camera;
  std::array<geometry::PinholeCamera, kMaxLevels> level_camera;
  int levels = 0;
  int finest = 0;

  std::array<FrameSlot, 2> slots;
  int reference_slot = 0;
  std::array<ReferenceLevel, kMaxLevels> reference;
  bool has_reference = false;

  // Per-point work buffers, sized for the finest optimised level.
  std::vector<float> residual;
  std::vector<float> weight;

  Eigen::Isometry3d T_world_reference = Eigen::Isometry3d::Identity();
  // Last accepted estimate of the current frame in the reference (constant-velocity guess).
  Eigen::Isometry3d T_ref_last = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d last_motion = Eigen::Isometry3d::Identity();  // T_prev_cur of last frame
  Matrix6d last_information = Matrix6d::Zero();
  bool has_motion = false;
  double keyframe_first_entropy = 0.0;
  int keyframe_age = 0;

  Impl(const OdometryConfig& c, const geometry::PinholeCamera& cam) : config(c), camera(cam) {
    levels = std::clamp(config.pyramid_levels, 1, kMaxLevels);
    finest = std::clamp(config.finest_level, 0, levels - 1);
    int capacity = 0;
    for (int l = 0; l < levels; ++l) {
      level_camera[l] = camera.at_level(l);
      const int w = level_camera[l].width;
      const int h = level_camera[l].height;
      for (auto& slot : slots) {
        slot.intensity[l].create(h, w, CV_32FC1);
        slot.depth_m[l].create(h, w, CV_32FC1);
      }
      if (l >= finest) {
        reference[l].reserve(w * h);
        capacity = std::max(capacity, w * h);
      }
    }
    residual.assign(capacity, 0.0f);
    weight.assign(capacity, 0.0f);
  }

  void build_pyramid(FrameSlot& slot, const cv::Mat& gray, const cv::Mat& depth_m) {
    const auto min_depth = static_cast<float>(config.min_depth_m);
    const auto max_depth = static_cast<float>(config.max_depth_m);
    detail::sanitize_depth(depth_m, slot.depth_m[0], min_depth, max_depth);
    if (finest == 0) gray.convertTo(slot.intensity[0], CV_32F);
    for (int l = 1; l < levels; ++l) {
      // Level 1 straight from the 8-bit input: one pass instead of convert-then-average.
      const cv::Mat& src = (l == 1) ? gray : slot.intensity[l - 1];
      detail::downsample_intensity(src, slot.intensity[l]);
      detail::downsample_depth(slot.depth_m[l - 1], slot.depth_m[l], kDepthEdgeSpreadRatio);
    }
  }

  // Selects pixels with depth and gradient, and precomputes their points and Jacobians: done
  // once per reference, not per iteration (the inverse compositional trick).
  void prepare_reference(const FrameSlot& slot) {
    const auto min_gradient_sq = static_cast<float>(config.min_gradient * config.min_gradient);
    for (int l = finest; l < levels; ++l) {
      const geometry::PinholeCamera& cam = level_camera[l];
      const auto fx = static_cast<float>(cam.fx);
      const auto fy = static_cast<float>(cam.fy);
      const auto cx = static_cast<float>(cam.cx);
      const auto cy = static_cast<float>(cam.cy);
      const cv::Mat& I = slot.intensity[l];
      const cv::Mat& D = slot.depth_m[l];
      ReferenceLevel& ref = reference[l];
      int n = 0;
      for (int v = 1; v < cam.height - 1; ++v) {
        const float* row = I.ptr<float>(v);
        const float* up = I.ptr<float>(v - 1);
        const float* down = I.ptr<float>(v + 1);
        const float* depth = D.ptr<float>(v);
        for (int u = 1; u < cam.width - 1; ++u) {
          const float z = depth[u];
          if (z <= 0.0f) continue;
          const float gx = 0.5f * (row[u + 1] - row[u - 1]);
          const float gy = 0.5f * (down[u] - up[u]);
          if (gx * gx + gy * gy < min_gradient_sq) continue;
          const float x = (static_cast<float>(u) - cx) * z / fx;
          const float y = (static_cast<float>(v) - cy) * z / fy;
          // d I / d p = grad I * d pi / d p; then d p / d xi = [I, -[p]x] so the rotational
          // part is p x (d I / d p).
          const float inv_z = 1.0f / z;
          const float a = gx * fx * inv_z;
          const float b = gy * fy * inv_z;
          const float c = -(a * x + b * y) * inv_z;
          ref.x[n] = x;
          ref.y[n] = y;
          ref.z[n] = z;
          ref.intensity[n] = row[u];
          ref.jacobian[0][n] = a;
          ref.jacobian[1][n] = b;
          ref.jacobian[2][n] = c;
          ref.jacobian[3][n] = y * c - z * b;
          ref.jacobian[4][n] = z * a - x * c;
          ref.jacobian[5][n] = x * b - y * a;
          ++n;
        }
      }
      ref.count = n;
    }
  }

  // Warps every reference point with T_cur_ref, samples the current image, stores residuals;
  // points that leave the image get weight 0. Returns how many stayed valid.
  int compute_residuals(int level, const cv::Mat& current, const Eigen::Isometry3d& T_cur_ref,
                        float brightness_offset) {
    const geometry::PinholeCamera& cam = level_camera[level];
    const ReferenceLevel& ref = reference[level];
    const Eigen::Matrix3f R = T_cur_ref.linear().cast<float>();
    const Eigen::Vector3f t = T_cur_ref.translation().cast<float>();
    const auto fx = static_cast<float>(cam.fx);
    const auto fy = static_cast<float>(cam.fy);
    const auto cx = static_cast<float>(cam.cx);
    const auto cy = static_cast<float>(cam.cy);
    const auto max_u = static_cast<float>(cam.width - 1) - 1e-3f;
    const auto max_v = static_cast<float>(cam.height - 1) - 1e-3f;
    const auto min_z = static_cast<float>(config.min_depth_m) * 0.5f;
    const auto* data = reinterpret_cast<const float*>(current.data);
    const auto stride = static_cast<int>(current.step1());
    int valid = 0;
    for (int i = 0; i < ref.count; ++i) {
      const float px = ref.x[i];
      const float py = ref.y[i];
      const float pz = ref.z[i];
      const float qx = R(0, 0) * px + R(0, 1) * py + R(0, 2) * pz + t.x();
      const float qy = R(1, 0) * px + R(1, 1) * py + R(1, 2) * pz + t.y();
      const float qz = R(2, 0) * px + R(2, 1) * py + R(2, 2) * pz + t.z();
      float r = 0.0f;
      float w = 0.0f;
      if (qz > min_z) {
        const float inv_z = 1.0f / qz;
        const float u = fx * qx * inv_z + cx;
        const float v = fy * qy * inv_z + cy;
        if (u >= 0.0f && v >= 0.0f && u < max_u && v < max_v) {
          const int u0 = static_cast<int>(u);
          const int v0 = static_cast<int>(v);
          const float du = u - static_cast<float>(u0);
          const float dv = v - static_cast<float>(v0);
          const float* p = data + v0 * stride + u0;
          const float top = p[0] + du * (p[1] - p[0]);
          const float bottom = p[stride] + du * (p[stride + 1] - p[stride]);
          r = top + dv * (bottom - top) - ref.intensity[i] - brightness_offset;
          w = 1.0f;
          ++valid;
        }
      }
      residual[i] = r;
      weight[i] = w;  // 1 marks valid; replaced by the robust weight below
    }
    return valid;
  }

  // Student-t scale by fixed-point iteration (Kerl 2013, eq. 12). weight[] holds 1 for points
  // that landed in the image and 0 for the others.
  double estimate_variance(int count, int valid, double initial_variance) const {
    const auto nu = static_cast<float>(config.student_t_dof);
    const float* r = residual.data();
    const float* mask = weight.data();
    float variance = static_cast<float>(initial_variance);
    for (int it = 0; it < kScaleIterations; ++it) {
      const float inv_var = 1.0f / variance;
      float sum = 0.0f;
#pragma omp simd reduction(+ : sum)
      for (int i = 0; i < count; ++i) {
        const float r2 = r[i] * r[i];
        sum += mask[i] * r2 * (nu + 1.0f) / (nu + r2 * inv_var);
      }
      const float next = std::max(sum / static_cast<float>(valid), 1e-6f);
      const bool converged = std::abs(next - variance) < 1e-3f * variance;
      variance = next;
      if (converged) break;
    }
    return variance;
  }

  // One pass: Student-t weights, H = sum w J J^T / sigma^2, g = sum w J r / sigma^2 and the
  // mean weighted squared error. 27 independent sums let the compiler vectorise across points.
  double accumulate(int level, int count, double variance, NormalEquations& out) const {
    const ReferenceLevel& ref = reference[level];
    const float* j0 = ref.jacobian[0].data();
    const float* j1 = ref.jacobian[1].data();
    const float* j2 = ref.jacobian[2].data();
    const float* j3 = ref.jacobian[3].data();
    const float* j4 = ref.jacobian[4].data();
    const float* j5 = ref.jacobian[5].data();
    const float* res = residual.data();
    const float* mask = weight.data();
    const auto nu = static_cast<float>(config.student_t_dof);
    const auto inv_var = static_cast<float>(1.0 / variance);
    double H[21] = {};
    double g[6] = {};
    double weighted_error = 0.0;
    double pose_offset[6] = {};
    double offset = 0.0;
    double g_offset = 0.0;
    for (int start = 0; start < count; start += kAccumulationBlock) {
      const int end = std::min(count, start + kAccumulationBlock);
      float h00 = 0, h01 = 0, h02 = 0, h03 = 0, h04 = 0, h05 = 0, h11 = 0, h12 = 0, h13 = 0,
            h14 = 0, h15 = 0, h22 = 0, h23 = 0, h24 = 0, h25 = 0, h33 = 0, h34 = 0, h35 = 0,
            h44 = 0, h45 = 0, h55 = 0, g0 = 0, g1 = 0, g2 = 0, g3 = 0, g4 = 0, g5 = 0, e = 0,
            o0 = 0, o1 = 0, o2 = 0, o3 = 0, o4 = 0, o5 = 0, oo = 0, go = 0;
#pragma omp simd reduction(+ : h00, h01, h02, h03, h04, h05, h11, h12, h13, h14, h15, h22, h23, \
                               h24, h25, h33, h34, h35, h44, h45, h55, g0, g1, g2, g3, g4, g5, e, \
                               o0, o1, o2, o3, o4, o5, oo, go)
      for (int i = start; i < end; ++i) {
        const float r = res[i];
        const float w = mask[i] * (nu + 1.0f) / (nu + r * r * inv_var);
        const float a0 = j0[i], a1 = j1[i], a2 = j2[i], a3 = j3[i], a4 = j4[i], a5 = j5[i];
        const float w0 = w * a0, w1 = w * a1, w2 = w * a2, w3 = w * a3, w4 = w * a4, w5 = w * a5;
        h00 += w0 * a0; h01 += w0 * a1; h02 += w0 * a2; h03 += w0 * a3; h04 += w0 * a4;
        h05 += w0 * a5; h11 += w1 * a1; h12 += w1 * a2; h13 += w1 * a3; h14 += w1 * a4;
        h15 += w1 * a5; h22 += w2 * a2; h23 += w2 * a3; h24 += w2 * a4; h25 += w2 * a5;
        h33 += w3 * a3; h34 += w3 * a4; h35 += w3 * a5; h44 += w4 * a4; h45 += w4 * a5;
        h55 += w5 * a5;
        g0 += w0 * r; g1 += w1 * r; g2 += w2 * r; g3 += w3 * r; g4 += w4 * r; g5 += w5 * r;
        e += w * r * r;
        o0 += w0; o1 += w1; o2 += w2; o3 += w3; o4 += w4; o5 += w5; oo += w; go += w * r;
      }
      const float block[21] = {h00, h01, h02, h03, h04, h05, h11, h12, h13, h14, h15,
                               h22, h23, h24, h25, h33, h34, h35, h44, h45, h55};
      for (int k = 0; k < 21; ++k) H[k] += block[k];
      g[0] += g0; g[1] += g1; g[2] += g2; g[3] += g3; g[4] += g4; g[5] += g5;
      weighted_error += e;
      const float offset_block[6] = {o0, o1, o2, o3, o4, o5};
      for (int k = 0; k < 6; ++k) pose_offset[k] += offset_block[k];
      offset += oo;
      g_offset += go;
    }
    int k = 0;
    for (int r = 0; r < 6; ++r) {
      for (int c = r; c < 6; ++c) {
        out.H(r, c) = H[k] / variance;
        out.H(c, r) = out.H(r, c);
        ++k;
      }
      out.g(r) = g[r] / variance;
      out.H_pose_offset(r) = pose_offset[r] / variance;
    }
    out.H_offset = offset / variance;
    out.g_offset = g_offset / variance;
    return weighted_error;
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
    return reference[finest].count >= std::max(6, static_cast<int>(config.min_valid_ratio * pixels));
  }

  void make_reference(int slot_index, const Eigen::Isometry3d& T_world_cur) {
    reference_slot = slot_index;
    prepare_reference(slots[slot_index]);
    has_reference = reference_usable();
    T_world_reference = T_world_cur;
    T_ref_last.setIdentity();
    keyframe_age = 0;
    keyframe_first_entropy = 0.0;
  }

  OdometryResult track(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m) {
    OdometryResult result;
    result.t_ns = t_ns;
    result.T_world_cur = T_world_reference * T_ref_last;
    if (gray.type() != CV_8UC1 || depth_m.type() != CV_32FC1 || gray.cols != camera.width ||
        gray.rows != camera.height || depth_m.size() != gray.size()) {
      return lost(result, "input is not CV_8UC1 gray and CV_32FC1 depth of the camera's size");
    }
    const int current_slot = 1 - reference_slot;
    FrameSlot& current = slots[current_slot];
    build_pyramid(current, gray, depth_m);

    if (!has_reference) {
      make_reference(current_slot, result.T_world_cur);
      result.status = has_reference ? TrackingStatus::kFirstFrame : TrackingStatus::kLost;
      result.reason = has_reference ? "first frame: became the reference"
                                    : "no usable depth: too few pixels with depth and gradient";
      result.new_keyframe = has_reference;
      return result;
    }

    // Constant-velocity initial guess (and prior mean) for T_ref_cur.
    // Frame to frame only: against a keyframe, the part of each step that the optimiser leaves
    // uncorrected is carried into the next prediction, so the predicted velocity random-walks
    // (measured on a simulated circle: RPE 69 m/s with it, 1 mm/s without).
    const bool predict = has_motion && config.initialize_with_previous_motion &&
                         config.reference_mode == ReferenceMode::kFrameToFrame;
    const Eigen::Isometry3d T_ref_predicted = predict ? T_ref_last * last_motion : T_ref_last;
    Eigen::Isometry3d T_cur_ref = T_ref_predicted.inverse();

    NormalEquations normal;
    float brightness_offset = 0.0f;
    double variance = 0.0;
    int valid = 0;
    int iterations = 0;
    double weighted_error = 0.0;
    for (int level = levels - 1; level >= finest; --level) {
      const int count = reference[level].count;
      double previous_error = std::numeric_limits<double>::infinity();
      Eigen::Isometry3d T_previous = T_cur_ref;
      double level_variance = 0.0;
      float offset_previous = brightness_offset;
      // A pixel at level l spans 2^l pixels of level 0: a step that moves the image by a fixed
      // fraction of a pixel is worth less at coarse levels, so they stop sooner.
      const double tolerance = config.step_tolerance * static_cast<double>(1 << (level - finest));
      for (int it = 0; it < config.max_iterations_per_level; ++it) {
        valid = compute_residuals(level, current.intensity[level], T_cur_ref, brightness_offset);
        if (valid < 6) break;
        if (level_variance == 0.0) {
          double sum = 0.0;
          for (int i = 0; i < count; ++i) sum += residual[i] * residual[i];
          level_variance = std::max(sum / valid, 1.0);
        }
        variance = estimate_variance(count, valid, level_variance);
        level_variance = variance;
        NormalEquations candidate;
        weighted_error = accumulate(level, count, variance, candidate) / valid;
        ++iterations;
        if (weighted_error > previous_error) {
          // The last step made the fit worse: undo it and stop refining this level.
          T_cur_ref = T_previous;
          brightness_offset = offset_previous;
          weighted_error = previous_error;
          break;
        }
        previous_error = weighted_error;
        normal = candidate;
        Matrix6d A = normal.H;
        Vector6d b = normal.g;
        if (config.use_motion_prior && predict) {
          // Kerl 2013: a Gaussian prior around the constant-velocity prediction.
          // Scaled to this level's data term: coarse levels have fewer, smaller gradients, and a
          // prior at full finest-level strength would pin them to the prediction.
          const double level_scale = normal.H.trace() / last_information.trace();
          const Matrix6d P = config.motion_prior_precision * level_scale * last_information;
          // T_ref_cur moves as exp(delta) T_ref_cur, so its deviation from the prediction is
          // delta + d with d = log(T_ref_cur T_ref_predicted^-1).
          const Vector6d d = geometry::log_se3(T_cur_ref.inverse() * T_ref_predicted.inverse());
          A += P;
          b -= P * d;
        }
        Vector6d delta;
        double delta_offset = 0.0;
        if (config.estimate_brightness_offset) {
          // Auto-exposure shifts every intensity alike; an offset absorbs it instead of the
          // pose (Engel et al. use an affine model for the same reason).
          Eigen::Matrix<double, 7, 7> A7;
          A7.topLeftCorner<6, 6>() = A;
          A7.topRightCorner<6, 1>() = normal.H_pose_offset;
          A7.bottomLeftCorner<1, 6>() = normal.H_pose_offset.transpose();
          A7(6, 6) = normal.H_offset;
          Eigen::Matrix<double, 7, 1> b7;
          b7.head<6>() = b;
          b7(6) = normal.g_offset;
          const Eigen::Matrix<double, 7, 1> x = A7.ldlt().solve(b7);
          delta = x.head<6>();
          delta_offset = x(6);
        } else {
          delta = A.ldlt().solve(b);
        }
        if (!delta.allFinite() || !std::isfinite(delta_offset)) break;
        T_previous = T_cur_ref;
        offset_previous = brightness_offset;
        brightness_offset += static_cast<float>(delta_offset);
        T_cur_ref = T_cur_ref * geometry::exp_se3(-delta);
        if (delta.squaredNorm() < tolerance * tolerance) break;
      }
    }

    result.iterations = iterations;
    const int finest_pixels = level_camera[finest].width * level_camera[finest].height;
    result.valid_ratio = static_cast<double>(valid) / finest_pixels;
    result.mean_weighted_error = weighted_error;
    const bool converged_numbers =
        T_cur_ref.matrix().allFinite() && normal.H.allFinite() && valid >= 6;
    if (!converged_numbers || result.valid_ratio < config.min_valid_ratio) {
      // Keep flying on the newest frame: it becomes the reference if it has depth.
      const Eigen::Isometry3d T_world_cur = result.T_world_cur;
      OdometryResult out = lost(result, "too few reference pixels visible in the current frame");
      make_reference(current_slot, T_world_cur);
      return out;
    }

    const Eigen::Isometry3d T_ref_cur = T_cur_ref.inverse();
    result.status = TrackingStatus::kOk;
    result.reason = "";
    result.T_ref_cur = T_ref_cur;
    // With the offset estimated, the pose information is its Schur complement.
    result.information = normal.H;
    if (config.estimate_brightness_offset && normal.H_offset > 0.0) {
      result.information -= normal.H_pose_offset * normal.H_pose_offset.transpose() /
                            normal.H_offset;
    }
    result.T_world_cur = T_world_reference * T_ref_cur;

    last_motion = T_ref_last.inverse() * T_ref_cur;
    last_information = normal.H;
    has_motion = true;

    bool new_reference = true;
    if (config.reference_mode == ReferenceMode::kFrameToKeyframe) {
      ++keyframe_age;
      const double entropy = entropy_of(normal.H);
      if (keyframe_age == 1) keyframe_first_entropy = entropy;
      const double ratio = keyframe_first_entropy != 0.0 ? entropy / keyframe_first_entropy : 0.0;
      new_reference = keyframe_age >= config.max_keyframe_age ||
                      (keyframe_age > 1 && ratio < config.keyframe_entropy_ratio);
    }
    if (new_reference) {
      make_reference(current_slot, result.T_world_cur);
      // The motion of this frame relative to its predecessor stays the prediction.
      result.new_keyframe = has_reference;
    } else {
      T_ref_last = T_ref_cur;
    }
    return result;
  }
};

DenseOdometry::DenseOdometry(const OdometryConfig& config, const geometry::PinholeCamera& camera)
    : impl_(std::make_unique<Impl>(config, camera)) {}

DenseOdometry::~DenseOdometry() = default;

OdometryResult DenseOdometry::track(std::int64_t t_ns, const cv::Mat& gray,
                                    const cv::Mat& depth_m) {
  return impl_->track(t_ns, gray, depth_m);
}

void DenseOdometry::reset() {
  impl_->has_reference = false;
  impl_->has_motion = false;
  impl_->T_world_reference.setIdentity();
  impl_->T_ref_last.setIdentity();
}

const OdometryConfig& DenseOdometry::config() const { return impl_->config; }

}  // namespace hq::odometry
