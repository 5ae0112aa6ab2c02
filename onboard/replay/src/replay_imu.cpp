#include "hq/replay/replay_imu.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/estimator/complementary_filter.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fmt/format.h>
#include <random>

namespace hq::replay {
namespace {

constexpr double kDegToRad = M_PI / 180.0;
constexpr double kStandardGravityMps2 = estimator::kGravityMps2;
// A recorded accelerometer whose gravity lies further than this from the motion capture's down
// is read in the wrong axes (motion-capture frames are levelled to within a degree or two).
constexpr double kMaxGravityTiltDeg = 15.0;

}  // namespace

MemsImuModel bmi088() {
  MemsImuModel m;
  m.name = "Bosch BMI088";
  m.rate_hz = 200.0;
  m.gyro_noise_density_radps = 0.014 * kDegToRad;
  m.accel_noise_density_mps2 = 190e-6 * kStandardGravityMps2;
  m.gyro_bias_random_walk = 4e-5;
  m.accel_bias_random_walk = 1e-3;
  m.gyro_turn_on_bias_radps = 0.1 * kDegToRad;
  m.accel_turn_on_bias_mps2 = 0.05;
  return m;
}

std::string describe(const MemsImuModel& m) {
  return fmt::format(
      "{} at {:.0f} Hz: datasheet gyro noise {:.3f} deg/s/sqrt(Hz), accelerometer {:.0f} "
      "ug/sqrt(Hz); assumed bias random walk {:.0e} rad/s^2/sqrt(Hz) and {:.0e} "
      "m/s^3/sqrt(Hz), bias left after start-up calibration {:.2f} deg/s and {:.2f} m/s^2 per "
      "axis",
      m.name, m.rate_hz, m.gyro_noise_density_radps / kDegToRad,
      m.accel_noise_density_mps2 / kStandardGravityMps2 * 1e6, m.gyro_bias_random_walk,
      m.accel_bias_random_walk, m.gyro_turn_on_bias_radps / kDegToRad, m.accel_turn_on_bias_mps2);
}

std::optional<Eigen::Isometry3d> interpolate_pose(const std::vector<recording::StampedPose>& poses,
                                                  std::int64_t t_ns) {
  if (poses.empty() || t_ns < poses.front().t_ns || t_ns > poses.back().t_ns) return std::nullopt;
  const auto after = std::lower_bound(
      poses.begin(), poses.end(), t_ns,
      [](const recording::StampedPose& pose, std::int64_t t) { return pose.t_ns < t; });
  if (after->t_ns == t_ns || after == poses.begin()) return after->T_G_S;
  const auto before = after - 1;
  const double s =
      static_cast<double>(t_ns - before->t_ns) / static_cast<double>(after->t_ns - before->t_ns);
  const Eigen::Quaterniond q0(before->T_G_S.linear());
  const Eigen::Quaterniond q1(after->T_G_S.linear());
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q0.slerp(s, q1).normalized().toRotationMatrix();
  T.translation() = (1.0 - s) * before->T_G_S.translation() + s * after->T_G_S.translation();
  return T;
}

Eigen::Matrix3d R_B_C_for_camera_as_body() { return R_B_C_from_angles(0.0, 0.0, 0.0); }

geometry::CameraMount camera_as_body_mount() {
  return camera_mount_from_angles(0.0, 0.0, 0.0, Eigen::Vector3d::Zero());
}

Eigen::Matrix3d R_camera_kinect_accel() { return Eigen::Vector3d(-1.0, -1.0, 1.0).asDiagonal(); }

GravityEstimate gravity_from_accelerometer(const evaluation::TrajectorySpline& T_G_C,
                                           const std::vector<recording::AccelSample>& accel,
                                           const Eigen::Matrix3d& R_C_A) {
  GravityEstimate out;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const recording::AccelSample& sample : accel) {
    if (!T_G_C.contains(sample.t_ns) || !sample.accel_mps2.allFinite()) continue;
    // f = R_G_A^T (a_G - g_G), so g_G = a_G - R_G_A f.
    const Eigen::Matrix3d R_G_A = T_G_C.pose(sample.t_ns).linear() * R_C_A;
    sum += T_G_C.acceleration_G_mps2(sample.t_ns) - R_G_A * sample.accel_mps2;
    ++out.samples;
  }
  if (out.samples == 0 || !(sum.norm() > 0.0)) {
    throw InputError(fmt::format(
        "gravity from the accelerometer: none of its {} samples lies within the ground truth",
        accel.size()));
  }
  out.g_G_mps2 = kStandardGravityMps2 * sum.normalized();
  out.tilt_from_G_down_deg =
      std::acos(std::clamp(-out.g_G_mps2.normalized().z(), -1.0, 1.0)) / kDegToRad;
  if (out.tilt_from_G_down_deg > kMaxGravityTiltDeg) {
    throw InputError(fmt::format(
        "gravity from the accelerometer: {:.1f} deg from the ground truth's down over {} "
        "samples, expected within {:.0f} deg: the accelerometer's axes are not the ones assumed",
        out.tilt_from_G_down_deg, out.samples, kMaxGravityTiltDeg));
  }
  return out;
}

namespace {

/// Bias that starts at +-turn_on per axis and walks; white noise on top.
class SensorErrors {
 public:
  SensorErrors(double turn_on, double random_walk, double noise_density, double rate_hz,
               std::mt19937_64& rng)
      : rng_(rng),
        step_sigma_(random_walk / std::sqrt(rate_hz)),
        noise_sigma_(noise_density * std::sqrt(rate_hz)) {
    std::bernoulli_distribution sign(0.5);
    for (int i = 0; i < 3; ++i) bias_[i] = sign(rng_) ? turn_on : -turn_on;
  }
  Eigen::Vector3d next() {
    bias_ += step_sigma_ * gaussian();
    return bias_ + noise_sigma_ * gaussian();
  }

 private:
  Eigen::Vector3d gaussian() { return {normal_(rng_), normal_(rng_), normal_(rng_)}; }
  std::mt19937_64& rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  double step_sigma_;
  double noise_sigma_;
  Eigen::Vector3d bias_ = Eigen::Vector3d::Zero();
};

}  // namespace

std::vector<ImuMeasurement> synthesise_imu(
    const evaluation::TrajectorySpline& T_G_C, const Eigen::Matrix3d& R_B_C,
    const Eigen::Vector3d& g_G_mps2, const ImuSynthesis& synthesis,
    const std::vector<recording::AccelSample>* recorded_accel, const Eigen::Matrix3d& R_C_A) {
  const MemsImuModel& model = synthesis.imu;
  if (!(model.rate_hz > 0.0)) {
    throw InputError(fmt::format("IMU synthesis: rate {} Hz, expected > 0", model.rate_hz));
  }
  const auto period_ns = static_cast<std::int64_t>(std::llround(1e9 / model.rate_hz));
  std::mt19937_64 rng(synthesis.seed);
  SensorErrors gyro_errors(model.gyro_turn_on_bias_radps, model.gyro_bias_random_walk,
                           model.gyro_noise_density_radps, model.rate_hz, rng);
  SensorErrors accel_errors(model.accel_turn_on_bias_mps2, model.accel_bias_random_walk,
                            model.accel_noise_density_mps2, model.rate_hz, rng);
  const Eigen::Matrix3d& R_QC = R_B_C;
  std::size_t next_recorded = 0;
  std::vector<ImuMeasurement> out;
  for (std::int64_t t = T_G_C.t_begin_ns() + period_ns; t <= T_G_C.t_end_ns(); t += period_ns) {
    ImuMeasurement sample;
    sample.t_ns = t;
    sample.gyro_radps = R_QC * T_G_C.omega_S_radps(t) + gyro_errors.next();
    if (recorded_accel != nullptr) {
      // The recorded samples of this period, (t - period, t], averaged.
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      int count = 0;
      while (next_recorded < recorded_accel->size() && (*recorded_accel)[next_recorded].t_ns <= t) {
        const recording::AccelSample& a = (*recorded_accel)[next_recorded++];
        if (a.t_ns > t - period_ns && a.accel_mps2.allFinite()) {
          sum += a.accel_mps2;
          ++count;
        }
      }
      if (count == 0) continue;  // the recording has a gap: so has the IMU
      sample.accel_mps2 = R_QC * R_C_A * (sum / count);
    } else {
      const Eigen::Matrix3d R_GC = T_G_C.pose(t).linear();
      sample.accel_mps2 =
          R_QC * R_GC.transpose() * (T_G_C.acceleration_G_mps2(t) - g_G_mps2) + accel_errors.next();
    }
    out.push_back(sample);
  }
  if (out.empty()) {
    throw InputError(
        fmt::format("IMU synthesis: no sample over the ground truth's {:.3f} s{}",
                    hq::to_seconds(T_G_C.t_end_ns() - T_G_C.t_begin_ns()),
                    recorded_accel != nullptr ? " with the recorded accelerometer" : ""));
  }
  return out;
}

AccelerometerChoice choose_accelerometer(const evaluation::TrajectorySpline& T_G_C,
                                         const std::vector<recording::AccelSample>* accel,
                                         bool use_recorded) {
  AccelerometerChoice choice;
  choice.g_G_mps2 = Eigen::Vector3d(0.0, 0.0, -kStandardGravityMps2);
  if (accel == nullptr) {
    choice.description = "gravity ASSUMED along the ground truth's -z (no accelerometer.txt)";
    return choice;
  }
  try {
    const GravityEstimate g = gravity_from_accelerometer(T_G_C, *accel, R_camera_kinect_accel());
    choice.g_G_mps2 = g.g_G_mps2;
    choice.description = fmt::format(
        "gravity from accelerometer.txt ({} samples, Kinect axes): {:.2f} deg from the ground "
        "truth's -z",
        g.samples, g.tilt_from_G_down_deg);
    if (use_recorded) choice.recorded = accel;
  } catch (const InputError& e) {
    // Another sensor's axes, or no overlap with the ground truth: the model's accelerometer
    // replays the sequence instead, and says why.
    choice.description = fmt::format(
        "accelerometer.txt NOT USED ({}); gravity ASSUMED along the ground truth's -z", e.what());
  }
  return choice;
}

std::vector<recording::AccelSample> read_gyro_file(const std::string& path) {
  // Same layout as accelerometer.txt ("t x y z"), so the same strict reader applies.
  return recording::read_tum_accelerometer(path);
}

namespace {

ReplayImu recorded_imu(const recording::TumSequence& sequence, const std::string& gyro_path) {
  ReplayImu imu;
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

}  // namespace

ReplayImu load_replay_imu(const recording::TumSequence& sequence, const Eigen::Matrix3d& R_B_C,
                          const ImuSynthesis& synthesis) {
  const std::string gyro_path = sequence.directory() + "/gyro.txt";
  if (sequence.has_accelerometer() && std::filesystem::exists(gyro_path)) {
    return recorded_imu(sequence, gyro_path);
  }
  if (!sequence.has_ground_truth()) {
    throw InputError(sequence.directory() +
                     ": no accelerometer.txt + gyro.txt and no groundtruth.txt to synthesise an "
                     "IMU from, expected one of them");
  }
  const evaluation::TrajectorySpline spline =
      evaluation::TrajectorySpline::fit(sequence.ground_truth(), synthesis.spline);
  ReplayImu imu;
  imu.synthesised = true;
  const std::string fit = fmt::format(
      "ground truth fitted by a cubic B-spline (knots every {:.0f} ms; residual {:.2f} mm, "
      "{:.3f} deg RMS)",
      1e3 * synthesis.spline.knot_spacing_s, 1e3 * spline.residual_rms_m(),
      spline.residual_rms_deg());
  const AccelerometerChoice accel = choose_accelerometer(
      spline, sequence.has_accelerometer() ? &sequence.accelerometer() : nullptr,
      synthesis.recorded_accelerometer);
  const Eigen::Vector3d& g_G_mps2 = accel.g_G_mps2;
  const std::string& gravity = accel.description;
  const std::vector<recording::AccelSample>* recorded = accel.recorded;
  imu.samples =
      synthesise_imu(spline, R_B_C, g_G_mps2, synthesis, recorded, R_camera_kinect_accel());
  imu.description = fmt::format(
      "IMU SYNTHESISED, {} samples: {}; {}; gyro {}; accelerometer {}", imu.samples.size(), fit,
      gravity, describe(synthesis.imu),
      recorded != nullptr ? "RECORDED (the Kinect's, accelerometer.txt, averaged per sample)"
                          : "from the fit's acceleration with the same IMU's errors");
  return imu;
}

}  // namespace hq::replay
