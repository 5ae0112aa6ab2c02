#include "hq/obstacles/obstacle_field.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/obstacles/support_surface.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <string>

namespace hq::obstacles {
namespace {
constexpr int kMaxSpeckleRank = 8;
// Distances are floored here so that a point at the sensor does not give an infinite push;
// the sum is saturated anyway.
constexpr double kMinDistanceM = 0.05;
constexpr float kInf = std::numeric_limits<float>::infinity();

bool is_valid_depth(float z) { return std::isfinite(z) && z > 0.0f; }
// Row-major index of pixel (u, v) or cell (cx, cy); both are >= 0 and image sizes fit an int.
std::size_t flat_index(int x, int y, int width) {
  return static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
         static_cast<std::size_t>(x);
}
}  // namespace

void read_config(config::StrictMap& section, ObstacleConfig& out) {
  section.read("cell_px", out.cell_px, 1, 256);
  section.read("speckle_rank", out.speckle_rank, 1, kMaxSpeckleRank);
  section.read_positive("suppression_radius_px", out.suppression_radius_px, 10000.0);
  section.read("vehicle_radius_m", out.vehicle_radius_m, 0.0, 5.0);
  section.read_positive("influence_distance_m", out.influence_distance_m, 100.0);
  section.read_positive("max_repulsive_speed_mps", out.max_repulsive_speed_mps, 20.0);
  // Zero gain is no avoidance at all (1515 collision ticks in the core-paper flight): not a
  // setting. Turning avoidance off is influence_distance_m at its smallest.
  section.read_positive("gain", out.gain, 100.0);
  section.read("support_normal_max_deg", out.support_normal_max_deg, 0.0, 90.0);
  section.read("support_influence_m", out.support_influence_m, 0.0, 10.0);
  section.read("min_range_m", out.min_range_m, 0.0, 10.0);
  section.read_positive("max_range_m", out.max_range_m, 100.0);
  section.read("near_invalid_fraction", out.near_invalid_fraction, 0.0, 1.0);
  section.read("central_window_fraction", out.central_window_fraction, 0.01, 1.0);
  section.read("max_points", out.max_points, 0, kMaxObstaclePoints);
  section.finish();
}

void check_camera(const char* component, const geometry::PinholeCamera& camera,
                  const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m) {
  if (camera.width <= 0 || camera.height <= 0 || !(camera.fx > 0.0) || !(camera.fy > 0.0)) {
    throw InputError(std::string(component) + ": camera " + std::to_string(camera.width) + "x" +
                     std::to_string(camera.height) + " fx " + std::to_string(camera.fx) +
                     ", expected a positive size and focal length");
  }
  if (!R_B_C.allFinite() || !p_B_C_m.allFinite() ||
      (R_B_C.transpose() * R_B_C - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6) {
    throw InputError(std::string(component) + ": R_B_C is not a rotation");
  }
}

ObstacleField::ObstacleField(const ObstacleConfig& config, const geometry::PinholeCamera& camera,
                             const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m)
    : config_(config), camera_(camera), R_B_C_(R_B_C), p_B_C_m_(p_B_C_m) {
  check_camera("obstacles", camera, R_B_C, p_B_C_m);
  if (config.cell_px < 1 || config.cell_px > std::min(camera.width, camera.height)) {
    throw InputError("obstacles.cell_px = " + std::to_string(config.cell_px) +
                     ", expected in [1, " + std::to_string(std::min(camera.width, camera.height)) +
                     "] for this camera");
  }
  if (config.max_points < 0 || config.max_points > kMaxObstaclePoints || config.speckle_rank < 1 ||
      config.speckle_rank > kMaxSpeckleRank) {
    throw InputError("obstacles: max_points = " + std::to_string(config.max_points) +
                     ", speckle_rank = " + std::to_string(config.speckle_rank) +
                     ", expected max_points <= " + std::to_string(kMaxObstaclePoints) +
                     " and speckle_rank in [1, " + std::to_string(kMaxSpeckleRank) + "]");
  }
  cells_x_ = camera.width / config.cell_px;
  cells_y_ = camera.height / config.cell_px;
  radius_cells_ = static_cast<int>(std::ceil(config.suppression_radius_px / config.cell_px));
  ray_norm_.resize(static_cast<std::size_t>(camera.width) *
                   static_cast<std::size_t>(camera.height));
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      ray_norm_[flat_index(u, v, camera.width)] = static_cast<float>(camera.ray(u, v).norm());
    }
  }
  cells_.resize(static_cast<std::size_t>(cells_x_) * static_cast<std::size_t>(cells_y_));
  minima_.reserve(cells_.size());
  support_z_m_.reserve(cells_.size());
}

void ObstacleField::add_point(ObstacleResult& result, const Eigen::Vector3d& p_H, bool hazard,
                              bool remembered) const {
  const double range = p_H.norm();
  const double d = std::max(range - config_.vehicle_radius_m, kMinDistanceM);
  const double d0 = config_.influence_distance_m;
  const double clearance_m = std::max(range - config_.vehicle_radius_m, 0.0);
  if (result.min_clearance_m < 0.0 || clearance_m < result.min_clearance_m) {
    result.min_clearance_m = clearance_m;
  }
  if (d >= d0 || !(range > 0.0)) return;
  // Khatib 1986 on the clearance d: U = eta/2 (1/d - 1/d0)^2, v = -grad U, along -p/|p|.
  const double speed = config_.gain * (1.0 / d - 1.0 / d0) / (d * d);
  result.v_obs_H_mps -= speed * p_H / range;
  if (result.count < config_.max_points) {
    ObstaclePoint& point = result.points[static_cast<std::size_t>(result.count++)];
    point.p_H_m = p_H;
    point.distance_m = p_H.norm();
    point.near_hazard = hazard;
    point.remembered = remembered;
  }
}

void ObstacleField::add_support_push(ObstacleResult& result, double height_m) const {
  const double height = std::max(height_m, kMinDistanceM);
  if (ground_phase_ || height >= config_.support_influence_m) return;
  // Upwards only, on the height above the surface.
  result.v_obs_H_mps.z() -=
      config_.gain * (1.0 / height - 1.0 / config_.support_influence_m) / (height * height);
}

Eigen::Vector3d ObstacleField::cell_point_C(const Cell& cell) const {
  const double z = cell.range_m / ray_norm_[flat_index(cell.u, cell.v, camera_.width)];
  return camera_.unproject(cell.u, cell.v, z);
}

bool ObstacleField::on_support_surface(const cv::Mat& depth_m, int u, int v,
                                       const Eigen::Matrix3d& R_HC,
                                       const Eigen::Vector3d& p_H) const {
  if (!(p_H.z() > 0.0)) return false;
  const auto point_at = [&](int pu, int pv, Eigen::Vector3d& p) {
    const float z = depth_m.ptr<float>(pv)[pu];
    if (!is_valid_depth(z)) return false;
    p = camera_.unproject(static_cast<double>(pu), static_cast<double>(pv), static_cast<double>(z));
    return true;
  };
  Eigen::Vector3d centre, normal_C;
  if (!point_at(u, v, centre)) return false;
  // Neighbours half a cell away.
  const int step = std::max(1, config_.cell_px / 2);
  if (!surface_normal_C(point_at, u, v, camera_.width, camera_.height, step,
                        NormalStencil::kCentralWhereBoth, centre, normal_C)) {
    return false;
  }
  return is_support_normal(R_HC, normal_C,
                           std::cos(config_.support_normal_max_deg * std::numbers::pi / 180.0));
}

double ObstacleField::floor_height(const cv::Mat& depth_m, const Eigen::Matrix3d& R_HC,
                                   const Eigen::Vector3d& p_HC) {
  // A camera looking down sees the floor in its lower rows; each cell's nearest point that
  // lies on a near-horizontal surface below the body gives that surface's depth below it. The
  // floor is the lowest such surface (a table top is higher); a lone deepest cell may be noise,
  // so the answer is the deepest value that two more cells confirm within kFloorAgreeM.
  constexpr double kFloorAgreeM = 0.05;
  support_z_m_.clear();
  for (int cy = cells_y_ / 2; cy < cells_y_; ++cy) {
    for (int cx = 0; cx < cells_x_; ++cx) {
      const Cell& cell = cells_[flat_index(cx, cy, cells_x_)];
      if (!std::isfinite(cell.range_m)) continue;
      const Eigen::Vector3d p_H = R_HC * cell_point_C(cell) + p_HC;
      if (on_support_surface(depth_m, cell.u, cell.v, R_HC, p_H)) support_z_m_.push_back(p_H.z());
    }
  }
  std::sort(support_z_m_.begin(), support_z_m_.end(), std::greater<>());
  for (std::size_t i = 0; i + 2 < support_z_m_.size(); ++i) {
    if (support_z_m_[i] - support_z_m_[i + 2] < kFloorAgreeM) return support_z_m_[i + 1];
  }
  return std::numeric_limits<double>::quiet_NaN();
}

void ObstacleField::min_pool(const cv::Mat& depth_m) {
  // A cell's value is the k-th smallest valid range (distance along the ray, not z, so that a
  // fronto-parallel wall has one nearest point): fewer than k pixels nearer than the rest, i.e.
  // isolated speckle, cannot make a cell near.
  const auto k = static_cast<std::size_t>(config_.speckle_rank);  // in [1, kMaxSpeckleRank]
  const auto max_range = static_cast<float>(config_.max_range_m);
  for (int cy = 0; cy < cells_y_; ++cy) {
    for (int cx = 0; cx < cells_x_; ++cx) {
      std::array<float, kMaxSpeckleRank> smallest;
      std::array<int, kMaxSpeckleRank> smallest_index;
      std::size_t n = 0;
      for (int v = cy * config_.cell_px; v < (cy + 1) * config_.cell_px; ++v) {
        const auto* row = depth_m.ptr<float>(v);
        const float* norms = &ray_norm_[flat_index(0, v, camera_.width)];
        for (int u = cx * config_.cell_px; u < (cx + 1) * config_.cell_px; ++u) {
          const float z = row[u];
          if (!is_valid_depth(z) || z > max_range) continue;
          const float range = z * norms[u];
          if (n == k && range >= smallest[k - 1]) continue;
          // Insertion into the sorted k smallest.
          std::size_t i = (n < k) ? n++ : k - 1;
          while (i > 0 && smallest[i - 1] > range) {
            smallest[i] = smallest[i - 1];
            smallest_index[i] = smallest_index[i - 1];
            --i;
          }
          smallest[i] = range;
          smallest_index[i] = v * camera_.width + u;
        }
      }
      Cell& cell = cells_[flat_index(cx, cy, cells_x_)];
      if (n == k) {
        cell.range_m = smallest[k - 1];
        cell.u = smallest_index[k - 1] % camera_.width;
        cell.v = smallest_index[k - 1] / camera_.width;
      } else {
        cell.range_m = kInf;
      }
    }
  }
}

bool ObstacleField::check_near_range(const cv::Mat& depth_m, const Eigen::Matrix3d& R_HC,
                                     const Eigen::Vector3d& p_HC, ObstacleResult& result) const {
  // A structured-light sensor returns nothing for surfaces nearer than its minimum range,
  // which must not read as free space.
  const int window_w =
      std::max(1, static_cast<int>(config_.central_window_fraction * camera_.width));
  const int window_h =
      std::max(1, static_cast<int>(config_.central_window_fraction * camera_.height));
  const int u0 = (camera_.width - window_w) / 2;
  const int v0 = (camera_.height - window_h) / 2;
  int invalid = 0;
  int nan = 0;
  for (int v = v0; v < v0 + window_h; ++v) {
    const auto* row = depth_m.ptr<float>(v);
    for (int u = u0; u < u0 + window_w; ++u) {
      invalid += is_valid_depth(row[u]) ? 0 : 1;
      nan += std::isnan(row[u]) ? 1 : 0;
    }
  }
  result.nan_fraction = static_cast<double>(nan) / (window_w * window_h);
  if (result.nan_fraction > 0.5) {
    result.reason = "depth frame corrupt: mostly NaN";
    return false;
  }
  result.central_invalid_fraction = static_cast<double>(invalid) / (window_w * window_h);
  result.near_hazard = result.central_invalid_fraction > config_.near_invalid_fraction;
  if (result.near_hazard && !ground_phase_) {
    add_point(result, R_HC * Eigen::Vector3d(0.0, 0.0, config_.min_range_m) + p_HC, true);
  }
  return true;
}

void ObstacleField::find_minima() {
  // Local minima within the suppression radius; ties go to the lower index so that a plateau
  // yields one point. Every cell with a range (out to max_range_m) is a candidate: those beyond
  // d0 push nothing but still give the clearance (ClearanceFilter), which the operator sees
  // whenever an obstacle is in view, not only once it pushes.
  minima_.clear();
  const int r2 = radius_cells_ * radius_cells_;
  for (int cy = 0; cy < cells_y_; ++cy) {
    for (int cx = 0; cx < cells_x_; ++cx) {
      const int index = cy * cells_x_ + cx;
      const float range = cells_[static_cast<std::size_t>(index)].range_m;
      if (!std::isfinite(range)) continue;
      bool is_minimum = true;
      for (int dy = -radius_cells_; dy <= radius_cells_ && is_minimum; ++dy) {
        const int ny = cy + dy;
        if (ny < 0 || ny >= cells_y_) continue;
        for (int dx = -radius_cells_; dx <= radius_cells_; ++dx) {
          const int nx = cx + dx;
          if (nx < 0 || nx >= cells_x_ || dx * dx + dy * dy > r2 || (dx == 0 && dy == 0)) continue;
          const int other = ny * cells_x_ + nx;
          const float other_range = cells_[static_cast<std::size_t>(other)].range_m;
          if (other_range < range || (other_range == range && other < index)) {
            is_minimum = false;
            break;
          }
        }
      }
      if (is_minimum) minima_.push_back(index);
    }
  }
  // Nearest first, so that max_points keeps the ones that matter.
  std::sort(minima_.begin(), minima_.end(), [this](int a, int b) {
    return cells_[static_cast<std::size_t>(a)].range_m <
           cells_[static_cast<std::size_t>(b)].range_m;
  });
}

void ObstacleField::push_from_minima(const cv::Mat& depth_m, const Eigen::Matrix3d& R_HC,
                                     const Eigen::Vector3d& p_HC, ObstacleResult& result) const {
  for (const int index : minima_) {
    const Cell& cell = cells_[static_cast<std::size_t>(index)];
    const Eigen::Vector3d p_H = R_HC * cell_point_C(cell) + p_HC;
    // Taking off or landing, whatever is below the vehicle is the floor it leaves or seeks.
    if (ground_phase_ && p_H.z() > 0.0) continue;
    if (on_support_surface(depth_m, cell.u, cell.v, R_HC, p_H)) {
      // Upwards only, on the height above the surface.
      add_support_push(result, p_H.z());
      continue;
    }
    add_point(result, p_H, false);
  }
}

void ObstacleField::push_from_remembered(std::span<const Eigen::Vector3d> p_H_m,
                                         ObstacleResult& result) const {
  // The same Khatib term per point, after the view's minima so that the listed points stay
  // nearest-first within the view.
  for (const Eigen::Vector3d& p_H : p_H_m) {
    if (!p_H.allFinite() || (ground_phase_ && p_H.z() > 0.0)) continue;
    // The memory keeps only points in a band around the vehicle's height (floor and ceiling
    // excluded there), and a camera looking 30 deg down remembers an obstacle by its face below
    // the vehicle: the point stands for a column, so it pushes horizontally, on its horizontal
    // offset.
    add_point(result, Eigen::Vector3d(p_H.x(), p_H.y(), 0.0), false, true);
  }
}

ObstacleResult ObstacleField::compute(const cv::Mat& depth_m,
                                      const Eigen::Matrix3d& R_H_B_from_tilt,
                                      std::span<const Eigen::Vector3d> remembered_p_H_m) {
  ObstacleResult result;
  if (depth_m.type() != CV_32FC1 || depth_m.cols != camera_.width ||
      depth_m.rows != camera_.height) {
    result.reason = "depth image is not CV_32FC1 of the camera's size";
    return result;
  }
  if (!R_H_B_from_tilt.allFinite()) {
    result.reason = "R_H_B_from_tilt is not finite";
    return result;
  }
  const Eigen::Matrix3d R_HC = R_H_B_from_tilt * R_B_C_;
  const Eigen::Vector3d p_HC = R_H_B_from_tilt * p_B_C_m_;
  min_pool(depth_m);
  result.floor_height_m = floor_height(depth_m, R_HC, p_HC);
  if (!check_near_range(depth_m, R_HC, p_HC, result)) return result;
  find_minima();
  push_from_minima(depth_m, R_HC, p_HC, result);
  push_from_remembered(remembered_p_H_m, result);

  const double speed = result.v_obs_H_mps.norm();
  if (speed > config_.max_repulsive_speed_mps) {
    result.v_obs_H_mps *= config_.max_repulsive_speed_mps / speed;
  }
  result.valid = true;
  return result;
}

}  // namespace hq::obstacles
