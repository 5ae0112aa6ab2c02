#include "reference_points.hpp"

#include "hq/base/target_clones.hpp"

#include "kernels.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

namespace hq::odometry::detail {

namespace {

// The level whose normal map serves `level`: depth_normal_smoothing_levels coarser (block
// means: less noise). Never decreases with the level.
int normal_source(const OdometryConfig& config, const LevelCameras& cameras, int level) {
  return std::min(level + config.depth_normal_smoothing_levels, cameras.levels() - 1);
}

// Unit surface normals of one level's depth (CV_32FC3, zero where unknown): central
// differences of its block means, none beside missing depth or across an edge. Inlined, as
// surface_normal, into each clone of prepare(): the x86-64-v3 one fuses their multiplies and
// adds, and the normals must not depend on whether the compiler chose to inline.
[[gnu::always_inline]] inline void compute_normals(const OdometryConfig& config,
                                                   const geometry::PinholeCamera& cam,
                                                   const cv::Mat& D, cv::Mat& out) {
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
// source level's camera; false where it has none or sees the surface more obliquely than
// depth_max_incidence_deg (the ray-to-plane factor of the Jacobian, 1 / cos, is unbounded).
[[gnu::always_inline]] inline bool surface_normal(const geometry::PinholeCamera& cam,
                                                  const cv::Mat& normal_map,
                                                  float min_cos_incidence,
                                                  const Eigen::Vector3f& p_C,
                                                  Eigen::Vector3f& normal) {
  const double u = cam.fx * static_cast<double>(p_C.x() / p_C.z()) + cam.cx;
  const double v = cam.fy * static_cast<double>(p_C.y() / p_C.z()) + cam.cy;
  const auto iu = static_cast<int>(std::lround(u));
  const auto iv = static_cast<int>(std::lround(v));
  if (iu < 0 || iv < 0 || iu >= cam.width || iv >= cam.height) return false;
  const cv::Vec3f& n = normal_map.at<cv::Vec3f>(iv, iu);
  normal = Eigen::Vector3f(n[0], n[1], n[2]);
  return std::abs(normal.dot(p_C)) >= min_cos_incidence * p_C.norm() && normal.squaredNorm() > 0.5f;
}

}  // namespace

void ReferenceLevel::reserve(int capacity) {
  const auto size = static_cast<std::size_t>(capacity);
  for (auto* v : {&x, &y, &z, &intensity, &photometric, &gradient, &depth_point, &nx, &ny, &nz}) {
    v->assign(size, 0.0f);
  }
  for (auto& j : jacobian) j.assign(size, 0.0f);
  pixel.assign(size, 0);
  count = 0;
}

float min_cos_incidence(const OdometryConfig& config) {
  return static_cast<float>(std::cos(config.depth_max_incidence_deg * M_PI / 180.0));
}

ReferencePreparer::ReferencePreparer(const OdometryConfig& config, const LevelCameras& cameras)
    : config_(config), cameras_(cameras), min_cos_incidence_(min_cos_incidence(config)) {
  if (!config_.depth_jacobian_from_normals) return;
  for (int l = cameras_.finest(); l < cameras_.levels(); ++l) {
    const geometry::PinholeCamera& cam = cameras_.at(l);
    at_level(normal_map_, l).create(cam.height, cam.width, CV_32FC3);
    at_level(normal_map_, l) = cv::Scalar::all(0.0);
  }
}

void ReferencePreparer::reserve(ReferenceSet& set) const {
  for (int l = cameras_.finest(); l < cameras_.levels(); ++l) {
    at_level(set, l).reserve(cameras_.at(l).width * cameras_.at(l).height);
  }
}

HQ_CLONES_X86_64_V3
void ReferencePreparer::prepare(const FrameSlot& slot, const PerLevel<cv::Mat>* moving,
                                ReferenceSet& out) {
  const auto min_gradient_sq = static_cast<float>(config_.min_gradient * config_.min_gradient);
  const auto spread = static_cast<float>(config_.depth_max_spread_ratio);
  const int finest = cameras_.finest();
  const int levels = cameras_.levels();
  if (config_.depth_jacobian_from_normals) {
    int computed = -1;  // normal_source() never decreases with the level
    for (int l = finest; l < levels; ++l) {
      if (!depth_term_at(config_, l) || normal_source(config_, cameras_, l) == computed) continue;
      computed = normal_source(config_, cameras_, l);
      compute_normals(config_, cameras_.at(computed), at_level(slot.depth_m, computed),
                      at_level(normal_map_, computed));
    }
  }
  for (int l = finest; l < levels; ++l) {
    // With the depth term, pixels without gradient still constrain the pose through their
    // depth (a textureless wall fixes its normal's translation and two rotations).
    const bool depth_level = depth_term_at(config_, l);
    const int stride = depth_level ? std::max(1, config_.depth_point_stride) : 0;
    const geometry::PinholeCamera& cam = cameras_.at(l);
    const Intrinsics k = cameras_.intrinsics(l);
    const cv::Mat& I = at_level(slot.intensity, l);
    const cv::Mat& D = at_level(slot.depth_m, l);
    ReferenceLevel& ref = at_level(out, l);
    const bool skip_moving = moving != nullptr;
    const int source = normal_source(config_, cameras_, l);
    int n = 0;
    for (int v = 1; v < cam.height - 1; ++v) {
      const float* row = I.ptr<float>(v);
      const float* up = I.ptr<float>(v - 1);
      const float* down = I.ptr<float>(v + 1);
      const float* depth = D.ptr<float>(v);
      const std::uint8_t* moved = skip_moving ? at_level(*moving, l).ptr<std::uint8_t>(v) : nullptr;
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
        const Eigen::Vector3f p_C = cam.unproject(static_cast<float>(u), static_cast<float>(v), z);
        Eigen::Vector3f normal = Eigen::Vector3f::Zero();
        if (surface && config_.depth_jacobian_from_normals) {
          surface = surface_normal(cameras_.at(source), at_level(normal_map_, source),
                                   min_cos_incidence_, p_C, normal);
        }
        if (!textured && !surface) continue;
        const float x = p_C.x();
        const float y = p_C.y();
        float J[6];
        photometric_jacobian(x, y, z, gx, gy, k, J);
        const auto i = static_cast<std::size_t>(n);
        ref.x[i] = x;
        ref.y[i] = y;
        ref.z[i] = z;
        ref.intensity[i] = row[u];
        ref.photometric[i] = textured ? 1.0f : 0.0f;
        ref.gradient[i] = std::sqrt(gx * gx + gy * gy);
        ref.depth_point[i] = surface ? 1.0f : 0.0f;
        ref.nx[i] = normal.x();
        ref.ny[i] = normal.y();
        ref.nz[i] = normal.z();
        for (std::size_t j = 0; j < 6; ++j) ref.jacobian[j][i] = textured ? J[j] : 0.0f;
        ref.pixel[i] = v * cam.width + u;
        ++n;
      }
    }
    ref.count = n;
  }
}

}  // namespace hq::odometry::detail
