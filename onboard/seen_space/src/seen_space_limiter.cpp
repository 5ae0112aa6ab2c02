#include "hq/seen_space/seen_space_limiter.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace hq::seen_space {

namespace {

constexpr double kTwoPi = 2.0 * M_PI;
constexpr float kNone = std::numeric_limits<float>::infinity();

double wrap_pi(double a) {
  a = std::fmod(a + M_PI, kTwoPi);
  if (a < 0.0) a += kTwoPi;
  return a - M_PI;
}

}  // namespace

void read_config(config::StrictMap& section, SeenSpaceConfig& out) {
  section.read("enabled", out.enabled);
  section.read("bins", out.bins, 8, kMaxBins);
  section.read("pixel_stride", out.pixel_stride, 1, 64);
  section.read("min_range_m", out.min_range_m, 0.0, 10.0);
  section.read_positive("max_range_m", out.max_range_m, 100.0);
  section.read_positive("vertical_band_m", out.vertical_band_m, 10.0);
  section.read("min_valid_fraction", out.min_valid_fraction, 0.0, 1.0);
  section.read_positive("max_age_s", out.max_age_s, 600.0);
  section.read_positive("max_pose_jump_m", out.max_pose_jump_m, 100.0);
  section.read("margin_m", out.margin_m, 0.0, 10.0);
  section.read_positive("brake_accel_mps2", out.brake_accel_mps2, 50.0);
  section.read("reaction_s", out.reaction_s, 0.0, 5.0);
  section.read("creep_speed_mps", out.creep_speed_mps, 0.0, 5.0);
  section.read("no_data_half_angle_deg", out.no_data_half_angle_deg, 0.0, 90.0);
  section.finish();
}

SeenSpaceLimiter::SeenSpaceLimiter(const SeenSpaceConfig& config,
                                   const geometry::PinholeCamera& camera,
                                   const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m,
                                   double vehicle_radius_m)
    : config_(config),
      camera_(camera),
      R_B_C_(R_B_C),
      p_B_C_m_(p_B_C_m),
      vehicle_radius_m_(vehicle_radius_m) {
  if (config.bins < 8 || config.bins > kMaxBins) {
    throw InputError("seen_space.bins: " + std::to_string(config.bins) + ", expected 8.." +
                     std::to_string(kMaxBins));
  }
  if (!(config.max_range_m > config.min_range_m)) {
    throw InputError("seen_space: max_range_m " + std::to_string(config.max_range_m) +
                     " must exceed min_range_m " + std::to_string(config.min_range_m));
  }
  if (!(camera.fx > 0.0 && camera.fy > 0.0 && camera.width > 0 && camera.height > 0)) {
    throw InputError("seen_space: camera intrinsics must be positive (fx, fy, width, height)");
  }
  if (!R_B_C.allFinite() || !p_B_C_m.allFinite() || !(vehicle_radius_m >= 0.0)) {
    throw InputError("seen_space: camera extrinsics and vehicle radius must be finite");
  }
  bin_width_rad_ = kTwoPi / config.bins;
  memory_m_.fill(kNone);
}

int SeenSpaceLimiter::bin_of_fixed_azimuth(double azimuth_rad) const {
  double a = std::fmod(azimuth_rad, kTwoPi);
  if (a < 0.0) a += kTwoPi;
  const int b = static_cast<int>(a / bin_width_rad_);
  return std::clamp(b, 0, config_.bins - 1);
}

int SeenSpaceLimiter::bin_of_heading_azimuth(double azimuth_H_rad) const {
  return bin_of_fixed_azimuth(azimuth_H_rad + yaw_rad_);
}

double SeenSpaceLimiter::max_speed_mps(double free_m) const {
  const double stop_m = free_m - vehicle_radius_m_ - config_.margin_m;
  if (!(stop_m > 0.0)) return 0.0;
  const double a = config_.brake_accel_mps2;
  const double t_r = config_.reaction_s;
  // v t_r + v^2 / (2 a) = stop_m, the positive root.
  return a * (-t_r + std::sqrt(t_r * t_r + 2.0 * stop_m / a));
}

double SeenSpaceLimiter::max_speed_mps(double free_m, double v_now_mps) const {
  const double stop_m =
      free_m - vehicle_radius_m_ - config_.margin_m - std::max(0.0, v_now_mps) * config_.reaction_s;
  if (!(stop_m > 0.0)) return 0.0;
  return std::sqrt(2.0 * config_.brake_accel_mps2 * stop_m);
}

double SeenSpaceLimiter::free_distance_m(int b, bool* obstacle) const {
  if (obstacle != nullptr) *obstacle = false;
  if (b < 0 || b >= config_.bins) return -1.0;
  const auto i = static_cast<std::size_t>(b);
  const float seen_m = bins_[i].seen ? bins_[i].free_m : kNone;
  const float d = std::min(seen_m, memory_m_[i]);
  if (obstacle != nullptr) *obstacle = memory_m_[i] <= seen_m || bins_[i].obstacle;
  return std::isfinite(d) ? static_cast<double>(d) : -1.0;
}

void SeenSpaceLimiter::scan_depth(const cv::Mat& depth_m, const Eigen::Matrix3d& R_HC,
                                  const Eigen::Vector3d& o_H) {
  const auto n = static_cast<std::size_t>(config_.bins);
  std::fill_n(frame_obstacle_m_.begin(), n, kNone);
  std::fill_n(frame_free_m_.begin(), n, 0.0f);
  std::fill_n(frame_valid_.begin(), n, 0);
  std::fill_n(frame_total_.begin(), n, 0);
  const double band = config_.vertical_band_m;
  const double max_range = config_.max_range_m;
  const int stride = config_.pixel_stride;
  for (int v = stride / 2; v < depth_m.rows; v += stride) {
    const auto* row = depth_m.ptr<float>(v);
    for (int u = stride / 2; u < depth_m.cols; u += stride) {
      const Eigen::Vector3d ray_H = R_HC * camera_.ray(u, v);
      const float z = row[u];
      const bool valid =
          std::isfinite(z) && static_cast<double>(z) >= config_.min_range_m && z > 0.0f;
      if (!valid) {
        if (ray_H.head<2>().squaredNorm() < 1e-12) continue;  // straight down: no azimuth
        const auto b = static_cast<std::size_t>(
            bin_of_fixed_azimuth(std::atan2(ray_H.y(), ray_H.x()) + yaw_rad_));
        ++frame_total_[b];
        continue;
      }
      const Eigen::Vector3d p_H = o_H + static_cast<double>(z) * ray_H;
      const double r_m = p_H.head<2>().norm();
      if (r_m < 1e-6) continue;
      const auto b =
          static_cast<std::size_t>(bin_of_fixed_azimuth(std::atan2(p_H.y(), p_H.x()) + yaw_rad_));
      ++frame_total_[b];
      ++frame_valid_[b];
      if (std::abs(p_H.z()) <= band) {
        if (r_m <= max_range) {
          frame_obstacle_m_[b] = std::min(frame_obstacle_m_[b], static_cast<float>(r_m));
        } else {
          frame_free_m_[b] = static_cast<float>(max_range);
        }
        continue;
      }
      // Above or below the band: free until the ray left it (from the camera centre).
      double free_m = 0.0;
      if (std::abs(o_H.z()) <= band) {
        const double z_exit = p_H.z() > 0.0 ? band : -band;
        const double f = (z_exit - o_H.z()) / (p_H.z() - o_H.z());
        free_m = (o_H.head<2>() + f * (p_H.head<2>() - o_H.head<2>())).norm();
      }
      free_m = std::min(free_m, max_range);
      frame_free_m_[b] = std::max(frame_free_m_[b], static_cast<float>(free_m));
    }
  }
}

SeenSpaceUpdate SeenSpaceLimiter::update(std::int64_t t_ns, const cv::Mat& depth_m,
                                         const Eigen::Isometry3d* T_O_C,
                                         const Eigen::Matrix3d& R_H_B) {
  SeenSpaceUpdate out;
  t_now_ns_ = t_ns;
  memory_m_.fill(kNone);
  const auto n = static_cast<std::size_t>(config_.bins);
  // Ageing: what was not seen again for max_age_s is no data again.
  const auto max_age_ns = static_cast<std::int64_t>(config_.max_age_s * 1e9);
  for (std::size_t b = 0; b < n; ++b) {
    if (bins_[b].seen && t_ns - bins_[b].t_seen_ns > max_age_ns) bins_[b].seen = false;
  }
  if (!config_.enabled) {
    out.reason = "seen_space disabled";
    return out;
  }
  const bool pose_ok = T_O_C != nullptr && T_O_C->matrix().allFinite() && R_H_B.allFinite();
  if (!pose_ok) {
    pose_chain_broken_ = true;
    out.reason = "no pose";
    for (std::size_t b = 0; b < n; ++b) out.seen_bins += bins_[b].seen ? 1 : 0;
    return out;
  }

  // The pose of H in O, and of the body origin: R_H_O = R_H_B R_B_C R_C_O.
  const Eigen::Matrix3d R_O_C = T_O_C->linear();
  const Eigen::Matrix3d R_HC = R_H_B * R_B_C_;
  const Eigen::Matrix3d R_H_O = R_HC * R_O_C.transpose();
  const Eigen::Vector3d p_C_B = -R_B_C_.transpose() * p_B_C_m_;
  const Eigen::Vector3d p_O_B = *T_O_C * p_C_B;
  if (have_pose_ && pose_chain_broken_) {
    // Tracking came back: how far the vehicle turned and moved meanwhile is unknown.
    for (std::size_t b = 0; b < n; ++b) bins_[b].seen = false;
    have_pose_ = false;
  }
  if (!have_pose_) t_pose_since_ns_ = t_ns;
  pose_chain_broken_ = false;
  if (have_pose_) {
    // Yaw turns the bins: a world-fixed direction keeps its bin. R_Hcur_Hprev = Rz(-dpsi).
    const Eigen::Matrix3d R_cur_prev = R_H_O * R_H_O_prev_.transpose();
    yaw_rad_ = wrap_pi(yaw_rad_ + std::atan2(R_cur_prev(0, 1), R_cur_prev(0, 0)));
    const Eigen::Vector3d dp_H = R_H_O * (p_O_B - p_O_B_prev_);
    const double travel_m = dp_H.head<2>().norm();
    if (!(travel_m <= config_.max_pose_jump_m)) {
      for (std::size_t b = 0; b < n; ++b) bins_[b].seen = false;
    } else {
      // The distance to anything seen cannot have shrunk by more than the travel.
      const auto shrink = static_cast<float>(travel_m);
      for (std::size_t b = 0; b < n; ++b) {
        if (bins_[b].seen) bins_[b].free_m = std::max(0.0f, bins_[b].free_m - shrink);
      }
    }
  }
  have_pose_ = true;
  R_H_O_prev_ = R_H_O;
  p_O_B_prev_ = p_O_B;
  R_H_O_ = R_H_O;
  p_O_B_ = p_O_B;

  out.updated = true;
  if (depth_m.empty() || depth_m.type() != CV_32FC1 || depth_m.cols != camera_.width ||
      depth_m.rows != camera_.height) {
    out.reason = "depth missing or not camera-sized CV_32FC1";
    for (std::size_t b = 0; b < n; ++b) out.seen_bins += bins_[b].seen ? 1 : 0;
    return out;
  }

  const Eigen::Vector3d o_H = R_H_B * p_B_C_m_;  // camera centre from the body, in H
  scan_depth(depth_m, R_HC, o_H);
  for (std::size_t b = 0; b < n; ++b) {
    if (frame_total_[b] == 0) continue;  // outside the view: the kept value stands
    Bin& bin = bins_[b];
    if (std::isfinite(frame_obstacle_m_[b])) {
      bin.seen = true;
      bin.obstacle = true;
      bin.free_m = frame_obstacle_m_[b];
    } else if (static_cast<double>(frame_valid_[b]) >=
               config_.min_valid_fraction * static_cast<double>(frame_total_[b])) {
      bin.seen = true;
      bin.obstacle = false;
      bin.free_m = frame_free_m_[b];
    } else {
      bin.seen = false;  // the camera looks there and reads nothing: maybe too near
      continue;
    }
    bin.t_seen_ns = t_ns;
    ++out.covered_bins;
  }
  for (std::size_t b = 0; b < n; ++b) out.seen_bins += bins_[b].seen ? 1 : 0;
  return out;
}

void SeenSpaceLimiter::add_remembered_point(const Eigen::Vector3f& p_O_m, std::int64_t t_seen_ns) {
  if (!config_.enabled || !have_pose_ || pose_chain_broken_ || !p_O_m.allFinite()) return;
  if (t_seen_ns < t_pose_since_ns_) return;
  const Eigen::Vector3d p_H = R_H_O_ * (p_O_m.cast<double>() - p_O_B_);
  if (std::abs(p_H.z()) > config_.vertical_band_m) return;
  const double r_m = p_H.head<2>().norm();
  if (r_m > config_.max_range_m || r_m < 1e-6) return;
  const auto b =
      static_cast<std::size_t>(bin_of_fixed_azimuth(std::atan2(p_H.y(), p_H.x()) + yaw_rad_));
  memory_m_[b] = std::min(memory_m_[b], static_cast<float>(r_m));
}

LimitedCommand SeenSpaceLimiter::limit(const Eigen::Vector3d& v_H_mps,
                                       const std::optional<Eigen::Vector3d>& v_est_H_mps) const {
  LimitedCommand out;
  if (!v_H_mps.allFinite()) {
    out.limited = true;
    return out;  // zero
  }
  out.v_H_mps = v_H_mps;
  const double speed = v_H_mps.head<2>().norm();
  out.v_max_mps = std::numeric_limits<double>::infinity();
  if (!config_.enabled || speed < 1e-9) return out;
  const double heading = std::atan2(v_H_mps.y(), v_H_mps.x()) + yaw_rad_;
  const double window = config_.no_data_half_angle_deg * M_PI / 180.0 + 0.5 * bin_width_rad_;
  double v_max = out.v_max_mps;
  bool unseen = false;
  const bool have_v_est = v_est_H_mps.has_value() && v_est_H_mps->head<2>().allFinite();
  for (int b = 0; b < config_.bins; ++b) {
    const double theta = wrap_pi((b + 0.5) * bin_width_rad_ - heading);
    bool obstacle = false;
    const double d = free_distance_m(b, &obstacle);
    if (d >= 0.0 && obstacle) {
      const double c = std::cos(theta);
      if (c <= 1e-3) continue;
      double v_bin = max_speed_mps(d);
      if (have_v_est) {
        // The vehicle's own speed towards this bin flies the reaction distance.
        const double a = (b + 0.5) * bin_width_rad_ - yaw_rad_;  // the bin's azimuth in H
        v_bin = max_speed_mps(d, v_est_H_mps->x() * std::cos(a) + v_est_H_mps->y() * std::sin(a));
      }
      v_max = std::min(v_max, v_bin / c);
      continue;
    }
    if (std::abs(theta) > window) continue;
    // Free up to d at most, then unknown; no data: unknown from here.
    const double v_bin = std::max(config_.creep_speed_mps, d >= 0.0 ? max_speed_mps(d) : 0.0);
    if (v_bin < v_max) {
      v_max = v_bin;
      unseen = v_bin <= config_.creep_speed_mps;
    }
  }
  out.v_max_mps = v_max;
  if (speed > v_max) {
    const double scale = v_max / speed;
    out.v_H_mps.x() *= scale;
    out.v_H_mps.y() *= scale;
    out.limited = true;
    out.unseen = unseen && v_max <= config_.creep_speed_mps;
  }
  return out;
}

void SeenSpaceLimiter::heading_limits(std::array<float, kMaxBins>& out_mps) const {
  for (int i = 0; i < config_.bins; ++i) {
    const int b = bin_of_heading_azimuth((i + 0.5) * bin_width_rad_);
    const double d = free_distance_m(b);
    out_mps[static_cast<std::size_t>(i)] =
        static_cast<float>(d >= 0.0 ? max_speed_mps(d) : config_.creep_speed_mps);
  }
}

}  // namespace hq::seen_space
