#include "foxglove_frames.hpp"

#include "hq/geometry/ros_frames.hpp"

namespace hq::flight_log {

RigidTransform odom_T_base_link(const Eigen::Vector3d& p_m, double yaw_rad, double roll_rad,
                                double pitch_rad) {
  return {geometry::enu_from_ned(p_m), geometry::q_E_F(roll_rad, pitch_rad, yaw_rad)};
}

RigidTransform odom_T_base_link(const link::VehicleState& s) {
  const bool known = s.odom_valid;
  const Eigen::Vector3d p_odom_m =
      known ? Eigen::Vector3d(s.p_odom_m.x, s.p_odom_m.y, s.p_odom_m.z) : Eigen::Vector3d::Zero();
  return odom_T_base_link(p_odom_m, known ? static_cast<double>(s.yaw_odom_rad) : 0.0, s.roll_rad,
                          s.pitch_rad);
}

RigidTransform rigid(const Eigen::Isometry3d& T) {
  return {T.translation(), Eigen::Quaterniond(T.linear()).normalized()};
}

void frame_transform_json(Json& j, std::int64_t stamp_ns, const char* parent, const char* child,
                          const RigidTransform& T) {
  j.clear();
  j.raw("{\"timestamp\":");
  j.stamp(stamp_ns);
  j.raw(",\"parent_frame_id\":");
  j.string(parent);
  j.raw(",\"child_frame_id\":");
  j.string(child);
  j.raw(",\"translation\":");
  j.vector3(T.translation);
  j.raw(",\"rotation\":{\"x\":");
  j.number(T.rotation.x());
  j.raw(",\"y\":");
  j.number(T.rotation.y());
  j.raw(",\"z\":");
  j.number(T.rotation.z());
  j.raw(",\"w\":");
  j.number(T.rotation.w());
  j.raw("}}");
}

void camera_calibration_json(Json& j, std::int64_t stamp_ns, const char* frame_id,
                             const geometry::PinholeCamera& camera, int width_px, int height_px) {
  // Pixel centres at integer coordinates: c' = (c + 0.5) s - 0.5, as PinholeCamera::at_level.
  const double sx = camera.width > 0 ? static_cast<double>(width_px) / camera.width : 1.0;
  const double sy = camera.height > 0 ? static_cast<double>(height_px) / camera.height : 1.0;
  const double fx = camera.fx * sx;
  const double fy = camera.fy * sy;
  const double cx = (camera.cx + 0.5) * sx - 0.5;
  const double cy = (camera.cy + 0.5) * sy - 0.5;
  const double k[9] = {fx, 0, cx, 0, fy, cy, 0, 0, 1};
  const double r[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const double p[12] = {fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0};
  const auto array = [&](const double* v, int n) {
    j.raw("[");
    for (int i = 0; i < n; ++i) {
      if (i > 0) j.raw(",");
      j.number(v[i]);
    }
    j.raw("]");
  };
  j.clear();
  j.raw("{\"timestamp\":");
  j.stamp(stamp_ns);
  j.raw(",\"frame_id\":");
  j.string(frame_id);
  j.raw(",\"width\":");
  j.integer(width_px);
  j.raw(",\"height\":");
  j.integer(height_px);
  j.raw(",\"distortion_model\":\"plumb_bob\",\"D\":[0,0,0,0,0],\"K\":");
  array(k, 9);
  j.raw(",\"R\":");
  array(r, 9);
  j.raw(",\"P\":");
  array(p, 12);
  j.raw("}");
}

}  // namespace hq::flight_log
