#include "hq/vehicle_config/vehicle_config.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/geometry/camera_mount.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <sstream>

namespace hq {
namespace {
void require_deg_as_rad(config::StrictMap& map, const std::string& key, double& value_rad,
                        double min_deg, double max_deg) {
  if (!map.has(key)) throw InputError(map.describe(key) + " is missing");
  map.read_deg_as_rad(key, value_rad, min_deg, max_deg);
}
void require_positive(config::StrictMap& map, const std::string& key, double& value, double max) {
  if (!map.has(key)) throw InputError(map.describe(key) + " is missing");
  map.read_positive(key, value, max);
}
}  // namespace

Eigen::Matrix3d R_B_C_from_angles(double yaw_rad, double pitch_rad, double roll_rad) {
  Eigen::Matrix3d R_forward_optical;
  // Columns: optical x = body right (e_y), optical y = body down (e_z), optical z = forward (e_x).
  R_forward_optical << 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0;
  return (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
             .toRotationMatrix() *
         R_forward_optical;
}

geometry::CameraMount camera_mount_from_angles(double yaw_rad, double pitch_rad, double roll_rad,
                                               const Eigen::Vector3d& p_B_C_m) {
  Eigen::Isometry3d T_B_C = Eigen::Isometry3d::Identity();
  T_B_C.linear() = R_B_C_from_angles(yaw_rad, pitch_rad, roll_rad);
  T_B_C.translation() = p_B_C_m;
  return geometry::CameraMount(T_B_C);
}

void read_config(config::StrictMap& root, VehicleConfig& out) {
  require_positive(root, "mass_kg", out.mass_kg, 100.0);
  config::StrictMap limits = root.child("limits");
  require_deg_as_rad(limits, "max_tilt_deg", out.max_tilt_rad, 1.0, 80.0);
  if (!limits.has("min_thrust_n"))
    throw InputError(limits.describe("min_thrust_n") + " is missing");
  limits.read("min_thrust_n", out.min_thrust_n, 0.0, 1e4);
  require_positive(limits, "max_thrust_n", out.max_thrust_n, 1e4);
  require_deg_as_rad(limits, "max_yaw_rate_degps", out.max_yaw_rate_radps, 1.0, 2000.0);
  limits.finish();
  const double weight_n = out.mass_kg * 9.80665;
  if (!(out.max_thrust_n > weight_n) || !(out.min_thrust_n < weight_n)) {
    std::ostringstream message;
    message << limits.describe("max_thrust_n") << " = " << out.max_thrust_n
            << ", min_thrust_n = " << out.min_thrust_n << ", expected min < m g = " << weight_n
            << " < max";
    throw InputError(message.str());
  }

  // Vehicle files written before the frame-letter rename name the mount by words; both load.
  const char* const mount_key =
      root.has("T_body_camera") ? "T_body_camera" : "T_B_C";  // vocabulary: old spelling
  config::StrictMap camera = root.child(mount_key);
  double yaw_rad = 0.0;
  double pitch_rad = 0.0;
  double roll_rad = 0.0;
  require_deg_as_rad(camera, "yaw_deg", yaw_rad, -180.0, 180.0);
  require_deg_as_rad(camera, "pitch_deg", pitch_rad, -90.0, 90.0);
  require_deg_as_rad(camera, "roll_deg", roll_rad, -180.0, 180.0);
  double p[3] = {0.0, 0.0, 0.0};
  const char* const lever_key =
      camera.has("p_body_camera_m") ? "p_body_camera_m" : "p_B_C_m";  // vocabulary: old spelling
  camera.require_list(lever_key, p, 3);
  for (int i = 0; i < 3; ++i) {
    if (std::abs(p[i]) > 2.0) {
      std::ostringstream message;
      message << camera.describe(lever_key) << "[" << i << "] = " << p[i]
              << ", expected in [-2, 2]";
      throw InputError(message.str());
    }
  }
  camera.finish();
  root.finish();
  // The one check of the mount every consumer relies on (a rigid transform, and a horizontal
  // heading for eq. 9), here where the file is read, so no component finds out in flight.
  try {
    const geometry::CameraMount mount =
        camera_mount_from_angles(yaw_rad, pitch_rad, roll_rad, Eigen::Vector3d(p[0], p[1], p[2]));
    (void)mount.heading_rad();
    out.camera = mount;
  } catch (const InputError& e) {
    throw InputError(camera.describe("pitch_deg") + ": " + e.what());
  }
}

VehicleConfig load_vehicle_config(const std::string& path) {
  config::StrictMap root(config::load_yaml_file(path), path);
  VehicleConfig vehicle;
  read_config(root, vehicle);
  return vehicle;
}

}  // namespace hq
