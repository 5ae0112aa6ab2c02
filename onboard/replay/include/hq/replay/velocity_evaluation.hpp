#pragma once
/// Accuracy of the camera velocity of eq. 1 (raw poses) and eq. 2 (1€-filtered poses) of the
/// core paper against ground truth, and the lag the filter adds.
///
/// Truth: v_C(t) = R_GC(t)^T (p_GC(t + h) - p_GC(t - h)) / 2h, a central difference over +-1
/// frame interval h (the median spacing of the evaluated frames), ground truth interpolated to
/// the stamps (interpolate_pose), expressed in the camera frame at time t like Ck_v_Ck.

#include "hq/config/camera_info.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/recording/tum_io.hpp"
#include "hq/replay/replay_imu.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace hq::replay {

/// One frame's camera velocity from the estimator (only frames whose estimate was kOk).
struct VelocitySample {
  std::int64_t t_ns = 0;
  Eigen::Vector3d v_C_raw_mps = Eigen::Vector3d::Zero();  ///< eq. 1.
  Eigen::Vector3d v_C_mps = Eigen::Vector3d::Zero();      ///< eq. 2.
  /// The velocity the chain flies on (the IMU-fused one by default), as the camera's.
  Eigen::Vector3d v_C_flown_mps = Eigen::Vector3d::Zero();
};

struct LagSearch {
  double max_lag_s = 0.2;  ///< Shifts searched: 0 .. max_lag_s.
  double step_s = 0.001;
};

struct VelocityErrors {
  int samples = 0;                ///< Frames compared (truth defined at every shift).
  double frame_interval_s = 0.0;  ///< h of the central difference.
  Eigen::Vector3d rmse_raw_mps = Eigen::Vector3d::Zero();       ///< eq. 1, per camera axis.
  Eigen::Vector3d rmse_filtered_mps = Eigen::Vector3d::Zero();  ///< eq. 2, per camera axis.
  Eigen::Vector3d rmse_flown_mps = Eigen::Vector3d::Zero();     ///< flown, per camera axis.
  double truth_rms_mps = 0.0;  ///< |v_true| RMS over the samples: the scale of the errors.
  /// Shift s minimising the filtered RMSE (3-axis) of v_est(t) against v_true(t - s).
  double filtered_lag_ms = 0.0;
  double raw_lag_ms = 0.0;    ///< Same for eq. 1 (a backward difference already lags by h/2).
  double flown_lag_ms = 0.0;  ///< Same for the flown velocity.
  Eigen::Vector3d rmse_filtered_at_lag_mps = Eigen::Vector3d::Zero();

  /// 3-axis RMSE: sqrt(sum of the per-axis mean squares).
  [[nodiscard]] double raw_norm_mps() const { return rmse_raw_mps.norm(); }
  [[nodiscard]] double filtered_norm_mps() const { return rmse_filtered_mps.norm(); }
  [[nodiscard]] double flown_norm_mps() const { return rmse_flown_mps.norm(); }
};

/// Truth v_C at t_ns (see the file comment); nullopt where t -+ h leaves the ground truth.
std::optional<Eigen::Vector3d> true_camera_velocity(
    const std::vector<recording::StampedPose>& T_G_C, std::int64_t t_ns, std::int64_t h_ns);

/// Compares the samples with the truth. Samples whose truth is undefined at any searched shift
/// are left out. Throws hq::InputError if fewer than one sample remains or h is not positive.
VelocityErrors evaluate_velocity(const std::vector<VelocitySample>& samples,
                                 const std::vector<recording::StampedPose>& T_G_C,
                                 std::int64_t frame_interval_ns, const LagSearch& lag = {});

/// A replay of one sequence through the OnboardChain.
struct SequenceReplay {
  std::vector<VelocitySample> samples;
  std::vector<recording::StampedPose> ground_truth;  ///< T_G_C.
  std::int64_t frame_interval_ns = 0;                ///< Median spacing of all frames.
  int frames = 0;
  int ok_estimates = 0;
  int inertial_estimates = 0;  ///< Frames the estimate coasted on the IMU instead.
  /// Mean squared Mahalanobis distance of the used frames' velocities against the IMU's
  /// prediction (NIS): 3 for a filter whose covariances are right, more when overconfident.
  double mean_innovation_chi2 = 0.0;
  /// Why the other frames had no odometry velocity: the estimate's reason, counted.
  std::map<std::string, int> unavailable_reasons;
  ReplayImu imu;  ///< samples emptied after use; description and synthesised kept.

  /// Share of frames with an odometry velocity (kOk), 0..1.
  [[nodiscard]] double availability() const {
    return frames > 0 ? static_cast<double>(ok_estimates) / frames : 0.0;
  }
};

/// Replays a TUM-layout sequence (undistorted with `camera`) through an OnboardChain with its
/// IMU (load_replay_imu; a synthesised IMU makes the camera the body), collecting eq. 1 and 2.
/// @param vehicle  used when the sequence has its own IMU files (its extrinsics must be the
///                 recording's). Throws hq::InputError for unreadable data, no ground truth,
///                 or no usable velocity in the whole sequence (too short for the estimator's
///                 warm-up and reacquire_frames).
SequenceReplay replay_velocity(const std::string& sequence_dir, const config::CameraInfo& camera,
                               const pipeline::OnboardConfig& config, const VehicleConfig& vehicle,
                               const ImuSynthesis& synthesis = {});

}  // namespace hq::replay
