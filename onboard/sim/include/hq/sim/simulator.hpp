#pragma once
/// Lock-step software-in-the-loop simulator: quadrotor + attitude controller at a fixed rate,
/// IMU samples, RGB-D frames and truth, advanced only by step_to(t_ns). No wall clock: the
/// caller owns time, so a run is a pure function of (config, world, seed, commands).

#include "hq/sim/imu.hpp"
#include "hq/sim/quadrotor.hpp"
#include "hq/sim/rgbd_renderer.hpp"
#include "hq/sim/world.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace hq::config {
class StrictMap;
}

namespace hq::sim {

struct SimConfig {
  double dynamics_rate_hz = 1000.0;  ///< fixed physics step; imu.rate_hz must divide it.
  double vehicle_radius_m = 0.35;    ///< collision sphere (0.5 m span plus propeller tips).
  std::uint64_t seed = 1;            ///< noise and gusts; same seed -> identical run.
  /// Vehicle file shared with hq::control (e.g. calib/vehicle_core_paper.yaml): when set, its
  /// mass, tilt limit and T_B_C are used, so the simulated and the controlled vehicle
  /// are the same one.
  std::string vehicle_file;
  QuadrotorParams vehicle;
  ImuParams imu;
  CameraParams camera;
};

/// Fills `out` from a `sim:`-style section (keys: dynamics_rate_hz, vehicle_radius_m, seed,
/// vehicle_file, vehicle, imu, camera); strict, ranges checked, `_deg` converted once. With
/// vehicle_file, vehicle.mass_kg, vehicle.max_tilt_deg and camera.T_B_C must be absent.
void read_config(config::StrictMap& section, SimConfig& out);
/// Loads a sim config file (top-level keys as in read_config).
SimConfig load_sim_config(const std::string& path);
/// Default config with the camera at width x height (60 deg x 45 deg field of view class).
SimConfig default_sim_config(int width = 320, int height = 240);
/// Re-sizes the camera to a "WIDTHxHEIGHT" string (e.g. "640x480") keeping its horizontal field
/// of view. Throws hq::InputError naming `what` (e.g. "--resolution") and the value.
void set_resolution(SimConfig& config, const std::string& width_x_height, const std::string& what);

/// Ground truth at the current step.
struct TruthState {
  std::int64_t t_ns = 0;
  Eigen::Isometry3d T_N_B = Eigen::Isometry3d::Identity();
  Eigen::Vector3d v_N_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_B_radps = Eigen::Vector3d::Zero();
  /// Velocity in the horizontal frame H (NED, yaw only; core paper §3): what eq. 5 estimates.
  Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d a_N_mps2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d euler_rad = Eigen::Vector3d::Zero();  ///< roll, pitch, yaw.
  /// Centre to nearest obstacle surface (people where they are at t_ns) minus vehicle radius.
  double clearance_m = 0.0;
  bool collision = false;  ///< clearance_m < 0, or a hard floor impact, at this step.
  bool on_ground = true;
  /// Speed at which the floor stopped the vehicle at this step (m/s), 0 when it did not.
  double floor_impact_speed_mps = 0.0;
};

/// A floor impact faster than this is a crash, counted as a collision (a landing's touchdown
/// is 0.3 m/s; PX4's default landing speed is 0.7 m/s).
inline constexpr double kHardFloorImpactSpeedMps = 1.5;

class Simulator {
 public:
  /// Throws hq::InputError on inconsistent rates or markers that lie on no surface.
  explicit Simulator(const SimConfig& config, const World& world);

  /// Holds until the next set_command (zero-order hold, as a serial link delivers it).
  void set_command(const AttitudeCommand& command);
  /// Advances physics in fixed steps up to (not beyond) t_ns. Allocates nothing.
  void step_to(std::int64_t t_ns);
  [[nodiscard]] std::int64_t t_ns() const { return t_ns_; }

  /// Copies IMU samples produced since the last call (oldest first) into out; returns count.
  /// At most `capacity`; older samples beyond the internal buffer (1 s) are dropped.
  std::size_t take_imu(ImuSample* out, std::size_t capacity);

  /// True when a camera frame fell due since the last render_camera().
  [[nodiscard]] bool camera_due() const { return camera_due_; }
  /// Stamp and camera pose of the due frame (the physics step at or after its nominal time).
  [[nodiscard]] std::int64_t camera_t_ns() const { return camera_t_ns_; }
  [[nodiscard]] const Eigen::Isometry3d& camera_T_N_C() const { return camera_pose_; }
  /// Renders the due frame (image BGR CV_8UC3 or gray, depth CV_32F metres), the world's people
  /// where they are at camera_t_ns(), and clears the flag.
  void render_camera(cv::Mat& image, cv::Mat& depth_m);
  /// Noise realisation of the due frame (RgbdRenderer::render's frame_index).
  [[nodiscard]] std::uint64_t camera_frame_index() const { return frame_index_; }
  /// Clears the due flag without rendering: for a caller rendering the due frame with its own
  /// RgbdRenderer on another thread while physics runs on (hq-sim --sitl).
  void hand_off_camera() { camera_due_ = false; }
  /// Frames that fell due and were superseded before being rendered.
  [[nodiscard]] std::int64_t dropped_frames() const { return dropped_frames_; }

  [[nodiscard]] const TruthState& truth() const { return truth_; }
  /// True if a collision happened at any step so far.
  [[nodiscard]] bool collided() const { return collided_; }
  /// Times the floor stopped the vehicle (touchdowns and impacts), and the fastest of them.
  [[nodiscard]] int floor_impacts() const { return floor_impacts_; }
  [[nodiscard]] double max_floor_impact_speed_mps() const { return max_floor_impact_speed_mps_; }
  /// Floor impacts faster than kHardFloorImpactSpeedMps: crashes.
  [[nodiscard]] int hard_floor_impacts() const { return hard_floor_impacts_; }
  [[nodiscard]] const SimConfig& config() const { return config_; }
  [[nodiscard]] const World& world() const { return world_; }
  [[nodiscard]] const Quadrotor& vehicle() const { return vehicle_; }
  /// The IMU model, whose biases are truth the estimators' can be checked against.
  [[nodiscard]] const ImuModel& imu() const { return imu_; }

 private:
  void physics_step();
  void update_truth();

  SimConfig config_;
  World world_;
  Quadrotor vehicle_;
  ImuModel imu_;
  RgbdRenderer renderer_;
  std::int64_t step_ns_ = 1'000'000;
  std::int64_t t_ns_ = 0;
  std::int64_t steps_ = 0;
  int imu_decimation_ = 2;
  Eigen::Vector3d imu_f_sum_mps2_ = Eigen::Vector3d::Zero();  ///< over the current IMU period
  Eigen::Vector3d imu_omega_sum_radps_ = Eigen::Vector3d::Zero();
  std::int64_t camera_period_ns_ = 33'333'333;
  std::int64_t next_camera_ns_ = 0;
  std::uint64_t frame_index_ = 0;
  bool camera_due_ = false;
  std::int64_t camera_t_ns_ = 0;
  Eigen::Isometry3d camera_pose_ = Eigen::Isometry3d::Identity();
  std::int64_t dropped_frames_ = 0;
  std::vector<ImuSample> imu_ring_;
  std::size_t imu_head_ = 0;  ///< index of the oldest sample
  std::size_t imu_count_ = 0;
  TruthState truth_;
  bool collided_ = false;
  int floor_impacts_ = 0;
  int hard_floor_impacts_ = 0;
  double max_floor_impact_speed_mps_ = 0.0;
};

}  // namespace hq::sim
