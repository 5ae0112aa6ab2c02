#include "hq/sim/simulator.hpp"

#include "hq/base/error.hpp"
#include "hq/config/camera_info.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>

namespace hq::sim {

namespace {
constexpr double kGravityMps2 = 9.81;
constexpr double kPi = 3.14159265358979323846;

/// Camera optical axes (x right, y down, z forward) in a level forward-looking body NED frame.
Eigen::Matrix3d R_B_C_looking_forward() {
  Eigen::Matrix3d R;
  R << 0.0, 0.0, 1.0,  //
      1.0, 0.0, 0.0,   //
      0.0, 1.0, 0.0;
  return R;
}

/// T_B_C of a camera turned yaw_right about body z (down), tilted down by tilt_down
/// and rolled about its optical axis (core paper §2: 45 deg right, 30 deg down).
Eigen::Isometry3d make_T_B_C(const Eigen::Vector3d& p_B_C_m, double yaw_right_rad,
                             double tilt_down_rad, double optical_roll_rad) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_right_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
               Eigen::AngleAxisd(-tilt_down_rad, Eigen::Vector3d::UnitY()).toRotationMatrix() *
               R_B_C_looking_forward() *
               Eigen::AngleAxisd(optical_roll_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = p_B_C_m;
  return T;
}

/// Rejects a key that the vehicle file already defines (two sources would silently disagree).
void reject_with_vehicle_file(const config::StrictMap& map, const std::string& key,
                              const SimConfig& out) {
  if (!out.vehicle_file.empty() && map.has(key)) {
    throw InputError(map.describe(key) + " is set, but vehicle_file = " + out.vehicle_file +
                     " defines it; remove one");
  }
}

void read_vec3(config::StrictMap& map, const std::string& key, Eigen::Vector3d& v) {
  double values[3] = {v.x(), v.y(), v.z()};
  map.read_list(key, values, 3);
  v = Eigen::Vector3d(values[0], values[1], values[2]);
}
}  // namespace

SimConfig default_sim_config(int width, int height) {
  SimConfig config;
  config.camera.pinhole = pinhole_from_fov(width, height, 58.0 * kPi / 180.0);  // Xtion: 58 deg
  config.camera.T_B_C =
      make_T_B_C(Eigen::Vector3d(0.12, 0.0, 0.05), 45.0 * kPi / 180.0, 30.0 * kPi / 180.0, 0.0);
  return config;
}

void set_resolution(SimConfig& config, const std::string& width_x_height, const std::string& what) {
  int width = 0;
  int height = 0;
  char tail = 0;
  if (std::sscanf(width_x_height.c_str(), "%dx%d%c", &width, &height, &tail) != 2 || width < 16 ||
      height < 16 || width > 4096 || height > 4096) {
    throw InputError(what + " = " + width_x_height + ", expected WIDTHxHEIGHT such as 640x480");
  }
  const double hfov_rad =
      2.0 * std::atan(0.5 * config.camera.pinhole.width / config.camera.pinhole.fx);
  config.camera.pinhole = pinhole_from_fov(width, height, hfov_rad);
}

namespace {

/// vehicle: the quadrotor's parameters; mass and tilt limit come from the vehicle file if one
/// is named, and the rotors must lift what that file says the vehicle can.
void read_vehicle(config::StrictMap& section, const VehicleConfig& vehicle_file, SimConfig& out) {
  config::StrictMap v = section.child("vehicle");
  QuadrotorParams& p = out.vehicle;
  reject_with_vehicle_file(v, "mass_kg", out);
  reject_with_vehicle_file(v, "max_tilt_deg", out);
  v.read_positive("mass_kg", p.mass_kg, 100.0);
  read_vec3(v, "inertia_kgm2", p.inertia_kgm2);
  if (!(p.inertia_kgm2.minCoeff() > 0.0)) {
    throw InputError(v.describe("inertia_kgm2") + " has a value <= 0, expected > 0");
  }
  v.read_positive("arm_length_m", p.arm_length_m, 5.0);
  v.read_positive("thrust_coefficient", p.thrust_coefficient, 1.0);
  v.read_positive("torque_coefficient", p.torque_coefficient, 1.0);
  v.read_positive("max_rotor_speed_radps", p.max_rotor_speed_radps, 1e5);
  v.read_positive("motor_time_constant_s", p.motor_time_constant_s, 10.0);
  v.read("linear_drag_nspm", p.linear_drag_nspm, 0.0, 100.0);
  v.read("rest_height_m", p.rest_height_m, 0.0, 5.0);
  v.read_positive("attitude_natural_hz", p.attitude_natural_hz, 100.0);
  v.read_positive("attitude_damping", p.attitude_damping, 10.0);
  v.read_positive("yaw_rate_gain_per_s", p.yaw_rate_gain_per_s, 1000.0);
  v.read_deg_as_rad("max_tilt_deg", p.max_tilt_rad, 1.0, 80.0);
  read_vec3(v, "wind_mean_mps", p.wind_mean_mps);
  v.read("gust_sigma_mps", p.gust_sigma_mps, 0.0, 20.0);
  v.read_positive("gust_time_constant_s", p.gust_time_constant_s, 1000.0);
  v.finish();
  const double max_thrust_n =
      4.0 * p.thrust_coefficient * p.max_rotor_speed_radps * p.max_rotor_speed_radps;
  if (max_thrust_n < 1.2 * p.mass_kg * kGravityMps2) {
    throw InputError(v.describe("max_rotor_speed_radps") + " = " +
                     std::to_string(p.max_rotor_speed_radps) + ": maximum thrust " +
                     std::to_string(max_thrust_n) + " N, expected >= 1.2 * weight");
  }
  if (!out.vehicle_file.empty() && max_thrust_n < vehicle_file.max_thrust_n) {
    throw InputError(v.describe("max_rotor_speed_radps") + " = " +
                     std::to_string(p.max_rotor_speed_radps) + ": maximum thrust " +
                     std::to_string(max_thrust_n) + " N, expected >= max_thrust_n of " +
                     out.vehicle_file);
  }
}

/// imu: noise model and rate (a divisor of the dynamics rate, so samples fall on steps).
void read_imu(config::StrictMap& section, SimConfig& out) {
  config::StrictMap m = section.child("imu");
  ImuParams& p = out.imu;
  m.read("rate_hz", p.rate_hz, 200.0, 500.0);
  m.read("gyro_noise_density", p.gyro_noise_density, 0.0, 1.0);
  m.read("gyro_random_walk", p.gyro_random_walk, 0.0, 1.0);
  m.read("accel_noise_density", p.accel_noise_density, 0.0, 10.0);
  m.read("accel_random_walk", p.accel_random_walk, 0.0, 10.0);
  m.read("gyro_initial_bias_sigma_radps", p.gyro_initial_bias_sigma_radps, 0.0, 1.0);
  m.read("accel_initial_bias_sigma_mps2", p.accel_initial_bias_sigma_mps2, 0.0, 5.0);
  const double ratio = out.dynamics_rate_hz / p.rate_hz;
  if (std::abs(ratio - std::round(ratio)) > 1e-9) {
    throw InputError(
        m.describe("rate_hz") + " = " + std::to_string(p.rate_hz) +
        ", expected a divisor of dynamics_rate_hz = " + std::to_string(out.dynamics_rate_hz));
  }
  m.finish();
}

/// camera.depth: the structured-light model.
void read_depth_sensor(config::StrictMap& c, DepthSensorParams& q) {
  config::StrictMap d = c.child("depth");
  d.read("min_range_m", q.min_range_m, 0.0, 100.0);
  d.read_positive("max_range_m", q.max_range_m, 100.0);
  if (q.max_range_m <= q.min_range_m) {
    throw InputError(d.describe("max_range_m") + " = " + std::to_string(q.max_range_m) +
                     ", expected > min_range_m = " + std::to_string(q.min_range_m));
  }
  d.read("noise_sigma_per_m2", q.noise_sigma_per_m2, 0.0, 1.0);
  d.read_positive("baseline_m", q.baseline_m, 10.0);
  d.read_positive("disparity_focal_px", q.disparity_focal_px, 1e5);
  d.read("disparity_subpixels", q.disparity_subpixels, 0, 1024);
  d.read("edge_jump_ratio", q.edge_jump_ratio, 0.0, 10.0);
  d.read("dark_albedo", q.dark_albedo, 0.0, 1.0);
  d.read_deg_as_rad("grazing_max_deg", q.grazing_max_rad, 0.0, 90.0);
  d.finish();
}

/// camera: image size and field of view, image model, mount (unless the vehicle file has it)
/// and depth sensor.
/// camera.T_B_C: lever arm and the core paper's mount angles (§2: 45 deg right, 30 deg
/// down), defaults those of default_sim_config().
void read_camera_mount(config::StrictMap& c, Eigen::Isometry3d& T_B_C) {
  config::StrictMap t = c.child("T_B_C");
  Eigen::Vector3d p_B_C_m = T_B_C.translation();
  double yaw_right_rad = 45.0 * kPi / 180.0;
  double tilt_down_rad = 30.0 * kPi / 180.0;
  double optical_roll_rad = 0.0;
  read_vec3(t, "p_B_C_m", p_B_C_m);
  t.read_deg_as_rad("yaw_right_deg", yaw_right_rad, -180.0, 180.0);
  t.read_deg_as_rad("tilt_down_deg", tilt_down_rad, -90.0, 90.0);
  t.read_deg_as_rad("optical_roll_deg", optical_roll_rad, -180.0, 180.0);
  t.finish();
  T_B_C = make_T_B_C(p_B_C_m, yaw_right_rad, tilt_down_rad, optical_roll_rad);
}

void read_camera(config::StrictMap& section, SimConfig& out) {
  config::StrictMap c = section.child("camera");
  CameraParams& p = out.camera;
  int width = p.pinhole.width;
  int height = p.pinhole.height;
  double hfov_rad = 2.0 * std::atan(0.5 * width / p.pinhole.fx);
  c.read("width", width, 16, 4096);
  c.read("height", height, 16, 4096);
  c.read_deg_as_rad("hfov_deg", hfov_rad, 10.0, 170.0);
  p.pinhole = pinhole_from_fov(width, height, hfov_rad);
  if (!(p.pinhole.fx >= config::kMinFocalPx && p.pinhole.fx <= config::kMaxFocalPx)) {
    std::ostringstream message;
    message << c.describe("hfov_deg") << " = " << hfov_rad * 180.0 / M_PI << " with width " << width
            << " gives fx = " << p.pinhole.fx << " px, expected in [" << config::kMinFocalPx << ", "
            << config::kMaxFocalPx << "] px";
    throw InputError(message.str());
  }
  c.read_positive("rate_hz", p.rate_hz, 1000.0);
  c.read("gray", p.gray);
  c.read("image_noise_sigma", p.image_noise_sigma, 0.0, 50.0);
  c.read("ambient", p.ambient, 0.0, 1.0);
  c.read("diffuse", p.diffuse, 0.0, 1.0);
  reject_with_vehicle_file(c, "T_B_C", out);
  if (out.vehicle_file.empty()) read_camera_mount(c, p.T_B_C);
  read_depth_sensor(c, p.depth);
  c.finish();
}

}  // namespace

void read_config(config::StrictMap& section, SimConfig& out) {
  section.read_positive("dynamics_rate_hz", out.dynamics_rate_hz, 100000.0);
  if (out.dynamics_rate_hz < 500.0) {
    throw InputError(section.describe("dynamics_rate_hz") + " = " +
                     std::to_string(out.dynamics_rate_hz) + ", expected >= 500");
  }
  section.read_positive("vehicle_radius_m", out.vehicle_radius_m, 5.0);
  int seed = static_cast<int>(out.seed);
  section.read("seed", seed, 0, 2147483647);
  out.seed = static_cast<std::uint64_t>(seed);
  section.read("vehicle_file", out.vehicle_file, {});
  VehicleConfig vehicle_file;
  if (!out.vehicle_file.empty()) {
    vehicle_file = load_vehicle_config(out.vehicle_file);
    out.vehicle.mass_kg = vehicle_file.mass_kg;
    out.vehicle.max_tilt_rad = vehicle_file.max_tilt_rad;
    out.camera.T_B_C = vehicle_file.camera.T_B_C();
  }
  read_vehicle(section, vehicle_file, out);
  read_imu(section, out);
  read_camera(section, out);
  section.finish();
}

SimConfig load_sim_config(const std::string& path) {
  const YAML::Node root = config::load_yaml_file(path);
  config::StrictMap map(root, path);
  SimConfig config = default_sim_config();
  read_config(map, config);
  return config;
}

Simulator::Simulator(const SimConfig& config, const World& world)
    : config_(config),
      world_(world),
      vehicle_(config.vehicle, config.seed * 3u + 1u),
      imu_(config.imu, config.seed * 3u + 2u),
      renderer_(config.camera, world_, config.seed * 3u + 3u) {
  step_ns_ = std::llround(1e9 / config_.dynamics_rate_hz);
  imu_decimation_ = static_cast<int>(std::lround(config_.dynamics_rate_hz / config_.imu.rate_hz));
  if (imu_decimation_ < 1 ||
      std::abs(config_.dynamics_rate_hz / config_.imu.rate_hz - imu_decimation_) > 1e-9) {
    throw InputError(
        "sim config: imu.rate_hz = " + std::to_string(config_.imu.rate_hz) +
        ", expected a divisor of dynamics_rate_hz = " + std::to_string(config_.dynamics_rate_hz));
  }
  camera_period_ns_ = std::llround(1e9 / config_.camera.rate_hz);
  imu_ring_.resize(static_cast<std::size_t>(std::ceil(config_.imu.rate_hz)));  // 1 s
  vehicle_.reset(world_.start_N_m, world_.start_yaw_rad);
  update_truth();
  // The first frame is due at t = 0.
  camera_due_ = true;
  camera_t_ns_ = 0;
  camera_pose_ = truth_.T_N_B * config_.camera.T_B_C;
  next_camera_ns_ = camera_period_ns_;
}

void Simulator::set_command(const AttitudeCommand& command) { vehicle_.set_command(command); }

void Simulator::step_to(std::int64_t t_ns) {
  while (t_ns_ + step_ns_ <= t_ns) physics_step();
}

void Simulator::physics_step() {
  vehicle_.step(static_cast<double>(step_ns_) * 1e-9);
  ++steps_;
  t_ns_ += step_ns_;
  update_truth();

  // Specific force: what the accelerometer feels, f = R_BW (a_W - g_W). A MEMS IMU averages
  // over its sample period (its digital low-pass), so short events such as the touchdown
  // impulse reach the samples instead of falling between them.
  const QuadrotorState& s = vehicle_.state();
  const Eigen::Matrix3d R_N_B = s.q_N_B.toRotationMatrix();
  imu_f_sum_mps2_ += R_N_B.transpose() * (s.a_N_mps2 + Eigen::Vector3d(0.0, 0.0, kGravityMps2));
  imu_omega_sum_radps_ += s.omega_B_radps;
  if (steps_ % imu_decimation_ == 0) {
    const ImuSample sample = imu_.measure(t_ns_, imu_omega_sum_radps_ / imu_decimation_,
                                          imu_f_sum_mps2_ / imu_decimation_);
    imu_f_sum_mps2_.setZero();
    imu_omega_sum_radps_.setZero();
    const std::size_t capacity = imu_ring_.size();
    if (imu_count_ == capacity) {
      imu_head_ = (imu_head_ + 1) % capacity;
      --imu_count_;
    }
    imu_ring_[(imu_head_ + imu_count_) % capacity] = sample;
    ++imu_count_;
  }

  if (t_ns_ >= next_camera_ns_) {
    if (camera_due_) ++dropped_frames_;
    camera_due_ = true;
    camera_t_ns_ = t_ns_;
    camera_pose_ = truth_.T_N_B * config_.camera.T_B_C;
    ++frame_index_;
    while (next_camera_ns_ <= t_ns_) next_camera_ns_ += camera_period_ns_;
  }
}

void Simulator::update_truth() {
  const QuadrotorState& s = vehicle_.state();
  truth_.t_ns = t_ns_;
  truth_.T_N_B.setIdentity();
  truth_.T_N_B.linear() = s.q_N_B.toRotationMatrix();
  truth_.T_N_B.translation() = s.p_N_m;
  truth_.v_N_mps = s.v_N_mps;
  truth_.omega_B_radps = s.omega_B_radps;
  truth_.a_N_mps2 = s.a_N_mps2;
  truth_.euler_rad = euler_from_R_N_B(truth_.T_N_B.linear());
  // H: NED, yaw only (core paper §3), so R_N_H = Rx(pi) Rz(psi).
  const Eigen::Matrix3d R_N_H = R_N_B_from_euler(0.0, 0.0, truth_.euler_rad.z());
  truth_.v_H_mps = R_N_H.transpose() * s.v_N_mps;
  // At this step's time: a person walking into the vehicle is a collision too.
  truth_.clearance_m = distance_to_obstacles(world_, s.p_N_m, static_cast<double>(t_ns_) * 1e-9) -
                       config_.vehicle_radius_m;
  truth_.on_ground = s.on_ground;
  // Impacts with the floor count too (issue 39: a fall from 11.8 m read "collision ticks 0").
  truth_.floor_impact_speed_mps = s.floor_impact_speed_mps;
  if (s.floor_impact_speed_mps > 1e-3) {
    ++floor_impacts_;
    max_floor_impact_speed_mps_ = std::max(max_floor_impact_speed_mps_, s.floor_impact_speed_mps);
  }
  const bool hard_impact = s.floor_impact_speed_mps > kHardFloorImpactSpeedMps;
  hard_floor_impacts_ += hard_impact ? 1 : 0;
  truth_.collision = truth_.clearance_m < 0.0 || hard_impact;
  collided_ = collided_ || truth_.collision;
}

std::size_t Simulator::take_imu(ImuSample* out, std::size_t capacity) {
  const std::size_t n = std::min(capacity, imu_count_);
  const std::size_t ring = imu_ring_.size();
  for (std::size_t i = 0; i < n; ++i) out[i] = imu_ring_[(imu_head_ + i) % ring];
  imu_head_ = (imu_head_ + n) % ring;
  imu_count_ -= n;
  return n;
}

void Simulator::render_camera(cv::Mat& image, cv::Mat& depth_m) {
  renderer_.render(camera_pose_, static_cast<double>(camera_t_ns_) * 1e-9, frame_index_, image,
                   depth_m);
  camera_due_ = false;
}

}  // namespace hq::sim
