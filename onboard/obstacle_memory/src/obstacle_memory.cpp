#include "hq/obstacle_memory/obstacle_memory.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/obstacles/obstacle_field.hpp"
#include "hq/obstacles/support_surface.hpp"

#include "point_cloud_file.hpp"
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace hq::obstacle_memory {
namespace {
constexpr int kNormalStepPx = 8;  // support-surface normals, see voxelise()
// Voxel indices are packed 21 bits per axis, offset so that every stored field is >= 1 and
// <= 2^21 - 2: neighbour keys are then key +- one field unit, and key 0 marks an empty slot.
constexpr int kKeyBits = 21;
constexpr std::int64_t kKeyOffset = std::int64_t{1} << (kKeyBits - 1);
constexpr std::int64_t kKeyLimit = kKeyOffset - 2;
constexpr std::uint64_t kEmptyKey = 0;
constexpr float kInf = std::numeric_limits<float>::infinity();

std::size_t power_of_two_at_least(std::size_t n) {
  std::size_t size = 16;
  while (size < n) size *= 2;
  return size;
}

std::size_t hash_slot(std::uint64_t key, std::size_t mask) {
  // Fibonacci hashing: neighbouring voxels spread over the table.
  return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ULL) >> 20) & mask;
}

bool valid_depth(float z) { return std::isfinite(z) && z > 0.0f; }

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}
}  // namespace

namespace {

/// Throws "<name(key)> = <value>, expected <what>" unless ok.
template <typename T>
void expect(bool ok, const ConfigKeyName& name, const char* key, T value, const std::string& what) {
  if (ok) return;
  std::ostringstream message;
  message << name(key) << " = " << value << ", expected " << what;
  throw InputError(message.str());
}

constexpr double kRadPerDeg = M_PI / 180.0;

}  // namespace

void validate(const MemoryConfig& c, const ConfigKeyName& name_or_default) {
  const ConfigKeyName name =
      name_or_default ? name_or_default
                      : ConfigKeyName([](const std::string& key) { return "memory." + key; });
  expect(c.leaf_m > 0.0 && c.leaf_m <= 10.0, name, "leaf_m", c.leaf_m, "in (0, 10]");
  expect(c.pixel_stride >= 1 && c.pixel_stride <= 64, name, "pixel_stride", c.pixel_stride,
         "in [1, 64]");
  expect(c.min_range_m >= 0.0 && c.min_range_m <= 10.0, name, "min_range_m", c.min_range_m,
         "in [0, 10]");
  expect(c.max_range_m > 0.0 && c.max_range_m <= 100.0, name, "max_range_m", c.max_range_m,
         "in (0, 100]");
  expect(c.max_range_m > c.min_range_m, name, "max_range_m", c.max_range_m,
         "> min_range_m (" + std::to_string(c.min_range_m) + ")");
  expect(c.min_neighbors >= 0 && c.min_neighbors <= 26, name, "min_neighbors", c.min_neighbors,
         "in [0, 26]");
  expect(c.max_age_s > 0.0 && c.max_age_s <= 3600.0, name, "max_age_s", c.max_age_s,
         "in (0, 3600]");
  expect(c.radius_m > 0.0 && c.radius_m <= 100.0, name, "radius_m", c.radius_m, "in (0, 100]");
  expect(c.capacity >= 1 && c.capacity <= 1000000, name, "capacity", c.capacity, "in [1, 1000000]");
  expect(c.max_pose_jump_m > 0.0 && c.max_pose_jump_m <= 100.0, name, "max_pose_jump_m",
         c.max_pose_jump_m, "in (0, 100]");
  expect(c.max_pose_jump_rad >= 0.1 * kRadPerDeg && c.max_pose_jump_rad <= 180.0 * kRadPerDeg, name,
         "max_pose_jump_deg", c.max_pose_jump_rad / kRadPerDeg, "in [0.1, 180]");
  expect(c.vertical_band_m > 0.0 && c.vertical_band_m <= 100.0, name, "vertical_band_m",
         c.vertical_band_m, "in (0, 100]");
  expect(c.support_normal_max_rad >= 0.0 && c.support_normal_max_rad <= 90.0 * kRadPerDeg, name,
         "support_normal_max_deg", c.support_normal_max_rad / kRadPerDeg, "in [0, 90]");
  expect(c.sectors >= 3 && c.sectors <= 360, name, "sectors", c.sectors, "in [3, 360]");
  expect(c.max_points >= 0 && c.max_points <= kMaxRememberedPoints, name, "max_points",
         c.max_points, "in [0, " + std::to_string(kMaxRememberedPoints) + "]");
}

void read_config(config::StrictMap& section, MemoryConfig& out) {
  // The getters check types; validate() checks every range, as the constructor does.
  constexpr double kAny = std::numeric_limits<double>::max();
  constexpr int kAnyInt = std::numeric_limits<int>::max();
  section.read("enabled", out.enabled);
  section.read("leaf_m", out.leaf_m, -kAny, kAny);
  section.read("pixel_stride", out.pixel_stride, -kAnyInt, kAnyInt);
  section.read("min_range_m", out.min_range_m, -kAny, kAny);
  section.read("max_range_m", out.max_range_m, -kAny, kAny);
  section.read("min_neighbors", out.min_neighbors, -kAnyInt, kAnyInt);
  section.read("max_age_s", out.max_age_s, -kAny, kAny);
  section.read("radius_m", out.radius_m, -kAny, kAny);
  section.read("capacity", out.capacity, -kAnyInt, kAnyInt);
  section.read("max_pose_jump_m", out.max_pose_jump_m, -kAny, kAny);
  section.read_deg_as_rad("max_pose_jump_deg", out.max_pose_jump_rad, -kAny, kAny);
  section.read("vertical_band_m", out.vertical_band_m, -kAny, kAny);
  section.read_deg_as_rad("support_normal_max_deg", out.support_normal_max_rad, -kAny, kAny);
  section.read("sectors", out.sectors, -kAnyInt, kAnyInt);
  section.read("max_points", out.max_points, -kAnyInt, kAnyInt);
  validate(out, [&section](const std::string& key) { return section.describe(key); });
  section.finish();
}

ObstacleMemory::ObstacleMemory(const MemoryConfig& config, const geometry::PinholeCamera& camera,
                               const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m)
    : config_(config), camera_(camera), R_B_C_(R_B_C), p_B_C_m_(p_B_C_m) {
  obstacles::check_camera("memory", camera, R_B_C, p_B_C_m);
  validate(config);
  inv_leaf_ = static_cast<float>(1.0 / config.leaf_m);
  // Rays per column and row (x/z, y/z): the back-projection of the sampling loop is then two
  // multiplications per sample, as before PinholeCamera, and no division.
  ray_x_.resize(static_cast<std::size_t>(camera.width));
  ray_y_.resize(static_cast<std::size_t>(camera.height));
  for (int u = 0; u < camera.width; ++u) {
    ray_x_[static_cast<std::size_t>(u)] = static_cast<float>(camera.ray(u, 0).x());
  }
  for (int v = 0; v < camera.height; ++v) {
    ray_y_[static_cast<std::size_t>(v)] = static_cast<float>(camera.ray(0, v).y());
  }
  const std::size_t samples =
      static_cast<std::size_t>((camera.width + config.pixel_stride - 1) / config.pixel_stride) *
      static_cast<std::size_t>((camera.height + config.pixel_stride - 1) / config.pixel_stride);
  frame_table_.assign(power_of_two_at_least(2 * samples),
                      FrameVoxel{kEmptyKey, Eigen::Vector3f::Zero(), 0});
  frame_used_.reserve(samples);
  kept_voxels_.reserve(samples);
  entries_.reserve(static_cast<std::size_t>(config.capacity));
  map_table_.assign(power_of_two_at_least(2 * static_cast<std::size_t>(config.capacity)), -1);
  sector_distance_m_.assign(static_cast<std::size_t>(config.sectors), kInf);
  sector_point_.assign(static_cast<std::size_t>(config.sectors), Eigen::Vector3d::Zero());
  sector_order_.reserve(static_cast<std::size_t>(config.sectors));
}

bool ObstacleMemory::key_of(const Eigen::Vector3f& p_O_m, std::uint64_t& key) const {
  std::uint64_t packed = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const float scaled = std::floor(p_O_m[axis] * inv_leaf_);
    if (!(std::abs(scaled) < static_cast<float>(kKeyLimit))) return false;
    const auto field = static_cast<std::uint64_t>(static_cast<std::int64_t>(scaled) + kKeyOffset);
    packed = (packed << kKeyBits) | field;
  }
  key = packed;
  return true;
}

int ObstacleMemory::frame_slot(std::uint64_t key, bool insert) {
  const std::size_t mask = frame_table_.size() - 1;
  for (std::size_t slot = hash_slot(key, mask);; slot = (slot + 1) & mask) {
    FrameVoxel& voxel = frame_table_[slot];
    if (voxel.key == key) return static_cast<int>(slot);
    if (voxel.key == kEmptyKey) {
      if (!insert) return -1;
      voxel.key = key;
      voxel.sum_m.setZero();
      voxel.n = 0;
      frame_used_.push_back(static_cast<int>(slot));
      return static_cast<int>(slot);
    }
  }
}

int ObstacleMemory::map_index(std::uint64_t key) const {
  const std::size_t mask = map_table_.size() - 1;
  for (std::size_t slot = hash_slot(key, mask);; slot = (slot + 1) & mask) {
    const int index = map_table_[slot];
    if (index < 0) return -1;
    if (entries_[static_cast<std::size_t>(index)].key == key) return index;
  }
}

void ObstacleMemory::rebuild_map_table() {
  std::fill(map_table_.begin(), map_table_.end(), -1);
  const std::size_t mask = map_table_.size() - 1;
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    std::size_t slot = hash_slot(entries_[i].key, mask);
    while (map_table_[slot] >= 0) slot = (slot + 1) & mask;
    map_table_[slot] = static_cast<int>(i);
  }
}

void ObstacleMemory::clear() { entries_.clear(); }

std::size_t ObstacleMemory::memory_bytes() const {
  return frame_table_.capacity() * sizeof(FrameVoxel) + frame_used_.capacity() * sizeof(int) +
         kept_voxels_.capacity() * sizeof(MapPoint) + entries_.capacity() * sizeof(MapPoint) +
         map_table_.capacity() * sizeof(int) + sector_distance_m_.capacity() * sizeof(float) +
         sector_point_.capacity() * sizeof(Eigen::Vector3d) +
         sector_order_.capacity() * sizeof(int) +
         (ray_x_.capacity() + ray_y_.capacity()) * sizeof(float);
}

void ObstacleMemory::forget_on_pose_jump(const Eigen::Isometry3d& T_O_C, MemoryUpdate& out) {
  // A jump of the estimate (odometry re-initialised, or a wrong alignment) would misplace every
  // remembered point relative to the vehicle: forget them rather than push from ghosts.
  if (have_pose_) {
    const Eigen::Isometry3d step = T_O_C_prev_.inverse() * T_O_C;
    const double angle_rad = Eigen::AngleAxisd(step.linear()).angle();
    if (step.translation().norm() > config_.max_pose_jump_m ||
        angle_rad > config_.max_pose_jump_rad) {
      clear();
      ++clear_count_;
      out.cleared = true;
      out.clear_count = clear_count_;
    }
  }
  T_O_C_prev_ = T_O_C;
  have_pose_ = true;
}

void ObstacleMemory::voxelise(const cv::Mat& depth_m, const Eigen::Isometry3d& T_O_C,
                              const Eigen::Matrix3d& R_H_B) {
  // Valid depth into points in O, averaged per voxel (the effect of pcl::VoxelGrid, which
  // allocates and sorts on every call; a hash into a table sized once does neither).
  for (const int slot : frame_used_) frame_table_[static_cast<std::size_t>(slot)].key = kEmptyKey;
  frame_used_.clear();
  const Eigen::Matrix3f R_O_C = T_O_C.linear().cast<float>();
  const Eigen::Vector3f p_O_C = T_O_C.translation().cast<float>();
  const auto min_z = static_cast<float>(config_.min_range_m);
  const auto max_z = static_cast<float>(config_.max_range_m);
  const int stride = config_.pixel_stride;
  // Support surfaces: the normal from neighbouring samples, in H (gravity-aligned).
  const Eigen::Matrix3f R_H_C = (R_H_B * R_B_C_).cast<float>();
  const auto cos_max_tilt = static_cast<float>(std::cos(config_.support_normal_max_rad));
  const auto point_at = [&](int pu, int pv, Eigen::Vector3f& p_C) {
    const float z = depth_m.ptr<float>(pv)[pu];
    if (!(std::isfinite(z) && z >= min_z && z <= max_z)) return false;
    p_C = Eigen::Vector3f(ray_x_[static_cast<std::size_t>(pu)] * z,
                          ray_y_[static_cast<std::size_t>(pv)] * z, z);
    return true;
  };
  // Neighbouring samples mostly share a voxel: reuse the last slot instead of hashing again.
  std::uint64_t last_key = kEmptyKey;
  FrameVoxel* last_voxel = nullptr;
  for (int v = 0; v < camera_.height; v += stride) {
    for (int u = 0; u < camera_.width; u += stride) {
      Eigen::Vector3f p_C, n_C;
      if (!point_at(u, v, p_C)) continue;
      // One-sided differences kNormalStepPx apart: at 1 m a structured-light sensor quantises
      // depth in ~2 mm steps, which over adjacent pixels (3 mm apart) tilts a floor's normal by
      // tens of degrees. Without a normal the sample is unknown surface, most often the ragged
      // edge of depth at the sensor's minimum range on the floor ahead: not remembered.
      if (!obstacles::surface_normal_C(point_at, u, v, camera_.width, camera_.height, kNormalStepPx,
                                       obstacles::NormalStencil::kOneSided, p_C, n_C) ||
          obstacles::is_support_normal(R_H_C, n_C, cos_max_tilt)) {
        continue;
      }
      const Eigen::Vector3f p_O = R_O_C * p_C + p_O_C;
      std::uint64_t key = 0;
      if (!key_of(p_O, key)) continue;
      if (key != last_key) {
        last_key = key;
        last_voxel = &frame_table_[static_cast<std::size_t>(frame_slot(key, true))];
      }
      last_voxel->sum_m += p_O;
      ++last_voxel->n;
    }
  }
}

int ObstacleMemory::remove_speckle(std::int64_t t_ns) {
  // Radius outlier removal on the voxel grid. A voxel is kept when at least min_neighbors of its
  // 26 neighbours are occupied (pcl::RadiusOutlierRemoval with a radius of about one voxel
  // diagonal). Chosen over StatisticalOutlierRemoval because the voxel grid already makes the
  // spacing uniform, so a fixed-radius count separates isolated flying pixels from surfaces,
  // and the hash answers it in O(1) without a k-d tree.
  int removed = 0;
  kept_voxels_.clear();
  for (const int slot : frame_used_) {
    const FrameVoxel& voxel = frame_table_[static_cast<std::size_t>(slot)];
    int neighbors = 0;
    for (int dx = -1; dx <= 1 && neighbors < config_.min_neighbors; ++dx) {
      for (int dy = -1; dy <= 1 && neighbors < config_.min_neighbors; ++dy) {
        for (int dz = -1; dz <= 1 && neighbors < config_.min_neighbors; ++dz) {
          if (dx == 0 && dy == 0 && dz == 0) continue;
          const std::int64_t offset = (static_cast<std::int64_t>(dx) << (2 * kKeyBits)) +
                                      (static_cast<std::int64_t>(dy) << kKeyBits) + dz;
          const std::uint64_t neighbor = voxel.key + static_cast<std::uint64_t>(offset);
          if (frame_slot(neighbor, false) >= 0) ++neighbors;
        }
      }
    }
    if (neighbors < config_.min_neighbors) {
      ++removed;
      continue;
    }
    kept_voxels_.push_back(MapPoint{voxel.sum_m / static_cast<float>(voxel.n), t_ns, voxel.key});
  }
  return removed;
}

void ObstacleMemory::age_and_pool(std::int64_t t_ns, const cv::Mat& depth_m,
                                  const Eigen::Isometry3d& T_O_C, const Eigen::Matrix3d& R_H_B,
                                  double influence_distance_m) {
  // One pass compacts the map in place (age, radius, view) and min-pools the remembered points
  // outside the view into azimuth sectors of H.
  const Eigen::Isometry3d T_C_O = T_O_C.inverse();
  const Eigen::Matrix3f R_C_O = T_C_O.linear().cast<float>();
  const Eigen::Vector3f p_C_O = T_C_O.translation().cast<float>();
  const Eigen::Vector3f p_O_B = (T_O_C * (-R_B_C_.transpose() * p_B_C_m_)).cast<float>();
  const Eigen::Matrix3d R_H_C = R_H_B * R_B_C_;
  const Eigen::Vector3d p_H_C = R_H_B * p_B_C_m_;
  const auto radius2 = static_cast<float>(config_.radius_m * config_.radius_m);
  const auto max_age_ns = static_cast<std::int64_t>(config_.max_age_s * 1e9);
  const auto leaf = static_cast<float>(config_.leaf_m);
  std::fill(sector_distance_m_.begin(), sector_distance_m_.end(), kInf);
  const double sectors_per_rad = config_.sectors / (2.0 * M_PI);
  std::size_t kept = 0;
  for (const MapPoint& entry : entries_) {
    if (t_ns - entry.t_ns > max_age_ns) continue;
    if ((entry.p_O_m - p_O_B).squaredNorm() > radius2) continue;
    const Eigen::Vector3f p_C = R_C_O * entry.p_O_m + p_C_O;
    bool in_view = false;
    if (p_C.z() > 1e-3f) {
      const Eigen::Vector2d uv = camera_.project(p_C.cast<double>());
      const int u = static_cast<int>(std::lround(uv.x()));
      const int v = static_cast<int>(std::lround(uv.y()));
      if (u >= 0 && u < camera_.width && v >= 0 && v < camera_.height) {
        const float z_measured = depth_m.ptr<float>(v)[u];
        if (valid_depth(z_measured)) {
          // The ray reaches the point or passes it: re-observed (its voxel comes back from this
          // frame) or free space now. Nearer depth occludes it; the view's nearer surface
          // already stands for it in the field.
          if (z_measured >= p_C.z() - leaf) continue;
          in_view = true;
        }
      }
    }
    entries_[kept++] = entry;
    if (in_view) continue;
    const Eigen::Vector3d p_H = R_H_C * p_C.cast<double>() + p_H_C;
    if (std::abs(p_H.z()) > config_.vertical_band_m) continue;
    const double d = p_H.norm();
    if (!(d < influence_distance_m)) continue;
    int sector =
        static_cast<int>(std::floor((std::atan2(p_H.y(), p_H.x()) + M_PI) * sectors_per_rad));
    sector = std::clamp(sector, 0, config_.sectors - 1);
    if (d < static_cast<double>(sector_distance_m_[static_cast<std::size_t>(sector)])) {
      sector_distance_m_[static_cast<std::size_t>(sector)] = static_cast<float>(d);
      sector_point_[static_cast<std::size_t>(sector)] = p_H;
    }
  }
  entries_.resize(kept);
}

int ObstacleMemory::merge_frame() {
  // At capacity the earliest insertions go first.
  const std::size_t capacity = static_cast<std::size_t>(config_.capacity);
  const std::size_t n_new = std::min(kept_voxels_.size(), capacity);
  if (entries_.size() + n_new > capacity) {
    const std::size_t excess = entries_.size() + n_new - capacity;
    std::move(entries_.begin() + static_cast<std::ptrdiff_t>(excess), entries_.end(),
              entries_.begin());
    entries_.resize(entries_.size() - excess);
  }
  rebuild_map_table();
  const std::size_t mask = map_table_.size() - 1;
  for (std::size_t i = 0; i < n_new; ++i) {
    const MapPoint& voxel = kept_voxels_[i];
    const int index = map_index(voxel.key);
    if (index >= 0) {
      entries_[static_cast<std::size_t>(index)] = voxel;
      continue;
    }
    std::size_t slot = hash_slot(voxel.key, mask);
    while (map_table_[slot] >= 0) slot = (slot + 1) & mask;
    map_table_[slot] = static_cast<int>(entries_.size());
    entries_.push_back(voxel);
  }
  return static_cast<int>(n_new);
}

void ObstacleMemory::pick_sector_minima(MemoryUpdate& out) {
  // Sector minima (ties to the lower index, as the field's cells), nearest first: a wall beside
  // the vehicle gives one point, as it would in the view, so |v_obs| stays comparable.
  sector_order_.clear();
  const int n_sectors = config_.sectors;
  for (int s = 0; s < n_sectors; ++s) {
    const float d = sector_distance_m_[static_cast<std::size_t>(s)];
    if (!(d < kInf)) continue;
    const int before = (s + n_sectors - 1) % n_sectors;
    const int after = (s + 1) % n_sectors;
    const float d_before = sector_distance_m_[static_cast<std::size_t>(before)];
    const float d_after = sector_distance_m_[static_cast<std::size_t>(after)];
    if (d_before < d || (d_before == d && before < s)) continue;
    if (d_after < d || (d_after == d && after < s)) continue;
    sector_order_.push_back(s);
  }
  std::sort(sector_order_.begin(), sector_order_.end(), [this](int a, int b) {
    return sector_distance_m_[static_cast<std::size_t>(a)] <
           sector_distance_m_[static_cast<std::size_t>(b)];
  });
  for (const int s : sector_order_) {
    if (out.count >= config_.max_points) break;
    out.p_H_m[static_cast<std::size_t>(out.count++)] = sector_point_[static_cast<std::size_t>(s)];
  }
}

MemoryUpdate ObstacleMemory::update(std::int64_t t_ns, const cv::Mat& depth_m,
                                    const Eigen::Isometry3d& T_O_C, const Eigen::Matrix3d& R_H_B,
                                    double influence_distance_m) {
  MemoryUpdate out;
  out.clear_count = clear_count_;
  out.map_size = size();
  if (depth_m.type() != CV_32FC1 || depth_m.cols != camera_.width ||
      depth_m.rows != camera_.height) {
    out.reason = "depth image is not CV_32FC1 of the camera's size";
    return out;
  }
  // A non-finite pose would put NaN keys and points into the map: nothing enters.
  if (!T_O_C.matrix().allFinite()) {
    out.reason = "T_O_C (the camera pose in the odometry origin) is not finite";
    return out;
  }
  if (!R_H_B.allFinite() || !std::isfinite(influence_distance_m)) {
    out.reason = "R_H_B_from_tilt or influence distance is not finite";
    return out;
  }
  forget_on_pose_jump(T_O_C, out);
  voxelise(depth_m, T_O_C, R_H_B);                                  // 1. depth into voxels in O
  out.speckle_removed = remove_speckle(t_ns);                       // 2. isolated voxels dropped
  age_and_pool(t_ns, depth_m, T_O_C, R_H_B, influence_distance_m);  // 3. forget, pool
  out.inserted = merge_frame();                                     // 4. this frame into the map
  pick_sector_minima(out);                                          // 5. what the field gets
  out.updated = true;
  out.map_size = size();
  return out;
}

int ObstacleMemory::telemetry_cloud(std::span<Eigen::Vector3f> p_O_m) const {
  const std::size_t n =
      std::min({p_O_m.size(), static_cast<std::size_t>(kMaxTelemetryPoints), entries_.size()});
  for (std::size_t i = 0; i < n; ++i) {
    p_O_m[i] = entries_[i * entries_.size() / n].p_O_m;
  }
  return static_cast<int>(n);
}

void ObstacleMemory::save(const std::string& path) const {
  if (!ends_with(path, ".pcd") && !ends_with(path, ".ply")) {
    throw InputError("memory map " + path + ": unknown extension, expected .pcd or .ply");
  }
  std::vector<Eigen::Vector3f> points;
  points.reserve(entries_.size());
  for (const MapPoint& entry : entries_) points.push_back(entry.p_O_m);
  if (ends_with(path, ".pcd")) {
    write_pcd(path, points);
  } else {
    write_ply(path, points);
  }
}

}  // namespace hq::obstacle_memory
