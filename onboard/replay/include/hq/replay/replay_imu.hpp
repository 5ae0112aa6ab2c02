#pragma once
/// IMU for replaying recorded sequences through the chain. A sequence with accelerometer.txt and
/// gyro.txt (the simulator writes both, body frame Q, NED) is replayed as recorded. TUM RGB-D has
/// no gyro: its IMU is what a named MEMS IMU riding on the camera would have measured, derived
/// from a smooth fit of the motion capture (hq/evaluation/trajectory_spline.hpp) with that IMU's
/// datasheet noise, and the Kinect's own accelerometer (fr1, fr2) where the sequence has one.

#include "hq/evaluation/trajectory_spline.hpp"
#include "hq/geometry/camera_mount.hpp"
#include "hq/recording/tum_io.hpp"
#include "hq/recording/tum_sequence.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace hq::replay {

/// One IMU sample in the body frame Q (NED).
struct ImuMeasurement {
  std::int64_t t_ns = 0;
  Eigen::Vector3d gyro_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();  ///< Specific force.
};

/// A MEMS IMU's errors: white noise from its datasheet; what the datasheet does not give (the
/// bias random walk, the bias left after the flight controller's start-up calibration) is
/// assumed and said so in describe().
struct MemsImuModel {
  std::string name;
  double rate_hz = 200.0;                 ///< Samples the flight controller hands on.
  double gyro_noise_density_radps = 0.0;  ///< rad/s/sqrt(Hz)
  double accel_noise_density_mps2 = 0.0;  ///< m/s^2/sqrt(Hz)
  double gyro_bias_random_walk = 0.0;     ///< rad/s^2/sqrt(Hz) (assumed)
  double accel_bias_random_walk = 0.0;    ///< m/s^3/sqrt(Hz) (assumed)
  double gyro_turn_on_bias_radps = 0.0;   ///< per axis, after calibration (assumed)
  double accel_turn_on_bias_mps2 = 0.0;   ///< per axis, after calibration (assumed)
};

/// Bosch BMI088, the IMU of most current PX4 flight controllers (Pixhawk 6C/6X, Holybro,
/// CUAV): datasheet BST-BMI088-DS001, gyro 0.014 deg/s/sqrt(Hz), accelerometer 190 ug/sqrt(Hz)
/// (its noisiest axis, z).
MemsImuModel bmi088();
/// One line: the model's name and every figure, datasheet and assumed ones told apart.
std::string describe(const MemsImuModel& model);

/// How a replay's IMU is made where the sequence has none of its own.
struct ImuSynthesis {
  MemsImuModel imu = bmi088();
  evaluation::TrajectorySplineConfig spline;
  /// Use the sequence's recorded accelerometer (TUM's Kinect) rather than the model's, where
  /// it has one: a real sensor, noise, bias and misalignment included.
  bool recorded_accelerometer = true;
  std::uint64_t seed = 1;
};

/// Where a replay's IMU came from.
struct ReplayImu {
  std::vector<ImuMeasurement> samples;  ///< Increasing stamps.
  bool synthesised = false;             ///< The gyro, at least, made from the ground truth.
  std::string description;              ///< Lines for stderr: the sources and the IMU model.
};

/// Ground-truth pose at t_ns: position linear, rotation slerp between the neighbouring poses.
/// nullopt outside the trajectory's span. @pre poses sorted by stamp.
std::optional<Eigen::Isometry3d> interpolate_pose(const std::vector<recording::StampedPose>& poses,
                                                  std::int64_t t_ns);

/// The body frame Q of a TUM replay: the camera is the tracked sensor, so Q is the camera's
/// NED-equivalent (x = optical z forward, y = optical x right, z = optical y down), i.e.
/// R_QC = R_forward_optical = [e_y e_z e_x] and Q_p_C = 0.
Eigen::Matrix3d R_B_C_for_camera_as_body();
/// The same as a mount: R_B_C_for_camera_as_body(), no lever arm.
geometry::CameraMount camera_as_body_mount();

/// The Kinect v1's accelerometer axes A in its optical frame C: x left, y up, z forward, i.e.
/// C turned half a turn about its optical axis (TUM's accelerometer.txt, checked against the
/// motion capture by gravity_from_accelerometer).
Eigen::Matrix3d R_camera_kinect_accel();

/// Gravity in the ground truth's world frame, as a recorded accelerometer sees it: the mean of
/// a_G - R_G_A f_A over the samples within the fit (R_G_A = R_G_C R_C_A), scaled to standard
/// gravity (the direction is what a tilted motion-capture frame changes; a consumer
/// accelerometer's scale is no better than a few per cent).
struct GravityEstimate {
  Eigen::Vector3d g_G_mps2 = Eigen::Vector3d::Zero();
  double tilt_from_G_down_deg = 0.0;  ///< Angle between g_G and the world's -z.
  int samples = 0;
};
/// Throws hq::InputError when no sample lies within the fit, or when the gravity found is more
/// than 15 deg from the world's down: then R_C_A is not the recording's accelerometer axes.
GravityEstimate gravity_from_accelerometer(const evaluation::TrajectorySpline& T_G_C,
                                           const std::vector<recording::AccelSample>& accel,
                                           const Eigen::Matrix3d& R_C_A);

/// Where the replay's gravity and accelerometer come from.
struct AccelerometerChoice {
  Eigen::Vector3d g_G_mps2 = Eigen::Vector3d::Zero();
  /// The recorded samples to replay (Kinect axes), or null: the IMU model's.
  const std::vector<recording::AccelSample>* recorded = nullptr;
  std::string description;  ///< One clause for ReplayImu::description.
};
/// With a recorded accelerometer (null: none), gravity from it and, if use_recorded, the record
/// itself; when its gravity is not the motion capture's down (another sensor's axes) or it
/// does not overlap the ground truth, neither, and the description says why. Without one,
/// gravity along the world's -z, said to be assumed.
AccelerometerChoice choose_accelerometer(const evaluation::TrajectorySpline& T_G_C,
                                         const std::vector<recording::AccelSample>* accel,
                                         bool use_recorded);

/// IMU samples at synthesis.imu.rate_hz over the fit's span, in the body frame Q (R_B_C
/// is R_QC, the camera the tracked sensor, no lever arm):
///   gyro  = R_QC omega_C + bias + white noise;
///   accel = R_QC R_GC^T (a_G - g_G) + bias + white noise, or, with recorded_accel, the
///           recorded specific force R_QC R_C_A f_A averaged over the sample's period (as a
///           flight controller's accelerometer filter decimates) instead.
/// Biases start at +-turn_on (random sign per axis) and walk. Deterministic for a seed.
std::vector<ImuMeasurement> synthesise_imu(
    const evaluation::TrajectorySpline& T_G_C, const Eigen::Matrix3d& R_B_C,
    const Eigen::Vector3d& g_G_mps2, const ImuSynthesis& synthesis = {},
    const std::vector<recording::AccelSample>* recorded_accel = nullptr,
    const Eigen::Matrix3d& R_C_A = Eigen::Matrix3d::Identity());

/// Reads dir/gyro.txt ("t wx wy wz", s and rad/s, the simulator's extension of TUM). Throws
/// hq::InputError naming path:line.
std::vector<recording::AccelSample> read_gyro_file(const std::string& path);

/// The IMU of a sequence: accelerometer.txt + gyro.txt paired by stamp when both exist (body
/// frame Q of the recording); else synthesised from its ground truth with R_B_C (use
/// R_B_C_for_camera_as_body() for TUM), gravity and the accelerometer from
/// accelerometer.txt where there is one (Kinect axes), gravity along the world's -z where not.
/// Throws hq::InputError if neither is possible.
ReplayImu load_replay_imu(const recording::TumSequence& sequence, const Eigen::Matrix3d& R_B_C,
                          const ImuSynthesis& synthesis = {});

}  // namespace hq::replay
