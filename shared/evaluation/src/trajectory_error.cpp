#include "hq/evaluation/trajectory_error.hpp"

#include "hq/base/error.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <tuple>

namespace hq::evaluation {
namespace {

using recording::StampedPose;

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;
// A window shorter than half or longer than 1.5 times delta_s says little about drift per
// delta_s; it arises only at the ends of the sequence or across gaps in the estimate.
constexpr double kMinWindowFraction = 0.5;
constexpr double kMaxWindowFraction = 1.5;
// ground_truth_noise: an interval this much longer than the median one is a gap in the record.
constexpr double kMaxRegularInterval = 1.5;

void check_trajectory(const std::vector<StampedPose>& poses, const char* name) {
  for (std::size_t i = 0; i < poses.size(); ++i) {
    if (!poses[i].T_G_S.matrix().allFinite()) {
      throw InputError(std::string(name) + " pose " + std::to_string(i) + " (t_ns " +
                       std::to_string(poses[i].t_ns) + ") is not finite");
    }
    if (i > 0 && poses[i].t_ns <= poses[i - 1].t_ns) {
      throw InputError(std::string(name) + " pose " + std::to_string(i) + " (t_ns " +
                       std::to_string(poses[i].t_ns) + ") is not after pose " +
                       std::to_string(i - 1) + " (t_ns " + std::to_string(poses[i - 1].t_ns) +
                       "); expected strictly increasing stamps");
    }
  }
}

void check_positive(double value, const char* name) {
  if (!std::isfinite(value) || !(value > 0.0)) {
    throw InputError(std::string(name) + " = " + std::to_string(value) +
                     ", expected finite and > 0");
  }
}

std::string describe_association(const std::vector<StampedPose>& gt,
                                 const std::vector<StampedPose>& est, double max_dt_s) {
  return "(ground truth " + std::to_string(gt.size()) + " poses, estimate " +
         std::to_string(est.size()) + " poses, max_dt_s " + std::to_string(max_dt_s) + ")";
}

double rotation_angle_rad(const Eigen::Matrix3d& R) {
  // Via the quaternion: 2 atan2(|v|, |w|) stays accurate for small angles, unlike acos.
  return Eigen::AngleAxisd(Eigen::Quaterniond(R).normalized()).angle();
}

}  // namespace

ErrorStats error_stats(std::vector<double> values) {
  ErrorStats stats;
  if (values.empty()) return stats;
  const std::size_t n = values.size();
  stats.count = static_cast<int>(n);
  double sum = 0.0;
  double sum_squares = 0.0;
  for (const double v : values) {
    HQ_ASSERT(std::isfinite(v));
    sum += v;
    sum_squares += v * v;
  }
  stats.max = *std::max_element(values.begin(), values.end());
  stats.mean = sum / static_cast<double>(n);
  stats.rmse = std::sqrt(sum_squares / static_cast<double>(n));
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(values.begin(), middle, values.end());
  stats.median = *middle;
  if (n % 2 == 0) {
    // The lower middle value is the largest of the lower half.
    stats.median = 0.5 * (stats.median + *std::max_element(values.begin(), middle));
  }
  return stats;
}

std::vector<std::pair<std::size_t, std::size_t>> associate_poses(
    const std::vector<StampedPose>& gt, const std::vector<StampedPose>& est, double max_dt_s) {
  if (!std::isfinite(max_dt_s) || !(max_dt_s >= 0.0) || max_dt_s > 1e6) {
    throw InputError("max_dt_s = " + std::to_string(max_dt_s) + ", expected in [0, 1e6]");
  }
  check_trajectory(gt, "ground truth");
  check_trajectory(est, "estimate");
  const std::int64_t max_dt_ns = recording::seconds_to_ns(max_dt_s);

  struct Candidate {
    std::int64_t abs_dt_ns;
    std::size_t est_index;
    std::size_t gt_index;
  };
  std::vector<Candidate> candidates;
  std::size_t first_gt = 0;
  for (std::size_t e = 0; e < est.size(); ++e) {
    const std::int64_t t_ns = est[e].t_ns;
    while (first_gt < gt.size() && gt[first_gt].t_ns < t_ns - max_dt_ns) ++first_gt;
    for (std::size_t g = first_gt; g < gt.size() && gt[g].t_ns <= t_ns + max_dt_ns; ++g) {
      candidates.push_back({std::abs(gt[g].t_ns - t_ns), e, g});
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return std::tie(a.abs_dt_ns, a.est_index, a.gt_index) <
           std::tie(b.abs_dt_ns, b.est_index, b.gt_index);
  });
  std::vector<bool> gt_used(gt.size(), false);
  std::vector<bool> est_used(est.size(), false);
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  for (const Candidate& c : candidates) {
    if (gt_used[c.gt_index] || est_used[c.est_index]) continue;
    gt_used[c.gt_index] = true;
    est_used[c.est_index] = true;
    pairs.emplace_back(c.gt_index, c.est_index);
  }
  std::sort(pairs.begin(), pairs.end(),
            [](const auto& a, const auto& b) { return a.second < b.second; });
  return pairs;
}

RpeResult relative_pose_error(const std::vector<StampedPose>& gt,
                              const std::vector<StampedPose>& est, double delta_s,
                              double max_dt_s) {
  check_positive(delta_s, "delta_s");
  const std::vector<std::pair<std::size_t, std::size_t>> pairs = associate_poses(gt, est, max_dt_s);
  if (pairs.size() < 2) {
    throw InputError("RPE needs at least 2 associated poses, got " + std::to_string(pairs.size()) +
                     " " + describe_association(gt, est, max_dt_s));
  }
  // Pairs are sorted by estimate index and so (strictly increasing stamps) by estimate time.
  std::vector<std::int64_t> t_ns(pairs.size());
  for (std::size_t k = 0; k < pairs.size(); ++k) t_ns[k] = est[pairs[k].second].t_ns;

  RpeResult result;
  result.delta_s = delta_s;
  const double span_s = recording::ns_to_seconds(t_ns.back() - t_ns.front());
  if (span_s < delta_s) {
    result.delta_s = span_s;
    result.delta_clipped = true;
  }
  const std::int64_t delta_ns = recording::seconds_to_ns(result.delta_s);

  std::vector<double> trans_mps;
  std::vector<double> rot_degps;
  for (std::size_t i = 0; i + 1 < pairs.size(); ++i) {
    const std::int64_t target_ns = t_ns[i] + delta_ns;
    // The closest stamp to the target is the first at or after it, or the one before that.
    const auto after =
        std::lower_bound(t_ns.begin() + static_cast<std::ptrdiff_t>(i) + 1, t_ns.end(), target_ns);
    std::size_t j = static_cast<std::size_t>(after - t_ns.begin());
    if (j == t_ns.size() || (j > i + 1 && target_ns - t_ns[j - 1] < t_ns[j] - target_ns)) --j;
    const double window_s = recording::ns_to_seconds(t_ns[j] - t_ns[i]);
    if (window_s < kMinWindowFraction * result.delta_s ||
        window_s > kMaxWindowFraction * result.delta_s) {
      continue;
    }
    const Eigen::Isometry3d& Q_i = gt[pairs[i].first].T_G_S;
    const Eigen::Isometry3d& Q_j = gt[pairs[j].first].T_G_S;
    const Eigen::Isometry3d& P_i = est[pairs[i].second].T_G_S;
    const Eigen::Isometry3d& P_j = est[pairs[j].second].T_G_S;
    // Sturm 2012, eq. 1: the estimate's relative motion seen from the ground truth's.
    const Eigen::Isometry3d E = (Q_i.inverse() * Q_j).inverse() * (P_i.inverse() * P_j);
    trans_mps.push_back(E.translation().norm() / window_s);
    rot_degps.push_back(rotation_angle_rad(E.linear()) * kRadToDeg / window_s);
  }
  if (trans_mps.empty()) {
    throw InputError("RPE found no pair of associated poses between " +
                     std::to_string(kMinWindowFraction * result.delta_s) + " and " +
                     std::to_string(kMaxWindowFraction * result.delta_s) + " s apart " +
                     describe_association(gt, est, max_dt_s));
  }
  result.trans_mps = error_stats(std::move(trans_mps));
  result.rot_degps = error_stats(std::move(rot_degps));
  return result;
}

AteResult absolute_trajectory_error(const std::vector<StampedPose>& gt,
                                    const std::vector<StampedPose>& est, double max_dt_s) {
  const std::vector<std::pair<std::size_t, std::size_t>> pairs = associate_poses(gt, est, max_dt_s);
  // Fewer than 3 points leave the rotation about their line undetermined.
  if (pairs.size() < 3) {
    throw InputError("ATE needs at least 3 associated poses, got " + std::to_string(pairs.size()) +
                     " " + describe_association(gt, est, max_dt_s));
  }
  Eigen::Matrix3Xd p_gt(3, static_cast<Eigen::Index>(pairs.size()));
  Eigen::Matrix3Xd p_est(3, static_cast<Eigen::Index>(pairs.size()));
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    p_gt.col(static_cast<Eigen::Index>(k)) = gt[pairs[k].first].T_G_S.translation();
    p_est.col(static_cast<Eigen::Index>(k)) = est[pairs[k].second].T_G_S.translation();
  }
  AteResult result;
  // Least-squares R, t minimising sum |p_gt - (R p_est + t)|^2 (Sturm 2012, eq. 3; Umeyama).
  result.T_gt_est.matrix() = Eigen::umeyama(p_est, p_gt, /*with_scaling=*/false);
  std::vector<double> errors_m(pairs.size());
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const Eigen::Index c = static_cast<Eigen::Index>(k);
    errors_m[k] = (p_gt.col(c) - result.T_gt_est * p_est.col(c)).norm();
  }
  result.trans_m = error_stats(std::move(errors_m));
  return result;
}

PoseNoise ground_truth_noise(const std::vector<StampedPose>& gt) {
  check_trajectory(gt, "ground truth");
  PoseNoise noise;
  if (gt.size() < 4) return noise;
  std::vector<std::int64_t> intervals_ns;
  for (std::size_t k = 1; k < gt.size(); ++k) intervals_ns.push_back(gt[k].t_ns - gt[k - 1].t_ns);
  std::vector<std::int64_t> sorted = intervals_ns;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2),
                   sorted.end());
  const auto median_ns = static_cast<double>(sorted[sorted.size() / 2]);
  // Step k (pose k to k+1) as a rate times the median interval: translation in the world,
  // rotation in the body frame (constant for a constant body rate).
  struct Step {
    Eigen::Vector3d translation;
    Eigen::Vector3d rotation;
    bool regular;
  };
  std::vector<Step> steps;
  for (std::size_t k = 0; k + 1 < gt.size(); ++k) {
    const double scale = median_ns / static_cast<double>(intervals_ns[k]);
    const Eigen::Isometry3d& a = gt[k].T_G_S;
    const Eigen::Isometry3d& b = gt[k + 1].T_G_S;
    const Eigen::AngleAxisd body(
        Eigen::Quaterniond(a.linear().transpose() * b.linear()).normalized());
    steps.push_back({scale * (b.translation() - a.translation()),
                     scale * body.angle() * body.axis(),
                     static_cast<double>(intervals_ns[k]) <= kMaxRegularInterval * median_ns});
  }
  double sum_t = 0.0;
  double sum_r = 0.0;
  for (std::size_t k = 0; k + 2 < steps.size(); ++k) {
    if (!steps[k].regular || !steps[k + 1].regular || !steps[k + 2].regular) continue;
    // The second difference of the steps is the third of the poses.
    sum_t += (steps[k + 2].translation - 2.0 * steps[k + 1].translation + steps[k].translation)
                 .squaredNorm();
    sum_r +=
        (steps[k + 2].rotation - 2.0 * steps[k + 1].rotation + steps[k].rotation).squaredNorm();
    ++noise.differences;
  }
  if (noise.differences == 0) return noise;
  constexpr double kThirdDifferenceGain = 20.0;  // 1 + 9 + 9 + 1: weights 1, -3, 3, -1
  const double n = kThirdDifferenceGain * noise.differences;
  noise.trans_m = std::sqrt(sum_t / n);
  noise.rot_deg = std::sqrt(sum_r / n) * kRadToDeg;
  return noise;
}

}  // namespace hq::evaluation
