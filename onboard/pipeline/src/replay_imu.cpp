#include "hq/pipeline/replay_imu.hpp"

#include "hq/base/error.hpp"
#include "hq/control/vehicle_config.hpp"
#include "hq/estimator/complementary_filter.hpp"
#include "hq/geometry/lie.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <random>

namespace hq::pipeline {

std::optional<Eigen::Isometry3d> interpolate_pose(const std::vector<recording::StampedPose>& poses,
                                                  std::int64_t t_ns) {
  if (poses.empty() || t_ns < poses.front().t_ns || t_ns > poses.back().t_ns) return std::nullopt;
  const auto after = std::lower_bound(
      poses.begin(), poses.end(), t_ns,
      [](const recording::StampedPose& pose, std::int64_t t) { return pose.t_ns < t; });
  if (after->t_ns == t_ns || after == poses.begin()) return after->T_world_sensor;
  const auto before = after - 1;
  const double s =
      static_cast<double>(t_ns - before->t_ns) / static_cast<double>(after->t_ns - before->t_ns);
  const Eigen::Quaterniond q0(before->T_world_sensor.linear());
  const Eigen::Quaterniond q1(after->T_world_sensor.linear());
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q0.slerp(s, q1).normalized().toRotationMatrix();
  T.translation() =
      (1.0 - s) * before->T_world_sensor.translation() + s * after->T_world_sensor.translation();
  return T;
}

Eigen::Matrix3d R_body_camera_for_camera_as_body() {
  return control::R_body_camera_from_angles(0.0, 0.0, 0.0);
}

geometry::CameraMount camera_as_body_mount() {
  return control::camera_mount_from_angles(0.0, 0.0, 0.0, Eigen::Vector3d::Zero());
}

std::vector<ImuMeasurement> synthesise_imu(
    const std::vector<recording::StampedPose>& T_world_camera, const Eigen::Matrix3d& R_body_camera,
    const ImuSynthesis& synthesis) {
  if (T_world_camera.size() < 2) {
    throw InputError("IMU synthesis: ground truth has " + std::to_string(T_world_camera.size()) +
                     " poses, expected at least 2");
  }
  const auto period_ns = static_cast<std::int64_t>(std::llround(1e9 / synthesis.rate_hz));
  const auto half_accel_ns =
      static_cast<std::int64_t>(std::llround(0.5e9 * synthesis.accel_difference_s));
  const std::int64_t margin_ns = std::max(period_ns, half_accel_ns);
  const std::int64_t t_begin_ns = T_world_camera.front().t_ns + margin_ns;
  const std::int64_t t_end_ns = T_world_camera.back().t_ns - margin_ns;
  const double sigma_radps = synthesis.gyro_noise_density * std::sqrt(synthesis.rate_hz);
  std::mt19937_64 rng(synthesis.seed);
  std::normal_distribution<double> normal(0.0, sigma_radps);
  const Eigen::Vector3d g_world_mps2(0.0, 0.0, -estimator::kGravityMps2);
  const Eigen::Matrix3d R_CQ = R_body_camera.transpose();

  std::vector<ImuMeasurement> out;
  for (std::int64_t t = t_begin_ns; t <= t_end_ns; t += period_ns) {
    const auto T_a = interpolate_pose(T_world_camera, t - period_ns / 2);
    const auto T_b = interpolate_pose(T_world_camera, t + period_ns / 2);
    const auto T_now = interpolate_pose(T_world_camera, t);
    const auto T_minus = interpolate_pose(T_world_camera, t - half_accel_ns);
    const auto T_plus = interpolate_pose(T_world_camera, t + half_accel_ns);
    if (!T_a || !T_b || !T_now || !T_minus || !T_plus) continue;
    const Eigen::Matrix3d R_WQ_a = T_a->linear() * R_CQ;
    const Eigen::Matrix3d R_WQ_b = T_b->linear() * R_CQ;
    const Eigen::Matrix3d R_WQ = T_now->linear() * R_CQ;
    ImuMeasurement sample;
    sample.t_ns = t;
    // Body rate: R_WQ(t + d/2) = R_WQ(t - d/2) exp(hat(omega_Q) d).
    const double d_s = 1e-9 * static_cast<double>(period_ns);
    sample.gyro_radps = geometry::log_so3(R_WQ_a.transpose() * R_WQ_b) / d_s;
    sample.gyro_radps += Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    const double h_s = 1e-9 * static_cast<double>(half_accel_ns);
    const Eigen::Vector3d a_world_mps2 =
        (T_plus->translation() - 2.0 * T_now->translation() + T_minus->translation()) / (h_s * h_s);
    // Specific force: what an accelerometer measures is acceleration minus gravity.
    sample.accel_mps2 = R_WQ.transpose() * (a_world_mps2 - g_world_mps2);
    out.push_back(sample);
  }
  if (out.empty()) {
    throw InputError("IMU synthesis: ground truth spans too short a time for the " +
                     std::to_string(synthesis.accel_difference_s) + " s acceleration difference");
  }
  return out;
}

std::vector<recording::AccelSample> read_gyro_file(const std::string& path) {
  // Same layout as accelerometer.txt ("t x y z"), so the same strict reader applies.
  return recording::read_tum_accelerometer(path);
}

ReplayImu load_replay_imu(const recording::TumSequence& sequence,
                          const Eigen::Matrix3d& R_body_camera, const ImuSynthesis& synthesis) {
  ReplayImu imu;
  const std::string gyro_path = sequence.directory() + "/gyro.txt";
  if (sequence.has_accelerometer() && std::filesystem::exists(gyro_path)) {
    const auto& accel = sequence.accelerometer();
    const auto gyro = read_gyro_file(gyro_path);
    if (gyro.size() != accel.size()) {
      throw InputError(gyro_path + ": " + std::to_string(gyro.size()) + " samples, expected " +
                       std::to_string(accel.size()) + " as in accelerometer.txt");
    }
    imu.samples.reserve(gyro.size());
    for (std::size_t i = 0; i < gyro.size(); ++i) {
      // Both files carry microsecond stamps of the same samples.
      if (std::llabs(gyro[i].t_ns - accel[i].t_ns) > 1000) {
        throw InputError(gyro_path + ": sample " + std::to_string(i + 1) +
                         " stamp differs from accelerometer.txt's, expected the same stamps");
      }
      imu.samples.push_back({accel[i].t_ns, gyro[i].accel_mps2, accel[i].accel_mps2});
    }
    imu.description = "IMU from accelerometer.txt and gyro.txt (" +
                      std::to_string(imu.samples.size()) + " samples, body frame of the recording)";
    return imu;
  }
  if (!sequence.has_ground_truth()) {
    throw InputError(sequence.directory() +
                     ": no accelerometer.txt + gyro.txt and no groundtruth.txt to synthesise an "
                     "IMU from, expected one of them");
  }
  imu.samples = synthesise_imu(sequence.ground_truth(), R_body_camera, synthesis);
  imu.synthesised = true;
  imu.description = "IMU SYNTHESISED from groundtruth.txt at " +
                    std::to_string(static_cast<int>(synthesis.rate_hz)) +
                    " Hz (gyro = body rate + white noise, accel = gravity + finite-difference "
                    "acceleration; the sequence has no gyro.txt/accelerometer.txt pair)";
  return imu;
}

}  // namespace hq::pipeline
