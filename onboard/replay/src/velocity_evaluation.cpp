#include "hq/replay/velocity_evaluation.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/sources/tum_frame_source.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <fmt/format.h>

namespace hq::replay {

std::optional<Eigen::Vector3d> true_camera_velocity(
    const std::vector<recording::StampedPose>& T_G_C, std::int64_t t_ns, std::int64_t h_ns) {
  const auto T_minus = interpolate_pose(T_G_C, t_ns - h_ns);
  const auto T_now = interpolate_pose(T_G_C, t_ns);
  const auto T_plus = interpolate_pose(T_G_C, t_ns + h_ns);
  if (!T_minus || !T_now || !T_plus) return std::nullopt;
  const double two_h_s = 2e-9 * static_cast<double>(h_ns);
  // Central difference in W, then into the camera frame at t (as Ck_v_Ck of eqs. 1-2).
  return Eigen::Vector3d(T_now->linear().transpose() *
                         (T_plus->translation() - T_minus->translation()) / two_h_s);
}

namespace {

struct Shifted {
  Eigen::Vector3d sq_raw = Eigen::Vector3d::Zero();
  Eigen::Vector3d sq_filtered = Eigen::Vector3d::Zero();
  Eigen::Vector3d sq_flown = Eigen::Vector3d::Zero();
};

Shifted squared_errors(const std::vector<VelocitySample>& samples,
                       const std::vector<recording::StampedPose>& truth, std::int64_t h_ns,
                       std::int64_t shift_ns) {
  Shifted out;
  for (const VelocitySample& sample : samples) {
    const Eigen::Vector3d v_true = *true_camera_velocity(truth, sample.t_ns - shift_ns, h_ns);
    out.sq_raw += (sample.v_C_raw_mps - v_true).cwiseAbs2();
    out.sq_filtered += (sample.v_C_mps - v_true).cwiseAbs2();
    out.sq_flown += (sample.v_C_flown_mps - v_true).cwiseAbs2();
  }
  return out;
}

}  // namespace

VelocityErrors evaluate_velocity(const std::vector<VelocitySample>& samples,
                                 const std::vector<recording::StampedPose>& T_G_C,
                                 std::int64_t frame_interval_ns, const LagSearch& lag) {
  if (frame_interval_ns <= 0) {
    throw InputError("velocity evaluation: frame interval = " + std::to_string(frame_interval_ns) +
                     " ns, expected > 0");
  }
  const auto max_shift_ns = static_cast<std::int64_t>(std::llround(lag.max_lag_s * 1e9));
  const auto step_ns = std::max<std::int64_t>(1, std::llround(lag.step_s * 1e9));
  // Truth is defined on one interval, so checking both ends of the shift range suffices.
  std::vector<VelocitySample> usable;
  for (const VelocitySample& sample : samples) {
    if (true_camera_velocity(T_G_C, sample.t_ns, frame_interval_ns) &&
        true_camera_velocity(T_G_C, sample.t_ns - max_shift_ns, frame_interval_ns)) {
      usable.push_back(sample);
    }
  }
  if (usable.empty()) {
    throw InputError("velocity evaluation: none of " + std::to_string(samples.size()) +
                     " estimates lies within the ground truth (with +-1 frame and " +
                     std::to_string(lag.max_lag_s) + " s lag margin), expected at least 1");
  }
  VelocityErrors errors;
  errors.samples = static_cast<int>(usable.size());
  errors.frame_interval_s = hq::to_seconds(frame_interval_ns);
  const double n = static_cast<double>(usable.size());
  const Shifted at_zero = squared_errors(usable, T_G_C, frame_interval_ns, 0);
  errors.rmse_raw_mps = (at_zero.sq_raw / n).cwiseSqrt();
  errors.rmse_filtered_mps = (at_zero.sq_filtered / n).cwiseSqrt();
  errors.rmse_flown_mps = (at_zero.sq_flown / n).cwiseSqrt();
  double truth_sq = 0.0;
  for (const VelocitySample& sample : usable) {
    truth_sq += true_camera_velocity(T_G_C, sample.t_ns, frame_interval_ns)->squaredNorm();
  }
  errors.truth_rms_mps = std::sqrt(truth_sq / n);

  double best_filtered = at_zero.sq_filtered.sum();
  double best_raw = at_zero.sq_raw.sum();
  double best_flown = at_zero.sq_flown.sum();
  errors.rmse_filtered_at_lag_mps = errors.rmse_filtered_mps;
  for (std::int64_t shift = step_ns; shift <= max_shift_ns; shift += step_ns) {
    const Shifted e = squared_errors(usable, T_G_C, frame_interval_ns, shift);
    if (e.sq_filtered.sum() < best_filtered) {
      best_filtered = e.sq_filtered.sum();
      errors.filtered_lag_ms = 1e-6 * static_cast<double>(shift);
      errors.rmse_filtered_at_lag_mps = (e.sq_filtered / n).cwiseSqrt();
    }
    if (e.sq_raw.sum() < best_raw) {
      best_raw = e.sq_raw.sum();
      errors.raw_lag_ms = 1e-6 * static_cast<double>(shift);
    }
    if (e.sq_flown.sum() < best_flown) {
      best_flown = e.sq_flown.sum();
      errors.flown_lag_ms = 1e-6 * static_cast<double>(shift);
    }
  }
  return errors;
}

SequenceReplay replay_velocity(const std::string& sequence_dir, const config::CameraInfo& camera,
                               const pipeline::OnboardConfig& config, const VehicleConfig& vehicle,
                               const ImuSynthesis& synthesis) {
  sources::TumFrameSource source(sequence_dir, camera);
  const recording::TumSequence& sequence = source.sequence();
  if (!sequence.has_ground_truth()) {
    throw InputError(sequence_dir +
                     "/groundtruth.txt: missing, expected ground truth to compare "
                     "velocities with");
  }
  SequenceReplay replay;
  replay.ground_truth = sequence.ground_truth();
  std::vector<std::int64_t> spacing_ns;
  for (std::size_t i = 1; i < sequence.size(); ++i) {
    spacing_ns.push_back(sequence.frame(i).t_ns - sequence.frame(i - 1).t_ns);
  }
  if (spacing_ns.empty()) {
    throw InputError(sequence_dir + ": 1 frame, expected at least 2 to differentiate poses");
  }
  std::nth_element(spacing_ns.begin(),
                   spacing_ns.begin() + static_cast<std::ptrdiff_t>(spacing_ns.size() / 2),
                   spacing_ns.end());
  replay.frame_interval_ns = spacing_ns[spacing_ns.size() / 2];

  replay.imu = load_replay_imu(sequence, R_B_C_for_camera_as_body(), synthesis);
  VehicleConfig replay_vehicle = vehicle;
  if (replay.imu.synthesised) {
    // The synthesised IMU lives on the camera: the camera is the body (see replay_imu.hpp).
    replay_vehicle.camera = camera_as_body_mount();
  }
  // A recording is replayed from its first frame in motion (hand-held or in flight): never a
  // vehicle resting on the floor with its motors idle.
  pipeline::OnboardConfig in_motion = config;
  in_motion.modes.start_landed = false;
  pipeline::OnboardChain chain(in_motion, replay_vehicle, source.camera());
  std::size_t next_imu = 0;
  sources::RgbdFrame frame;
  while (source.next(frame) == sources::FrameStatus::kFrame) {
    while (next_imu < replay.imu.samples.size() &&
           replay.imu.samples[next_imu].t_ns <= frame.t_ns) {
      const ImuMeasurement& m = replay.imu.samples[next_imu++];
      chain.on_imu(m.t_ns, m.gyro_radps, m.accel_mps2);
    }
    const pipeline::ChainOutput out =
        chain.on_frame(frame.t_ns, frame.depth_exposure_ns(), frame.gray, frame.depth_m);
    ++replay.frames;
    if (out.estimate.ok()) {
      ++replay.ok_estimates;
      replay.mean_innovation_chi2 += out.estimate.innovation_chi2;
      // The flown body velocity as the camera's centre moves (eq. 4 undone).
      const Eigen::Vector3d v_C_flown =
          replay_vehicle.camera.R_B_C().transpose() *
          (out.estimate.v_B_mps +
           out.estimate.omega_B_radps.cross(replay_vehicle.camera.p_B_C_m()));
      replay.samples.push_back(
          {frame.t_ns, out.estimate.v_C_raw_mps, out.estimate.v_C_mps, v_C_flown});
    } else {
      if (out.estimate.usable()) ++replay.inertial_estimates;
      ++replay.unavailable_reasons[out.estimate.reason];
    }
  }
  replay.imu.samples.clear();
  if (replay.ok_estimates > 0) replay.mean_innovation_chi2 /= replay.ok_estimates;
  if (replay.ok_estimates == 0) {
    // The chain's own start-up rules, not bad data: say which values to lower.
    const bool one_euro = config.estimator.velocity_output ==
                          estimator::VelocityEstimatorConfig::VelocityOutput::kOneEuro;
    const std::string warm_up =
        one_euro ? fmt::format("estimator.warmup_s ({} s) after a start, then for ",
                               config.estimator.warmup_s)
                 : std::string("a second frame after a start, then for ");
    throw InputError(fmt::format(
        "{}: none of its {} frames gave a usable velocity; the estimator waits {}"
        "estimator.reacquire_frames ({}) frames that agree with the IMU: a sequence this short "
        "needs a config with less",
        sequence_dir, replay.frames, warm_up, config.estimator.reacquire_frames));
  }
  return replay;
}

}  // namespace hq::replay
