#pragma once
/// Trajectory accuracy as defined by the TUM RGB-D benchmark (Sturm et al., IROS 2012): relative
/// pose error (RPE, drift per second, their eq. 1-2) and absolute trajectory error (ATE, their
/// eq. 3-4, after a least-squares rigid alignment by Horn's / Umeyama's method).
/// Q denotes ground truth, P the estimate; both are T_G_S in their own world frames.

#include "hq/recording/tum_io.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <cstddef>
#include <utility>
#include <vector>

namespace hq::evaluation {

/// Summary of a list of non-negative errors in the unit of the list.
struct ErrorStats {
  double rmse = 0;
  double mean = 0;
  double median = 0;  ///< Mean of the two middle values for an even count.
  double max = 0;
  int count = 0;  ///< 0 for an empty list, then every figure is 0.
};

/// RMSE, mean, median and maximum of values. @pre every value is finite.
ErrorStats error_stats(std::vector<double> values);

/// Pairs (gt index, estimate index) of stamps at most max_dt_s apart, chosen greedily by
/// smallest |dt| with each pose used at most once (TUM's associate.py); sorted by estimate.
/// Throws hq::InputError if either list is not strictly increasing in time or max_dt_s < 0.
std::vector<std::pair<std::size_t, std::size_t>> associate_poses(
    const std::vector<recording::StampedPose>& gt, const std::vector<recording::StampedPose>& est,
    double max_dt_s = 0.02);

struct RpeResult {
  ErrorStats trans_mps;        ///< |translation of E| / window length, m/s.
  ErrorStats rot_degps;        ///< rotation angle of E / window length, deg/s.
  double delta_s = 0;          ///< Window length used (after clipping).
  bool delta_clipped = false;  ///< The associated poses span less than the requested delta_s.
};

/// Relative pose error over windows of delta_s (Sturm 2012, eq. 1): for each associated
/// estimate i, the associated j whose t_j - t_i is closest to delta_s, within
/// [0.5, 1.5] delta_s; E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), normalised by t_j - t_i. If the
/// associated poses span less than delta_s, delta_s is clipped to the span. Throws
/// hq::InputError for fewer than 2 associated poses, non-finite poses or delta_s <= 0.
RpeResult relative_pose_error(const std::vector<recording::StampedPose>& gt,
                              const std::vector<recording::StampedPose>& est, double delta_s = 1.0,
                              double max_dt_s = 0.02);

struct AteResult {
  ErrorStats trans_m;          ///< |p_gt - T_gt_est * p_est| over associated poses, m.
  Eigen::Isometry3d T_gt_est;  ///< Rigid alignment (no scale) of estimate onto ground truth.
};

/// Absolute trajectory error of positions after the least-squares rigid alignment of the
/// associated positions (Sturm 2012, eq. 3-4; Umeyama 1991 without scale). Throws
/// hq::InputError for fewer than 3 associated poses or non-finite poses.
AteResult absolute_trajectory_error(const std::vector<recording::StampedPose>& gt,
                                    const std::vector<recording::StampedPose>& est,
                                    double max_dt_s = 0.02);

/// A ground truth's own noise per pose, estimated from its samples alone. White noise n_k on
/// each pose gives the third difference of the positions (and of the orientation, through the
/// body-frame steps log(R_k^T R_k+1)) a variance of 20 E|n|^2, while motion of constant
/// acceleration gives it none. Motion capture jitters (TUM fr1_360 at 100 Hz: about 0.066 deg
/// and 0.15 mm per pose), so a relative pose between two of its poses is uncertain by about
/// sqrt(2) times these: estimates whose errors differ by less cannot be ranked on it.
struct PoseNoise {
  double trans_m = 0;   ///< RMS length of one pose's position noise, m.
  double rot_deg = 0;   ///< RMS angle of one pose's rotation noise, deg.
  int differences = 0;  ///< Third differences used; 0 (and 0 noise) with none available.

  /// The same for the relative pose between two poses, whose noises are independent.
  [[nodiscard]] double pair_trans_m() const { return std::sqrt(2.0) * trans_m; }
  [[nodiscard]] double pair_rot_deg() const { return std::sqrt(2.0) * rot_deg; }
};

/// PoseNoise of gt. Steps are scaled to the median sample interval, so jittered stamps of
/// smooth motion add nothing; differences across a gap (an interval beyond 1.5 median
/// intervals) are skipped. Throws hq::InputError for non-finite or unordered poses.
PoseNoise ground_truth_noise(const std::vector<recording::StampedPose>& gt);

}  // namespace hq::evaluation
