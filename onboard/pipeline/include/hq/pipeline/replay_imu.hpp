#pragma once
/// IMU for replaying recorded sequences through the chain: read from the sequence when it has
/// accelerometer.txt and gyro.txt (the simulator writes both, body NED frame Q), otherwise
/// synthesised from the ground truth, because TUM RGB-D has no gyro and the bundled fr1_360 has
/// no accelerometer.txt either.

#include "hq/geometry/camera_mount.hpp"
#include "hq/recording/tum_io.hpp"
#include "hq/recording/tum_sequence.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace hq::pipeline {

/// One IMU sample in the body frame Q (NED).
struct ImuMeasurement {
  std::int64_t t_ns = 0;
  Eigen::Vector3d gyro_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();  ///< Specific force.
};

/// Parameters of the synthesised IMU.
struct ImuSynthesis {
  double rate_hz = 200.0;
  double gyro_noise_density = 1.7e-4;  ///< rad/s/sqrt(Hz): white noise, sigma = this sqrt(rate).
  double accel_difference_s = 0.05;    ///< Step of the second difference giving a_W: 5 ms
                                       ///< steps would amplify mocap noise 100-fold.
  std::uint64_t seed = 1;
};

/// Where a replay's IMU came from.
struct ReplayImu {
  std::vector<ImuMeasurement> samples;  ///< Increasing stamps.
  bool synthesised = false;
  std::string description;  ///< One line for stderr.
};

/// Ground-truth pose at t_ns: position linear, rotation slerp between the neighbouring poses.
/// nullopt outside the trajectory's span. @pre poses sorted by stamp.
std::optional<Eigen::Isometry3d> interpolate_pose(const std::vector<recording::StampedPose>& poses,
                                                  std::int64_t t_ns);

/// The body frame Q of a TUM replay: the camera is the tracked sensor, so Q is the camera's
/// NED-equivalent (x = optical z forward, y = optical x right, z = optical y down), i.e.
/// R_QC = R_forward_optical = [e_y e_z e_x] and Q_p_C = 0.
Eigen::Matrix3d R_body_camera_for_camera_as_body();
/// The same as a mount: R_body_camera_for_camera_as_body(), no lever arm.
geometry::CameraMount camera_as_body_mount();

/// Synthesises IMU samples at synthesis.rate_hz over the ground truth's span from
/// T_world_camera poses (world z up, as TUM's mocap frame and the simulator's NWU world are):
///   gyro  = body rate log(R_WQ(t - d/2)^T R_WQ(t + d/2)) / d, d = 1 / rate, plus white noise;
///   accel = R_WQ^T (a_W - g_W), g_W = (0, 0, -g), a_W the second difference of the
///           interpolated positions over accel_difference_s.
/// R_WQ = R_WC R_QC^T. Throws hq::InputError if the ground truth spans less than 2 samples.
std::vector<ImuMeasurement> synthesise_imu(
    const std::vector<recording::StampedPose>& T_world_camera, const Eigen::Matrix3d& R_body_camera,
    const ImuSynthesis& synthesis = {});

/// Reads dir/gyro.txt ("t wx wy wz", s and rad/s, the simulator's extension of TUM). Throws
/// hq::InputError naming path:line.
std::vector<recording::AccelSample> read_gyro_file(const std::string& path);

/// The IMU of a sequence: accelerometer.txt + gyro.txt paired by stamp when both exist (body
/// frame Q of the recording), else synthesised from its ground truth with R_body_camera (use
/// R_body_camera_for_camera_as_body() for TUM). Throws hq::InputError if neither is possible.
ReplayImu load_replay_imu(const recording::TumSequence& sequence,
                          const Eigen::Matrix3d& R_body_camera, const ImuSynthesis& synthesis = {});

}  // namespace hq::pipeline
