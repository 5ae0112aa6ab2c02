#include "hq/obstacle_memory/obstacle_memory.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"

#include <Eigen/Geometry>

#include <pcl/exceptions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace hq::obstacle_memory {
namespace {
constexpr int kNormalStepPx = 8;  // support-surface normals, see update()
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
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}
}  // namespace

void read_config(config::StrictMap& section, MemoryConfig& out) {
  section.read("enabled", out.enabled);
  section.read_positive("leaf_m", out.leaf_m, 10.0);
  section.read("pixel_stride", out.pixel_stride, 1, 64);
  section.read("min_range_m", out.min_range_m, 0.0, 10.0);
  section.read_positive("max_range_m", out.max_range_m, 100.0);
  section.read("min_neighbors", out.min_neighbors, 0, 26);
  section.read_positive("max_age_s", out.max_age_s, 3600.0);
  section.read_positive("radius_m", out.radius_m, 100.0);
  section.read("capacity", out.capacity, 1, 1000000);
  section.read_positive("max_pose_jump_m", out.max_pose_jump_m, 100.0);
  section.read_deg_as_rad("max_pose_jump_deg", out.max_pose_jump_rad, 0.1, 180.0);
  section.read_positive("vertical_band_m", out.vertical_band_m, 100.0);
  section.read_deg_as_rad("support_normal_max_deg", out.support_normal_max_rad, 0.0, 90.0);
  section.read("sectors", out.sectors, 3, 360);
  section.read("max_points", out.max_points, 0, kMaxRememberedPoints);
  if (!(out.max_range_m > out.min_range_m)) {
    throw InputError(section.describe("max_range_m") + " = " + std::to_string(out.max_range_m) +
                     ", expected > min_range_m (" + std::to_string(out.min_range_m) + ")");
  }
  section.finish();
}

ObstacleMemory::ObstacleMemory(const MemoryConfig& config, const geometry::PinholeCamera& camera,
                               const Eigen::Matrix3d& R_body_camera,
                               const Eigen::Vector3d& p_body_camera_m)
    : config_(config), camera_(camera), R_QC_(R_body_camera), p_QC_(p_body_camera_m) {
  if (camera.width <= 0 || camera.height <= 0 || !(camera.fx > 0.0) || !(camera.fy > 0.0)) {
    throw InputError("memory: camera " + std::to_string(camera.width) + "x" +
                     std::to_string(camera.height) + " fx " + std::to_string(camera.fx) +
                     ", expected a positive size and focal length");
  }
  if (!(config.leaf_m > 0.0) || config.pixel_stride < 1 || config.capacity < 1 ||
      config.sectors < 3 || config.max_points < 0 || config.max_points > kMaxRememberedPoints ||
      !(config.max_range_m > config.min_range_m)) {
    throw InputError("memory: leaf_m = " + std::to_string(config.leaf_m) +
                     ", pixel_stride = " + std::to_string(config.pixel_stride) +
                     ", capacity = " + std::to_string(config.capacity) +
                     ", sectors = " + std::to_string(config.sectors) +
                     ", max_points = " + std::to_string(config.max_points) +
                     ", expected leaf_m > 0, stride >= 1, capacity >= 1, sectors >= 3, "
                     "max_points <= " + std::to_string(kMaxRememberedPoints) +
                     " and max_range_m > min_range_m");
  }
  if (!R_QC_.allFinite() || !p_QC_.allFinite() ||
      (R_QC_.transpose() * R_QC_ - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6) {
    throw InputError("memory: R_body_camera is not a rotation");
  }
  inv_leaf_ = static_cast<float>(1.0 / config.leaf_m);
  const std::size_t samples =
      static_cast<std::size_t>((camera.width + config.pixel_stride - 1) / config.pixel_stride) *
      static_cast<std::size_t>((camera.height + config.pixel_stride - 1) / config.pixel_stride);
  frame_table_.assign(power_of_two_at_least(2 * samples), FrameVoxel{kEmptyKey, Eigen::Vector3f::Zero(), 0});
  frame_used_.reserve(samples);
  kept_voxels_.reserve(samples);
  entries_.reserve(static_cast<std::size_t>(config.capacity));
  map_table_.assign(power_of_two_at_least(2 * static_cast<std::size_t>(config.capacity)), -1);
  sector_distance_m_.assign(static_cast<std::size_t>(config.sectors), kInf);
  sector_point_.assign(static_cast<std::size_t>(config.sectors), Eigen::Vector3d::Zero());
  sector_order_.reserve(static_cast<std::size_t>(config.sectors));
}

bool ObstacleMemory::key_of(const Eigen::Vector3f& p_world_m, std::uint64_t& key) const {
  std::uint64_t packed = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const float scaled = std::floor(p_world_m[axis] * inv_leaf_);
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
         sector_order_.capacity() * sizeof(int);
}

MemoryUpdate ObstacleMemory::update(std::int64_t t_ns, const cv::Mat& depth_m,
                                    const Eigen::Isometry3d& T_world_camera,
                                    const Eigen::Matrix3d& R_horizontal_body,
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
  if (!T_world_camera.matrix().allFinite()) {
    out.reason = "T_world_camera is not finite";
    return out;
  }
  if (!R_horizontal_body.allFinite() || !std::isfinite(influence_distance_m)) {
    out.reason = "R_horizontal_body or influence distance is not finite";
    return out;
  }

  // A jump of the estimate (odometry re-initialised, or a wrong alignment) would misplace every
  // remembered point relative to the vehicle: forget them rather than push from ghosts.
  if (have_pose_) {
    const Eigen::Isometry3d step = T_world_camera_prev_.inverse() * T_world_camera;
    const double angle_rad = Eigen::AngleAxisd(step.linear()).angle();
    if (step.translation().norm() > config_.max_pose_jump_m ||
        angle_rad > config_.max_pose_jump_rad) {
      clear();
      ++clear_count_;
      out.cleared = true;
      out.clear_count = clear_count_;
    }
  }
  T_world_camera_prev_ = T_world_camera;
  have_pose_ = true;

  // 1. Valid depth into world points, averaged per voxel (the effect of pcl::VoxelGrid, which
  //    allocates and sorts on every call; a hash into a table sized once does neither).
  for (const int slot : frame_used_) frame_table_[static_cast<std::size_t>(slot)].key = kEmptyKey;
  frame_used_.clear();
  const Eigen::Matrix3f R_WC = T_world_camera.linear().cast<float>();
  const Eigen::Vector3f t_WC = T_world_camera.translation().cast<float>();
  const auto min_z = static_cast<float>(config_.min_range_m);
  const auto max_z = static_cast<float>(config_.max_range_m);
  const auto inv_fx = static_cast<float>(1.0 / camera_.fx);
  const auto inv_fy = static_cast<float>(1.0 / camera_.fy);
  const auto cx = static_cast<float>(camera_.cx);
  const auto cy = static_cast<float>(camera_.cy);
  const int stride = config_.pixel_stride;
  // Support surfaces: the normal from neighbouring samples, in H (gravity-aligned).
  const Eigen::Matrix3f R_HC_f = (R_horizontal_body * R_QC_).cast<float>();
  const auto min_vertical = static_cast<float>(std::cos(config_.support_normal_max_rad));
  const auto point_at = [&](int pu, int pv, Eigen::Vector3f& p) {
    const float pz = depth_m.ptr<float>(pv)[pu];
    if (!(std::isfinite(pz) && pz >= min_z && pz <= max_z)) return false;
    p = Eigen::Vector3f((static_cast<float>(pu) - cx) * inv_fx * pz,
                        (static_cast<float>(pv) - cy) * inv_fy * pz, pz);
    return true;
  };
  // Neighbouring samples mostly share a voxel: reuse the last slot instead of hashing again.
  std::uint64_t last_key = kEmptyKey;
  FrameVoxel* last_voxel = nullptr;
  for (int v = 0; v < camera_.height; v += stride) {
    const auto* row = depth_m.ptr<float>(v);
    const float y_over_z = (static_cast<float>(v) - cy) * inv_fy;
    for (int u = 0; u < camera_.width; u += stride) {
      const float z = row[u];
      if (!(std::isfinite(z) && z >= min_z && z <= max_z)) continue;
      const Eigen::Vector3f p_C((static_cast<float>(u) - cx) * inv_fx * z, y_over_z * z, z);
      // One-sided differences, to the right or left and below or above, whichever has depth,
      // kNormalStepPx apart: at 1 m a structured-light sensor quantises depth in ~2 mm steps,
      // which over adjacent pixels (3 mm apart) tilts a floor's normal by tens of degrees.
      Eigen::Vector3f side, vertical;
      const bool has_side =
          (u + kNormalStepPx < camera_.width && point_at(u + kNormalStepPx, v, side)) ||
          (u >= kNormalStepPx && point_at(u - kNormalStepPx, v, side));
      const bool has_vertical =
          (v + kNormalStepPx < camera_.height && point_at(u, v + kNormalStepPx, vertical)) ||
          (v >= kNormalStepPx && point_at(u, v - kNormalStepPx, vertical));
      // Without a normal the sample is unknown surface, most often the ragged edge of depth at
      // the sensor's minimum range on the floor ahead: not remembered.
      if (!has_side || !has_vertical) continue;
      const Eigen::Vector3f normal_C = (side - p_C).cross(vertical - p_C);
      const float norm = normal_C.norm();
      if (!(norm > 0.0f) || std::abs((R_HC_f * normal_C).z()) > min_vertical * norm) continue;
      const Eigen::Vector3f p_W = R_WC * p_C + t_WC;
      std::uint64_t key = 0;
      if (!key_of(p_W, key)) continue;
      if (key != last_key) {
        last_key = key;
        last_voxel = &frame_table_[static_cast<std::size_t>(frame_slot(key, true))];
      }
      last_voxel->sum_m += p_W;
      ++last_voxel->n;
    }
  }

  // 2. Speckle: radius outlier removal on the voxel grid. A voxel is kept when at least
  //    min_neighbors of its 26 neighbours are occupied (pcl::RadiusOutlierRemoval with a radius
  //    of about one voxel diagonal). Chosen over StatisticalOutlierRemoval because the voxel
  //    grid already makes the spacing uniform, so a fixed-radius count separates isolated
  //    flying pixels from surfaces, and the hash answers it in O(1) without a k-d tree.
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
      ++out.speckle_removed;
      continue;
    }
    kept_voxels_.push_back(MapPoint{voxel.sum_m / static_cast<float>(voxel.n), t_ns, voxel.key});
  }

  // 3. Age, radius and view: one pass compacts the map in place and min-pools the remembered
  //    points outside the view into azimuth sectors of H.
  const Eigen::Isometry3d T_camera_world = T_world_camera.inverse();
  const Eigen::Matrix3f R_CW = T_camera_world.linear().cast<float>();
  const Eigen::Vector3f t_CW = T_camera_world.translation().cast<float>();
  const Eigen::Vector3f p_world_body =
      (T_world_camera * (-R_QC_.transpose() * p_QC_)).cast<float>();
  const Eigen::Matrix3d R_HC = R_horizontal_body * R_QC_;
  const Eigen::Vector3d p_HC = R_horizontal_body * p_QC_;
  const auto radius2 = static_cast<float>(config_.radius_m * config_.radius_m);
  const auto max_age_ns = static_cast<std::int64_t>(config_.max_age_s * 1e9);
  const auto leaf = static_cast<float>(config_.leaf_m);
  const auto fx = static_cast<float>(camera_.fx);
  const auto fy = static_cast<float>(camera_.fy);
  std::fill(sector_distance_m_.begin(), sector_distance_m_.end(), kInf);
  const double sectors_per_rad = config_.sectors / (2.0 * M_PI);
  std::size_t kept = 0;
  for (const MapPoint& entry : entries_) {
    if (t_ns - entry.t_ns > max_age_ns) continue;
    if ((entry.p_world_m - p_world_body).squaredNorm() > radius2) continue;
    const Eigen::Vector3f p_C = R_CW * entry.p_world_m + t_CW;
    bool in_view = false;
    if (p_C.z() > 1e-3f) {
      const int u = static_cast<int>(std::lround(fx * p_C.x() / p_C.z() + cx));
      const int v = static_cast<int>(std::lround(fy * p_C.y() / p_C.z() + cy));
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
    const Eigen::Vector3d p_H = R_HC * p_C.cast<double>() + p_HC;
    if (std::abs(p_H.z()) > config_.vertical_band_m) continue;
    const double d = p_H.norm();
    if (!(d < influence_distance_m)) continue;
    int sector = static_cast<int>(std::floor((std::atan2(p_H.y(), p_H.x()) + M_PI) *
                                             sectors_per_rad));
    sector = std::clamp(sector, 0, config_.sectors - 1);
    if (d < sector_distance_m_[static_cast<std::size_t>(sector)]) {
      sector_distance_m_[static_cast<std::size_t>(sector)] = static_cast<float>(d);
      sector_point_[static_cast<std::size_t>(sector)] = p_H;
    }
  }
  entries_.resize(kept);

  // 4. Merge this frame; at capacity the earliest insertions go first.
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
  out.inserted = static_cast<int>(n_new);

  // 5. Sector minima (ties to the lower index, as the field's cells), nearest first: a wall
  //    beside the vehicle gives one point, as it would in the view, so |v_obs| stays comparable.
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
    out.p_horizontal_m[static_cast<std::size_t>(out.count++)] =
        sector_point_[static_cast<std::size_t>(s)];
  }
  out.updated = true;
  out.map_size = size();
  return out;
}

int ObstacleMemory::telemetry_cloud(std::span<Eigen::Vector3f> p_world_m) const {
  const std::size_t n = std::min({p_world_m.size(), static_cast<std::size_t>(kMaxTelemetryPoints),
                                  entries_.size()});
  for (std::size_t i = 0; i < n; ++i) {
    p_world_m[i] = entries_[i * entries_.size() / n].p_world_m;
  }
  return static_cast<int>(n);
}

void ObstacleMemory::save(const std::string& path) const {
  pcl::PointCloud<pcl::PointXYZ> cloud;
  cloud.reserve(entries_.size());
  for (const MapPoint& entry : entries_) {
    cloud.push_back(pcl::PointXYZ(entry.p_world_m.x(), entry.p_world_m.y(), entry.p_world_m.z()));
  }
  if (!ends_with(path, ".pcd") && !ends_with(path, ".ply")) {
    throw InputError("memory map " + path + ": unknown extension, expected .pcd or .ply");
  }
  int status = -1;
  try {
    if (ends_with(path, ".pcd")) {
    // PCL's binary writer refuses an empty cloud; ASCII writes a valid empty file.
      status = cloud.empty() ? pcl::io::savePCDFileASCII(path, cloud)
                             : pcl::io::savePCDFileBinary(path, cloud);
    } else {
      status = pcl::io::savePLYFileBinary(path, cloud);
    }
  } catch (const pcl::PCLException& e) {
    throw InputError("memory map " + path + ": pcl::io could not write " +
                     std::to_string(cloud.size()) + " points: " + e.what());
  }
  if (status < 0) {
    throw InputError("memory map " + path + ": pcl::io could not write " +
                     std::to_string(cloud.size()) + " points");
  }
}

}  // namespace hq::obstacle_memory
