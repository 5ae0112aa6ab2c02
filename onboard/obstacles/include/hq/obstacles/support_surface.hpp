#pragma once
/// Support surfaces (a floor, a table top): a depth surface whose normal is near vertical in H.
/// Horizontal motion cannot hit one, so the obstacle field pushes only upwards from it and the
/// obstacle memory does not remember it. One copy of the normal estimate both use, on float
/// (memory) or double (field) points. Frames: C camera (optical), H horizontal (hq/geometry/
/// frames.hpp). Header-only and allocation-free: it runs per depth sample.

#include <Eigen/Core>

#include <cmath>

namespace hq::obstacles {

/// Which neighbours a sample's surface normal is differenced from.
enum class NormalStencil {
  /// p(+step) - p(-step) where both sides have depth, else the one side that has (a depth
  /// minimum often sits where depth ends: at the sensor's minimum range or an occluding edge).
  kCentralWhereBoth,
  /// The +step side if it has depth, else the -step side; never both (cheaper, per sample).
  kOneSided,
};

/// The normal n_C (unnormalised) of the depth surface at pixel (u, v), seen at p_C, from the
/// samples step_px away along u and v. point_at(pu, pv, p) (pu, pv inside the width x height
/// image) sets p to the point seen there and returns false where there is no usable depth.
/// Returns false if a direction has no neighbour with depth or the normal is degenerate.
template <typename Scalar, typename PointAt>
bool surface_normal_C(PointAt&& point_at, int u, int v, int width, int height, int step_px,
                      NormalStencil stencil, const Eigen::Matrix<Scalar, 3, 1>& p_C,
                      Eigen::Matrix<Scalar, 3, 1>& n_C) {
  using Vec3 = Eigen::Matrix<Scalar, 3, 1>;
  const auto difference = [&](int du, int dv, Vec3& d) {
    Vec3 plus, minus;
    const int u_plus = u + du, v_plus = v + dv, u_minus = u - du, v_minus = v - dv;
    const bool has_plus = u_plus < width && v_plus < height && point_at(u_plus, v_plus, plus);
    if (stencil == NormalStencil::kOneSided && has_plus) {
      d = plus - p_C;
      return true;
    }
    const bool has_minus = u_minus >= 0 && v_minus >= 0 && point_at(u_minus, v_minus, minus);
    if (has_plus && has_minus) {
      d = plus - minus;
    } else if (has_plus) {
      d = plus - p_C;
    } else if (has_minus) {
      d = p_C - minus;
    } else {
      return false;
    }
    return true;
  };
  Vec3 along_u, along_v;
  if (!difference(step_px, 0, along_u) || !difference(0, step_px, along_v)) return false;
  n_C = along_u.cross(along_v);
  return n_C.squaredNorm() > Scalar(0);
}

/// Whether a normal n_C (any length > 0) lies within the angle whose cosine is cos_max_tilt of
/// the vertical of H.
template <typename Scalar>
bool is_support_normal(const Eigen::Matrix<Scalar, 3, 3>& R_H_C,
                       const Eigen::Matrix<Scalar, 3, 1>& n_C, Scalar cos_max_tilt) {
  return std::abs((R_H_C * n_C).z()) > cos_max_tilt * n_C.norm();
}

}  // namespace hq::obstacles
