#include "hq/sim/world.hpp"

#include "hq/base/error.hpp"
#include "hq/base/target_clones.hpp"
#include "hq/config/strict_yaml.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

namespace hq::sim {

namespace {

/// std::floor for |x| < 2^31 without a library call, so that loops using it vectorise with
/// plain SSE2: truncation, one down for negative non-integers. Same value (up to the sign of a
/// zero, which the callers only ever subtract or add).
[[gnu::always_inline]] inline float floor_small(float x) {
  const auto truncated = static_cast<float>(static_cast<std::int32_t>(x));
  return truncated - (truncated > x ? 1.0f : 0.0f);  // a select, not a branch
}

/// A random value in [0, 1] for a lattice cell: an integer avalanche hash (a variant of the
/// Murmur3 finaliser) of the cell, inlined so the callers' loops vectorise.
[[gnu::always_inline]] inline float lattice(std::int32_t x, std::int32_t y, std::uint32_t salt) {
  std::uint32_t h = static_cast<std::uint32_t>(x) * 0x8da6b343u ^
                    static_cast<std::uint32_t>(y) * 0xd8163841u ^ salt * 0xcb1ab31fu;
  h ^= h >> 16;
  h *= 0x85ebca6bu;
  h ^= h >> 13;
  h *= 0xc2b2ae35u;
  h ^= h >> 16;
  return static_cast<float>(static_cast<std::int32_t>(h & 0xffffu)) * (1.0f / 65535.0f);
}

/// Value noise in [0, 1]: smooth interpolation of random lattice values (cell = 1 unit).
[[gnu::always_inline]] inline float value_noise(float x, float y, std::uint32_t salt) {
  const float fx = floor_small(x);
  const float fy = floor_small(y);
  const auto ix = static_cast<std::int32_t>(fx);
  const auto iy = static_cast<std::int32_t>(fy);
  float ax = x - fx;
  float ay = y - fy;
  ax = ax * ax * (3.0f - 2.0f * ax);
  ay = ay * ay * (3.0f - 2.0f * ay);
  const float v00 = lattice(ix, iy, salt);
  const float v10 = lattice(ix + 1, iy, salt);
  const float v01 = lattice(ix, iy + 1, salt);
  const float v11 = lattice(ix + 1, iy + 1, salt);
  const float a = v00 + (v10 - v00) * ax;
  const float b = v01 + (v11 - v01) * ax;
  return a + (b - a) * ay;
}

/// The pattern in [0, 1] of one texture kind at (s, t) in units of the texture's scale: the
/// one definition albedo() and albedo_span() both evaluate, so they agree bit for bit.
template <Texture::Kind kKind>
[[gnu::always_inline]] inline float pattern_at(float s, float t, std::uint32_t salt) {
  if constexpr (kKind == Texture::Kind::kChecker) {
    const auto k =
        static_cast<std::int32_t>(floor_small(s)) + static_cast<std::int32_t>(floor_small(t));
    const float pattern = (k & 1) != 0 ? 1.0f : 0.0f;
    // Fine noise inside the squares keeps photometric gradients away from the edges too.
    return 0.8f * pattern + 0.2f * value_noise(s * 6.0f, t * 6.0f, salt);
  } else if constexpr (kKind == Texture::Kind::kNoise) {
    return 0.65f * value_noise(s, t, salt) + 0.35f * value_noise(s * 4.0f, t * 4.0f, salt + 1u);
  } else {
    const float phase = s - floor_small(s);
    const float pattern = phase < 0.5f ? 1.0f : 0.0f;
    return 0.8f * pattern + 0.2f * value_noise(s * 5.0f, t * 5.0f, salt);
  }
}

/// pattern_at<kKind> at n points, the kind hoisted out of the loop so it vectorises.
template <Texture::Kind kKind>
[[gnu::always_inline]] inline void albedo_loop(const Texture& texture, const float* s_m,
                                               const float* t_m, int n, float* b, float* g,
                                               float* r) {
  const float inv = 1.0f / texture.scale_m;
  const float cb = texture.color_bgr[0];
  const float cg = texture.color_bgr[1];
  const float cr = texture.color_bgr[2];
  // Locals, not members: the stores to b, g, r could otherwise alias them.
  const float contrast = texture.contrast;
  const std::uint32_t salt = texture.salt;
#pragma omp simd
  for (int i = 0; i < n; ++i) {
    const float f = 1.0f - contrast * pattern_at<kKind>(s_m[i] * inv, t_m[i] * inv, salt);
    b[i] = cb * f;
    g[i] = cg * f;
    r[i] = cr * f;
  }
}

}  // namespace

// Also built for AVX2 (8 lanes, a native 32-bit multiply for the hash) and picked at load time
// where the CPU has it. No FMA: the avx2 target does not enable it, so values are unchanged.
HQ_CLONES_AVX2 void Texture::albedo_span(const float* s_m, const float* t_m, int n, float* b,
                                         float* g, float* r) const {
  switch (kind) {
    case Kind::kChecker:
      albedo_loop<Kind::kChecker>(*this, s_m, t_m, n, b, g, r);
      break;
    case Kind::kNoise:
      albedo_loop<Kind::kNoise>(*this, s_m, t_m, n, b, g, r);
      break;
    case Kind::kStripes:
      albedo_loop<Kind::kStripes>(*this, s_m, t_m, n, b, g, r);
      break;
  }
}

Eigen::Vector3f Texture::albedo(float s_m, float t_m) const {
  const float inv = 1.0f / scale_m;
  float pattern = 0.0f;
  switch (kind) {
    case Kind::kChecker:
      pattern = pattern_at<Kind::kChecker>(s_m * inv, t_m * inv, salt);
      break;
    case Kind::kNoise:
      pattern = pattern_at<Kind::kNoise>(s_m * inv, t_m * inv, salt);
      break;
    case Kind::kStripes:
      pattern = pattern_at<Kind::kStripes>(s_m * inv, t_m * inv, salt);
      break;
  }
  return color_bgr * (1.0f - contrast * pattern);
}

namespace {

using config::StrictMap;

Texture read_texture(StrictMap map, std::uint32_t salt) {
  Texture texture;
  texture.salt = salt;
  std::string type = "noise";
  map.read("type", type, {"checker", "noise", "stripes"});
  texture.kind = type == "checker"   ? Texture::Kind::kChecker
                 : type == "stripes" ? Texture::Kind::kStripes
                                     : Texture::Kind::kNoise;
  double color[3] = {0.7, 0.7, 0.7};
  map.read_list("color_bgr", color, 3);
  for (int i = 0; i < 3; ++i) {
    if (color[i] < 0.0 || color[i] > 1.0) {
      throw InputError(map.describe("color_bgr") + "[" + std::to_string(i) +
                       "] = " + std::to_string(color[i]) + ", expected in [0, 1]");
    }
    texture.color_bgr[i] = static_cast<float>(color[i]);
  }
  double scale_m = texture.scale_m;
  map.read_positive("scale_m", scale_m, 100.0);
  texture.scale_m = static_cast<float>(scale_m);
  double contrast = texture.contrast;
  map.read("contrast", contrast, 0.0, 1.0);
  texture.contrast = static_cast<float>(contrast);
  map.finish();
  return texture;
}

void check_positive(const StrictMap& map, const std::string& key, const double* values, int count) {
  for (int i = 0; i < count; ++i) {
    if (!(values[i] > 0.0)) {
      throw InputError(map.describe(key) + "[" + std::to_string(i) +
                       "] = " + std::to_string(values[i]) + ", expected > 0");
    }
  }
}

// Every primitive is tested by every camera ray: 100k boxes never rendered a frame. The bundled
// worlds have at most 16; a generated room may have a few thousand.
constexpr std::size_t kMaxPrimitives = 10000;
// Indoor flight: anything placed farther than this from the origin is a typo (1e300 m gave a
// summary of NaN).
constexpr double kMaxCoordinateM = 1000.0;

void check_within(const StrictMap& map, const std::string& key, const double* values, int count) {
  for (int i = 0; i < count; ++i) {
    if (!(std::abs(values[i]) <= kMaxCoordinateM)) {
      std::ostringstream message;
      message << map.describe(key) << "[" << i << "] = " << values[i] << ", expected within +-"
              << kMaxCoordinateM << " m of the world origin";
      throw InputError(message.str());
    }
  }
}

YAML::Node sequence(const YAML::Node& root, const std::string& key, const std::string& path) {
  const YAML::Node node = root[key];
  if (!node.IsDefined() || node.IsNull()) return YAML::Node(YAML::NodeType::Sequence);
  if (!node.IsSequence()) throw InputError(path + ": " + key + " is not a list");
  return node;
}

Rectangle wall_between(const Eigen::Vector2d& from, const Eigen::Vector2d& to, double height_m) {
  Rectangle wall;
  const Eigen::Vector2d along = to - from;
  wall.center_m =
      Eigen::Vector3d(0.5 * (from.x() + to.x()), 0.5 * (from.y() + to.y()), 0.5 * height_m);
  wall.axis_u = Eigen::Vector3d(along.x(), along.y(), 0.0).normalized();
  wall.axis_v = Eigen::Vector3d::UnitZ();
  // Normal to the left of from -> to; walls are two-sided for rendering and distances.
  wall.normal = Eigen::Vector3d::UnitZ().cross(wall.axis_u);
  wall.half_u_m = 0.5 * along.norm();
  wall.half_v_m = 0.5 * height_m;
  return wall;
}

/// Distance from p to a rectangle (unsigned).
double distance_to_rectangle(const Rectangle& r, const Eigen::Vector3d& p) {
  const Eigen::Vector3d d = p - r.center_m;
  const double u = std::clamp(d.dot(r.axis_u), -r.half_u_m, r.half_u_m);
  const double v = std::clamp(d.dot(r.axis_v), -r.half_v_m, r.half_v_m);
  return (d - u * r.axis_u - v * r.axis_v).norm();
}

double distance_to_box(const Box& b, const Eigen::Vector3d& p) {
  const Eigen::Vector3d d = p - b.center_m;
  const double c = std::cos(b.yaw_rad);
  const double s = std::sin(b.yaw_rad);
  const Eigen::Vector3d local(c * d.x() + s * d.y(), -s * d.x() + c * d.y(), d.z());
  const Eigen::Vector3d q = local.cwiseAbs() - 0.5 * b.size_m;
  // Signed distance of a box (positive outside, negative inside).
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

double distance_to_cylinder(const Cylinder& c, const Eigen::Vector3d& p) {
  const double radial = (p.head<2>() - c.center_m).norm() - c.radius_m;
  const double half_h = 0.5 * c.height_m;
  const double axial = std::abs(p.z() - (c.base_z_m + half_h)) - half_h;
  const Eigen::Vector2d q(radial, axial);
  return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

}  // namespace

Cylinder body_at(const Walker& walker, double t_s) {
  Cylinder body;
  body.center_m = walker.from_m;
  body.radius_m = walker.radius_m;
  body.base_z_m = 0.0;
  body.height_m = walker.height_m;
  body.texture = walker.texture;
  const Eigen::Vector2d along = walker.to_m - walker.from_m;
  const double length_m = along.norm();
  if (!(length_m > 0.0)) return body;  // load_world() rejects it; a hand-made one stands still
  // The distance walked, folded onto one lap out and back (2 L); fmod keeps the sign of t_s.
  const double lap_m = 2.0 * length_m;
  double on_lap_m = std::fmod(walker.speed_mps * (t_s + walker.phase_s), lap_m);
  if (on_lap_m < 0.0) on_lap_m += lap_m;
  const double from_start_m = on_lap_m <= length_m ? on_lap_m : lap_m - on_lap_m;
  body.center_m = walker.from_m + (from_start_m / length_m) * along;
  return body;
}

double distance_to_obstacles(const World& world, const Eigen::Vector3d& p_N_m, double t_s) {
  double best = 1e9;
  for (const Rectangle& wall : world.walls)
    best = std::min(best, distance_to_rectangle(wall, p_N_m));
  for (const Box& box : world.boxes) best = std::min(best, distance_to_box(box, p_N_m));
  for (const Cylinder& c : world.cylinders) best = std::min(best, distance_to_cylinder(c, p_N_m));
  for (const Walker& walker : world.people)
    best = std::min(best, distance_to_cylinder(body_at(walker, t_s), p_N_m));
  return best;
}

double distance_to_obstacles(const World& world, const Eigen::Vector3d& p_N_m) {
  return distance_to_obstacles(world, p_N_m, 0.0);
}

namespace {

/// start: where the vehicle stands (on the floor, checked by read_floor()).
void read_start(StrictMap& map, World& world) {
  StrictMap start = map.child("start");
  double xy[2] = {0.0, 0.0};
  start.read_list("xy_m", xy, 2);
  check_within(start, "xy_m", xy, 2);
  world.start_N_m = Eigen::Vector3d(xy[0], xy[1], 0.0);
  start.read_deg_as_rad("yaw_deg", world.start_yaw_rad, -180.0, 180.0);
  start.finish();
}

/// floor: the rectangle at z = 0; the start must lie on it.
void read_floor(StrictMap& map, const std::string& path, std::uint32_t& salt, World& world) {
  StrictMap floor = map.child("floor");
  double half[2] = {20.0, 20.0};
  floor.read_list("half_size_m", half, 2);
  check_positive(floor, "half_size_m", half, 2);
  check_within(floor, "half_size_m", half, 2);
  world.floor.center_m = Eigen::Vector3d::Zero();
  world.floor.normal = Eigen::Vector3d::UnitZ();
  world.floor.axis_u = Eigen::Vector3d::UnitX();
  world.floor.axis_v = Eigen::Vector3d::UnitY();
  world.floor.half_u_m = half[0];
  world.floor.half_v_m = half[1];
  world.floor.texture = read_texture(floor.child("texture"), salt++);
  floor.finish();
  const Eigen::Vector2d start = world.start_N_m.head<2>();
  if (std::abs(start.x()) > half[0] || std::abs(start.y()) > half[1]) {
    std::ostringstream message;
    message << path << ": start.xy_m = [" << start.x() << ", " << start.y()
            << "], expected on the floor (|x| <= " << half[0] << ", |y| <= " << half[1]
            << " m, floor.half_size_m)";
    throw InputError(message.str());
  }
}

/// Rejects a world with more primitives than the renderer can draw, before reading any.
void check_primitive_count(const YAML::Node& root, const std::string& path) {
  std::size_t count = 0;
  std::string counts;
  for (const char* key : {"walls", "boxes", "cylinders", "markers", "people"}) {
    const std::size_t n = sequence(root, key, path).size();
    count += n;
    counts += (counts.empty() ? "" : ", ") + std::to_string(n) + " " + key;
  }
  if (count > kMaxPrimitives) {
    throw InputError(path + ": " + std::to_string(count) + " primitives (" + counts +
                     "), expected at most " + std::to_string(kMaxPrimitives));
  }
}

Rectangle read_wall(StrictMap w, std::uint32_t& salt) {
  double from[2] = {0, 0};
  double to[2] = {0, 0};
  double height_m = 2.5;
  w.require_list("from_m", from, 2);
  w.require_list("to_m", to, 2);
  check_within(w, "from_m", from, 2);
  check_within(w, "to_m", to, 2);
  w.read_positive("height_m", height_m, 100.0);
  if (std::hypot(to[0] - from[0], to[1] - from[1]) < 1e-3) {
    throw InputError(w.describe("to_m") + " equals from_m, expected a wall of length > 0");
  }
  Rectangle wall = wall_between({from[0], from[1]}, {to[0], to[1]}, height_m);
  wall.texture = read_texture(w.child("texture"), salt++);
  w.finish();
  return wall;
}

Box read_box(StrictMap b, std::uint32_t& salt) {
  Box box;
  double center[3] = {0, 0, 0};
  double size[3] = {1, 1, 1};
  b.require_list("center_m", center, 3);
  b.require_list("size_m", size, 3);
  check_within(b, "center_m", center, 3);
  check_positive(b, "size_m", size, 3);
  check_within(b, "size_m", size, 3);
  b.read_deg_as_rad("yaw_deg", box.yaw_rad, -180.0, 180.0);
  box.center_m = Eigen::Vector3d(center[0], center[1], center[2]);
  box.size_m = Eigen::Vector3d(size[0], size[1], size[2]);
  box.texture = read_texture(b.child("texture"), salt++);
  b.finish();
  return box;
}

Cylinder read_cylinder(StrictMap c, std::uint32_t& salt) {
  Cylinder cyl;
  double center[2] = {0, 0};
  c.require_list("center_m", center, 2);
  check_within(c, "center_m", center, 2);
  c.read_positive("radius_m", cyl.radius_m, 100.0);
  c.read_positive("height_m", cyl.height_m, 100.0);
  c.read("base_z_m", cyl.base_z_m, -10.0, 100.0);
  cyl.center_m = Eigen::Vector2d(center[0], center[1]);
  cyl.texture = read_texture(c.child("texture"), salt++);
  c.finish();
  return cyl;
}

// Walking pace, not a sprint: a person faster than this is a typo in the world file.
constexpr double kMaxWalkingSpeedMps = 3.0;
// A phase is an offset within the run; hq-sim runs at most an hour.
constexpr double kMaxPhaseS = 3600.0;

Walker read_walker(StrictMap p, std::uint32_t& salt) {
  Walker walker;
  double from[2] = {0, 0};
  double to[2] = {0, 0};
  p.require_list("from_m", from, 2);
  p.require_list("to_m", to, 2);
  check_within(p, "from_m", from, 2);
  check_within(p, "to_m", to, 2);
  p.read_positive("speed_mps", walker.speed_mps, kMaxWalkingSpeedMps);
  p.read("phase_s", walker.phase_s, -kMaxPhaseS, kMaxPhaseS);
  p.read_positive("radius_m", walker.radius_m, 1.0);
  p.read_positive("height_m", walker.height_m, 3.0);
  if (std::hypot(to[0] - from[0], to[1] - from[1]) < 1e-3) {
    throw InputError(p.describe("to_m") + " equals from_m, expected a walk of length > 0");
  }
  walker.from_m = Eigen::Vector2d(from[0], from[1]);
  walker.to_m = Eigen::Vector2d(to[0], to[1]);
  walker.texture = read_texture(p.child("texture"), salt++);
  p.finish();
  return walker;
}

// A marker's normal is written as a unit vector; one farther from length 1 than rounding in
// the file's digits is a typo in a direction, which normalising would hide.
constexpr double kNormalLengthTolerance = 1e-3;
// How far in front of a marker its face is probed for free space: more than the renderer's
// 1 cm on-surface tolerance would reach across thin boxes, less would miss it.
constexpr double kFaceProbeM = 0.01;

std::string vector_text(const Eigen::Vector3d& v) {
  std::ostringstream text;
  text << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return text.str();
}

Marker read_marker(StrictMap m) {
  Marker marker;
  double center[3] = {0, 0, 0};
  double normal[3] = {0, 0, 1};
  m.require("id", marker.id, 0, 586);  // AprilTag 36h11 has 587 codes.
  m.require_list("center_m", center, 3);
  check_within(m, "center_m", center, 3);
  m.read_list("normal", normal, 3);
  m.read_positive("size_m", marker.size_m, 10.0);
  m.read_deg_as_rad("rotation_deg", marker.rotation_rad, -180.0, 180.0);
  m.finish();
  const Eigen::Vector3d n(normal[0], normal[1], normal[2]);
  if (!(std::abs(n.norm() - 1.0) <= kNormalLengthTolerance)) {
    std::ostringstream message;
    message << m.describe("normal") << " (id " << marker.id << ") = " << vector_text(n)
            << " has length " << n.norm()
            << ", expected a unit vector (|length - 1| <= " << kNormalLengthTolerance << ")";
    throw InputError(message.str());
  }
  marker.center_N_m = Eigen::Vector3d(center[0], center[1], center[2]);
  marker.normal_N = n.normalized();
  return marker;
}

/// What a marker's face looks into, just in front of it: "" for free space, else "the floor"
/// or the solid it faces into. A flipped normal puts the printed side against its surface,
/// where no camera sees it. Walls are two-sided, so a marker on one faces free space both ways.
std::string faced_solid(const World& world, const Marker& marker) {
  const Eigen::Vector3d front = marker.center_N_m + kFaceProbeM * marker.normal_N;
  if (front.z() < 0.0) return "the floor";
  for (std::size_t i = 0; i < world.boxes.size(); ++i) {
    if (distance_to_box(world.boxes[i], front) < 0.0) return "boxes[" + std::to_string(i) + "]";
  }
  for (std::size_t i = 0; i < world.cylinders.size(); ++i) {
    if (distance_to_cylinder(world.cylinders[i], front) < 0.0) {
      return "cylinders[" + std::to_string(i) + "]";
    }
  }
  return "";
}

/// The markers of the file's list, which are world.markers' first entries.
void check_markers_face_free_space(const World& world, std::size_t listed,
                                   const std::string& path) {
  for (std::size_t k = 0; k < listed; ++k) {
    const Marker& marker = world.markers[k];
    const std::string solid = faced_solid(world, marker);
    if (solid.empty()) continue;
    throw InputError(path + ": markers[" + std::to_string(k) + "].normal (id " +
                     std::to_string(marker.id) + ") = " + vector_text(marker.normal_N) +
                     " faces into " + solid + ", expected it to face free space");
  }
}

/// One list of the world file, each entry read by read_entry(StrictMap) in file order (the
/// texture salts follow that order, so the textures do too).
template <typename ReadEntry>
void read_list(const YAML::Node& root, const char* key, const std::string& path,
               ReadEntry&& read_entry) {
  const YAML::Node entries = sequence(root, key, path);
  for (std::size_t i = 0; i < entries.size(); ++i) {
    read_entry(StrictMap(entries[i], path, std::string(key) + "[" + std::to_string(i) + "]"));
  }
}

/// marker_grid: rows x cols tags on the floor, ids in reading order from the start.
void read_marker_grid(StrictMap& map, World& world) {
  StrictMap grid = map.child("marker_grid");
  if (grid.has("rows")) {
    int rows = 0;
    int cols = 0;
    int first_id = 0;
    double spacing_m = 0.6;
    double size_m = 0.2;
    double center[2] = {0, 0};
    grid.require("rows", rows, 1, 24);
    grid.require("cols", cols, 1, 24);
    grid.read("first_id", first_id, 0, 586);
    grid.read_positive("spacing_m", spacing_m, 10.0);
    grid.read_positive("size_m", size_m, 10.0);
    grid.read_list("center_m", center, 2);
    if (first_id + rows * cols > 587) {
      throw InputError(grid.describe("first_id") + " = " + std::to_string(first_id) +
                       ", expected first_id + rows * cols <= 587 (AprilTag 36h11 codes)");
    }
    if (size_m * 1.5 > spacing_m) {
      throw InputError(grid.describe("spacing_m") + " = " + std::to_string(spacing_m) +
                       ", expected >= 1.5 * size_m so tags and their white margins do not overlap");
    }
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) {
        Marker marker;
        marker.id = first_id + r * cols + c;
        marker.size_m = size_m;
        // Row index grows along world -x so that ids read like text seen from the start.
        marker.center_N_m = Eigen::Vector3d(center[0] + ((rows - 1) * 0.5 - r) * spacing_m,
                                            center[1] + ((cols - 1) * 0.5 - c) * spacing_m, 0.0);
        marker.normal_N = Eigen::Vector3d::UnitZ();
        world.markers.push_back(marker);
      }
    }
  }
  grid.finish();
}

}  // namespace

World load_world(const std::string& path) {
  const YAML::Node root = config::load_yaml_file(path);
  YAML::Node scalars = YAML::Clone(root);
  const char* list_keys[] = {"walls", "boxes", "cylinders", "markers", "people"};
  for (const char* key : list_keys) scalars.remove(key);

  World world;
  // One per texture, in file order: floor, walls, boxes, cylinders, people.
  std::uint32_t salt = 1;
  StrictMap map(scalars, path);
  world.name = path;
  map.read("name", world.name, {});
  int seed = 1;
  map.read("seed", seed, 0, 2147483647);
  world.seed = static_cast<std::uint64_t>(seed);
  read_start(map, world);
  read_floor(map, path, salt, world);
  check_primitive_count(root, path);
  read_list(root, "walls", path,
            [&](StrictMap entry) { world.walls.push_back(read_wall(std::move(entry), salt)); });
  read_list(root, "boxes", path,
            [&](StrictMap entry) { world.boxes.push_back(read_box(std::move(entry), salt)); });
  read_list(root, "cylinders", path, [&](StrictMap entry) {
    world.cylinders.push_back(read_cylinder(std::move(entry), salt));
  });
  read_list(root, "markers", path,
            [&](StrictMap entry) { world.markers.push_back(read_marker(std::move(entry))); });
  check_markers_face_free_space(world, world.markers.size(), path);
  read_list(root, "people", path,
            [&](StrictMap entry) { world.people.push_back(read_walker(std::move(entry), salt)); });
  read_marker_grid(map, world);
  map.finish();
  return world;
}

}  // namespace hq::sim
