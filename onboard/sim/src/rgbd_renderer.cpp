#include "hq/sim/rgbd_renderer.hpp"

#include "hq/base/error.hpp"
#include "hq/base/target_clones.hpp"

#include <opencv2/aruco.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace hq::sim {

namespace {

constexpr float kNoHit = std::numeric_limits<float>::infinity();
constexpr float kMinT = 1e-4f;
// 8 cells of AprilTag 36h11 (6 data + black border) plus a 2-cell white quiet zone on each
// side: with only one cell against a dark wall cv::aruco's adaptive threshold misses the tag.
constexpr int kTagCells = 12;
constexpr int kTagMargin = 2;
constexpr float kTagBlackAlbedo = 0.08f;
constexpr float kTagWhiteAlbedo = 0.92f;

using Vec3f = Eigen::Vector3f;

/// Marker bitmap placed on a surface: (s, t) surface coordinates -> cell (col, row).
struct SurfaceMarker {
  float s0 = 0.0f, t0 = 0.0f;    // marker centre in surface coordinates
  float a00 = 0.0f, a01 = 0.0f;  // col = a00 ds + a01 dt + kTagCells / 2
  float a10 = 0.0f, a11 = 0.0f;  // row = a10 ds + a11 dt + kTagCells / 2
  float reach = 0.0f;            // |ds|, |dt| beyond this cannot be on the tag
  Vec3f normal_N = Vec3f::UnitZ();
  Vec3f center_world = Vec3f::Zero();
  bool visible = false;                            // per frame: the camera sees the printed side
  std::uint8_t cells[kTagCells * kTagCells] = {};  // 1 = white
};

/// A planar patch that can carry markers: a rectangle or one face of a box.
struct Surface {
  const Texture* texture = nullptr;
  std::vector<int> markers;  // indices into Scene::markers
};

/// Inclusive pixel rectangle; empty when u1 < u0 or v1 < v0.
struct PixelBox {
  int u0 = 0, u1 = -1, v0 = 0, v1 = -1;
};

struct RectC {  // rectangle, per frame in camera coordinates
  Vec3f n_c, u_c, v_c;
  float n_dot_c = 0, u_dot_c = 0, v_dot_c = 0;
  float half_u = 0, half_v = 0;
  float shade = 1.0f;
  int surface = 0;
  PixelBox footprint;  // per frame: pixels whose ray can hit it (render(), not the reference)
};

struct BoxC {
  Eigen::Matrix3f R_local_camera;
  Vec3f o_local;  // camera origin in box coordinates
  Vec3f half;
  float face_shade[6] = {};  // +x -x +y -y +z -z
  Vec3f face_normal_c[6];
  int surface0 = 0;                      // first of six surfaces
  int u0 = 0, u1 = -1, v0 = 0, v1 = -1;  // per frame: image bounding box (inclusive)
  PixelBox footprint;                    // per frame, cut at the near plane (render())
};

struct CylinderC {
  float ox = 0, oy = 0, oz = 0;  // camera origin relative to the base centre (world axes)
  float radius = 0, height = 0;
  float top_shade = 1.0f;
  const Texture* texture = nullptr;
  int u0 = 0, u1 = -1, v0 = 0, v1 = -1;  // per frame: image bounding box (inclusive)
  PixelBox footprint;                    // per frame, cut at the near plane (render())
};

enum class HitKind { kNone, kRect, kBox, kCylinderSide, kCylinderTop };

struct Hit {
  float t = kNoHit;
  HitKind kind = HitKind::kNone;
  int index = 0;
  int face = 0;
  float s = 0, u = 0;  // surface coordinates
};

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

/// Standard normal from one 64-bit hash: Irwin-Hall sum of four 16-bit uniforms (variance
/// 1/3 scaled to 1). Cheaper than Box-Muller per pixel and bounded at +-3.5 sigma.
float gaussian_from_hash(std::uint64_t h) {
  constexpr float kInv = 1.0f / 65536.0f;
  const float sum = static_cast<float>(h & 0xffff) + static_cast<float>((h >> 16) & 0xffff) +
                    static_cast<float>((h >> 32) & 0xffff) + static_cast<float>(h >> 48);
  return (sum * kInv - 2.0f) * 1.7320508f;
}

/// Intersection and shading tables; RgbdRenderer::Scene is this, under its private name.
struct SceneTables {
  std::vector<Rectangle> rects_world;  // floor first, then walls
  std::vector<Box> boxes_world;
  std::vector<Cylinder> cylinders_world;  // the world's, then one per person (moved per frame)
  std::vector<Walker> people;             // person i is cylinders_world[first_person + i]
  std::size_t first_person = 0;
  std::vector<Surface> surfaces;  // rects, then 6 per box
  std::vector<SurfaceMarker> markers;
  std::vector<RectC> rects;
  std::vector<BoxC> boxes;
  std::vector<CylinderC> cylinders;
  std::vector<float> ray_x;     // per column: x / z of its rays (the same as in ray_c_)
  std::vector<float> ray_y;     // per row: y / z
  std::vector<float> inv_norm;  // per pixel: 1 / |(x, y, 1)| (the same as in ray_c_)
  // Per frame (prepare_frame), shared by render() and render_reference().
  Eigen::Matrix3f R_N_C = Eigen::Matrix3f::Identity();
  Vec3f light = Vec3f::UnitZ();
  std::uint64_t frame_key = 0;
  // Per row of render()'s shading: surface coordinates, light, incidence cosine, albedo.
  std::vector<float> row_s, row_w, row_shade, row_cos, row_b, row_g, row_r;
  std::vector<float> row_depth_draw, row_image_draw;  // standard normal noise draws
  std::vector<std::int32_t> row_levels;  // intensity of b, g, r, gray (planes), before uint8
  std::vector<int> near_markers;         // per run: markers that can cover it (markers_near_run)
  std::vector<float> inverse_depth;      // per pixel: 1 / noise-free z, 0 without a hit
};

}  // namespace

struct RgbdRenderer::Scene : SceneTables {};

geometry::PinholeCamera pinhole_from_fov(int width, int height, double hfov_rad) {
  geometry::PinholeCamera camera;
  camera.width = width;
  camera.height = height;
  camera.fx = 0.5 * width / std::tan(0.5 * hfov_rad);
  camera.fy = camera.fx;
  camera.cx = 0.5 * (width - 1);
  camera.cy = 0.5 * (height - 1);
  return camera;
}

namespace {

Eigen::Matrix3d box_R_N_local(const Box& box) {
  return Eigen::AngleAxisd(box.yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

/// Surface frame (origin, normal, s axis, t axis) of face f of a box, in world coordinates.
void box_face_frame(const Box& box, int face, Eigen::Vector3d& origin, Eigen::Vector3d& normal,
                    Eigen::Vector3d& axis_s, Eigen::Vector3d& axis_t) {
  const Eigen::Matrix3d R = box_R_N_local(box);
  const int axis = face / 2;
  const double sign = (face % 2 == 0) ? 1.0 : -1.0;
  normal = sign * R.col(axis);
  origin = box.center_m + normal * 0.5 * box.size_m[axis];
  // Surface coordinates are the two other local coordinates, matching the hit computation.
  const int a = axis == 0 ? 1 : 0;
  const int b = axis == 2 ? 1 : 2;
  axis_s = R.col(a);
  axis_t = R.col(b);
}

bool on_plane(const Eigen::Vector3d& origin, const Eigen::Vector3d& normal,
              const Eigen::Vector3d& axis_s, const Eigen::Vector3d& axis_t, double half_s,
              double half_t, const Marker& m) {
  const Eigen::Vector3d d = m.center_N_m - origin;
  return std::abs(d.dot(normal)) < 0.01 && std::abs(m.normal_N.dot(normal)) > 0.99 &&
         std::abs(d.dot(axis_s)) <= half_s + 1e-6 && std::abs(d.dot(axis_t)) <= half_t + 1e-6;
}

SurfaceMarker make_marker(const Marker& m, const Eigen::Vector3d& origin,
                          const Eigen::Vector3d& axis_s, const Eigen::Vector3d& axis_t,
                          const cv::Ptr<cv::aruco::Dictionary>& dictionary) {
  SurfaceMarker sm;
  const Eigen::Vector3d& n = m.normal_N;
  // Default "up" of the printed tag: world z on walls, world x on horizontal surfaces.
  Eigen::Vector3d up = std::abs(n.z()) > 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitZ();
  up = (up - up.dot(n) * n).normalized();
  up = Eigen::AngleAxisd(m.rotation_rad, n) * up;
  // Seen from the side n points to (x right, y up, z = n towards the viewer): right = up x n.
  const Eigen::Vector3d right = up.cross(n);
  const Eigen::Vector3d down = -up;
  const double cell_m = m.size_m / 8.0;
  const Eigen::Vector3d d = m.center_N_m - origin;
  sm.s0 = static_cast<float>(d.dot(axis_s));
  sm.t0 = static_cast<float>(d.dot(axis_t));
  sm.a00 = static_cast<float>(axis_s.dot(right) / cell_m);
  sm.a01 = static_cast<float>(axis_t.dot(right) / cell_m);
  sm.a10 = static_cast<float>(axis_s.dot(down) / cell_m);
  sm.a11 = static_cast<float>(axis_t.dot(down) / cell_m);
  sm.reach = static_cast<float>(cell_m * kTagCells * 0.7072);
  sm.normal_N = n.cast<float>();
  sm.center_world = m.center_N_m.cast<float>();

  cv::Mat tag;
  dictionary->drawMarker(m.id, 8, tag, 1);  // one pixel per cell: 6x6 code + black border
  for (int r = 0; r < kTagCells; ++r) {
    for (int c = 0; c < kTagCells; ++c) {
      const int tr = r - kTagMargin;
      const int tc = c - kTagMargin;
      const bool margin = tr < 0 || tc < 0 || tr >= 8 || tc >= 8;
      sm.cells[r * kTagCells + c] = margin ? 1 : (tag.at<std::uint8_t>(tr, tc) > 127);
    }
  }
  return sm;
}

/// Image bounding box of a world-frame axis-aligned-in-local box given by 8 corners; the whole
/// image if any corner is near or behind the camera. Lets a pixel skip primitives it cannot
/// hit: the test is 4 compares instead of a slab or quadratic intersection.
void screen_bounds(const Eigen::Vector3d corners_world[8], const Eigen::Matrix3d& R_C_N,
                   const Eigen::Vector3d& p_N_C, const geometry::PinholeCamera& cam, int& u0,
                   int& u1, int& v0, int& v1) {
  double min_u = 1e30, max_u = -1e30, min_v = 1e30, max_v = -1e30;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d p = R_C_N * (corners_world[i] - p_N_C);
    if (p.z() < 1e-3) {
      u0 = 0;
      v0 = 0;
      u1 = cam.width - 1;
      v1 = cam.height - 1;
      return;
    }
    const Eigen::Vector2d uv = cam.project(p);
    min_u = std::min(min_u, uv.x());
    max_u = std::max(max_u, uv.x());
    min_v = std::min(min_v, uv.y());
    max_v = std::max(max_v, uv.y());
  }
  u0 = static_cast<int>(std::clamp(std::floor(min_u) - 1.0, 0.0, cam.width - 1.0));
  u1 = static_cast<int>(std::clamp(std::ceil(max_u) + 1.0, -1.0, cam.width - 1.0));
  v0 = static_cast<int>(std::clamp(std::floor(min_v) - 1.0, 0.0, cam.height - 1.0));
  v1 = static_cast<int>(std::clamp(std::ceil(max_v) + 1.0, -1.0, cam.height - 1.0));
  if (max_u < 0.0 || max_v < 0.0) u1 = -1;  // entirely left of or above the image
}

/// The world's primitives and the planar surfaces (rectangles, then six faces per box) that
/// can carry markers.
void build_tables(SceneTables& sc, const World& world) {
  sc.rects_world.push_back(world.floor);
  sc.rects_world.insert(sc.rects_world.end(), world.walls.begin(), world.walls.end());
  sc.boxes_world = world.boxes;
  sc.cylinders_world = world.cylinders;
  // A person is a cylinder of its own, its centre set per frame (place_people()): the tables
  // are sized here, so no frame allocates.
  sc.people = world.people;
  sc.first_person = sc.cylinders_world.size();
  for (const Walker& walker : world.people) sc.cylinders_world.push_back(body_at(walker, 0.0));
  for (const Rectangle& r : sc.rects_world) {
    Surface s;
    s.texture = &r.texture;
    sc.surfaces.push_back(s);
  }
  for (const Box& b : sc.boxes_world) {
    for (int f = 0; f < 6; ++f) {
      Surface s;
      s.texture = &b.texture;
      sc.surfaces.push_back(s);
    }
  }
  sc.rects.resize(sc.rects_world.size());
  sc.boxes.resize(sc.boxes_world.size());
  sc.cylinders.resize(sc.cylinders_world.size());
  for (std::size_t i = 0; i < sc.rects_world.size(); ++i) sc.rects[i].surface = static_cast<int>(i);
  for (std::size_t i = 0; i < sc.boxes_world.size(); ++i) {
    sc.boxes[i].surface0 = static_cast<int>(sc.rects_world.size() + 6 * i);
  }
  for (std::size_t i = 0; i < sc.cylinders_world.size(); ++i) {
    sc.cylinders[i].texture = &sc.cylinders_world[i].texture;
  }
}

/// Each marker onto the first rectangle or box face its centre and normal lie on; throws
/// hq::InputError naming the marker if there is none.
void place_markers(SceneTables& sc, const std::vector<Marker>& markers) {
  const cv::Ptr<cv::aruco::Dictionary> dictionary =
      cv::aruco::getPredefinedDictionary(cv::aruco::DICT_APRILTAG_36h11);
  for (std::size_t k = 0; k < markers.size(); ++k) {
    const Marker& m = markers[k];
    int surface = -1;
    Eigen::Vector3d origin, normal, axis_s, axis_t;
    for (std::size_t i = 0; i < sc.rects_world.size() && surface < 0; ++i) {
      const Rectangle& r = sc.rects_world[i];
      if (on_plane(r.center_m, r.normal, r.axis_u, r.axis_v, r.half_u_m, r.half_v_m, m)) {
        surface = static_cast<int>(i);
        origin = r.center_m;
        axis_s = r.axis_u;
        axis_t = r.axis_v;
      }
    }
    for (std::size_t i = 0; i < sc.boxes_world.size() && surface < 0; ++i) {
      const Box& b = sc.boxes_world[i];
      for (int f = 0; f < 6 && surface < 0; ++f) {
        box_face_frame(b, f, origin, normal, axis_s, axis_t);
        const int a = f / 2 == 0 ? 1 : 0;
        const int c = f / 2 == 2 ? 1 : 2;
        if (on_plane(origin, normal, axis_s, axis_t, 0.5 * b.size_m[a], 0.5 * b.size_m[c], m) &&
            m.normal_N.dot(normal) > 0.0) {
          surface = sc.boxes[i].surface0 + f;
        }
      }
    }
    if (surface < 0) {
      throw InputError("markers[" + std::to_string(k) + "] (id " + std::to_string(m.id) +
                       "): centre lies on no wall, floor or box face with that normal");
    }
    sc.markers.push_back(make_marker(m, origin, axis_s, axis_t, dictionary));
    sc.surfaces[static_cast<std::size_t>(surface)].markers.push_back(
        static_cast<int>(sc.markers.size() - 1));
  }
}

}  // namespace

RgbdRenderer::RgbdRenderer(const CameraParams& params, const World& world, std::uint64_t seed)
    : params_(params), seed_(seed), scene_(std::make_unique<Scene>()) {
  const geometry::PinholeCamera& cam = params_.pinhole;
  const int n = cam.width * cam.height;
  ray_c_.resize(static_cast<std::size_t>(3 * n));
  for (int v = 0; v < cam.height; ++v) {
    for (int u = 0; u < cam.width; ++u) {
      const Eigen::Vector3d ray_C = cam.ray(u, v);
      const double x = ray_C.x();
      const double y = ray_C.y();
      const std::size_t i = static_cast<std::size_t>(3 * (v * cam.width + u));
      ray_c_[i] = static_cast<float>(x);
      ray_c_[i + 1] = static_cast<float>(y);
      ray_c_[i + 2] = static_cast<float>(1.0 / std::sqrt(x * x + y * y + 1.0));
    }
  }
  true_depth_m_.create(cam.height, cam.width, CV_32F);
  hit_t_.resize(static_cast<std::size_t>(n));
  hit_code_.resize(static_cast<std::size_t>(n));

  Scene& sc = *scene_;
  sc.ray_x.resize(static_cast<std::size_t>(cam.width));
  for (std::vector<float>* row : {&sc.row_s, &sc.row_w, &sc.row_shade, &sc.row_cos, &sc.row_b,
                                  &sc.row_g, &sc.row_r, &sc.row_depth_draw, &sc.row_image_draw}) {
    row->resize(static_cast<std::size_t>(cam.width));
  }
  sc.inverse_depth.resize(static_cast<std::size_t>(n));
  sc.inv_norm.resize(static_cast<std::size_t>(n));
  sc.near_markers.resize(world.markers.size());
  for (std::size_t i = 0; i < sc.inv_norm.size(); ++i) sc.inv_norm[i] = ray_c_[3 * i + 2];
  sc.row_levels.resize(4 * static_cast<std::size_t>(cam.width));
  sc.ray_y.resize(static_cast<std::size_t>(cam.height));
  for (int u = 0; u < cam.width; ++u)
    sc.ray_x[static_cast<std::size_t>(u)] = ray_c_[3 * static_cast<std::size_t>(u)];
  for (int v = 0; v < cam.height; ++v) {
    sc.ray_y[static_cast<std::size_t>(v)] = ray_c_[3 * static_cast<std::size_t>(v * cam.width) + 1];
  }
  build_tables(sc, world);
  place_markers(sc, world.markers);
}

RgbdRenderer::~RgbdRenderer() = default;

namespace {

/// Footprints are cut at this depth, below the smallest accepted hit (t is z in C: the rays
/// have z = 1), so a face crossing the camera's plane keeps the part in front of it.
constexpr double kFootprintNearZ = 0.5 * static_cast<double>(kMinT);

/// Pixel bounding rectangle of convex polygons given in camera coordinates, each cut at
/// z = kFootprintNearZ (Sutherland-Hodgman against that one plane) before projection. A ray
/// through a pixel centre hitting a polygon projects inside its hull; the one-pixel margin
/// covers rounding.
class Footprint {
 public:
  explicit Footprint(const geometry::PinholeCamera& cam) : cam_(cam) {}

  void add_polygon(const Eigen::Vector3d* p_c, int n) {
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3d& a = p_c[i];
      const Eigen::Vector3d& b = p_c[(i + 1) % n];
      const bool a_in = a.z() >= kFootprintNearZ;
      if (a_in) add_point(a);
      if (a_in != (b.z() >= kFootprintNearZ)) {
        const double s = (kFootprintNearZ - a.z()) / (b.z() - a.z());
        Eigen::Vector3d cut = a + s * (b - a);
        cut.z() = kFootprintNearZ;
        add_point(cut);
      }
    }
  }

  /// The 6 faces of the parallelepiped with corner k at corners_c[k] (bit 0, 1, 2 of k: which
  /// end along the first, second, third edge direction).
  void add_box(const Eigen::Vector3d corners_c[8]) {
    for (int axis = 0; axis < 3; ++axis) {
      const int b = 1 << ((axis + 1) % 3);
      const int c = 1 << ((axis + 2) % 3);
      for (int side = 0; side < 2; ++side) {
        const int k = side << axis;
        const Eigen::Vector3d quad[4] = {corners_c[k], corners_c[k | b], corners_c[k | b | c],
                                         corners_c[k | c]};
        add_polygon(quad, 4);
      }
    }
  }

  [[nodiscard]] PixelBox pixels() const {
    PixelBox box;
    if (max_u_ < min_u_) return box;  // wholly behind the camera
    box.u0 = static_cast<int>(std::clamp(std::floor(min_u_) - 1.0, 0.0, 1.0 * cam_.width));
    box.u1 = static_cast<int>(std::clamp(std::ceil(max_u_) + 1.0, -1.0, cam_.width - 1.0));
    box.v0 = static_cast<int>(std::clamp(std::floor(min_v_) - 1.0, 0.0, 1.0 * cam_.height));
    box.v1 = static_cast<int>(std::clamp(std::ceil(max_v_) + 1.0, -1.0, cam_.height - 1.0));
    return box;
  }

 private:
  void add_point(const Eigen::Vector3d& p) {
    const Eigen::Vector2d uv = cam_.project(p);
    min_u_ = std::min(min_u_, uv.x());
    max_u_ = std::max(max_u_, uv.x());
    min_v_ = std::min(min_v_, uv.y());
    max_v_ = std::max(max_v_, uv.y());
  }

  const geometry::PinholeCamera& cam_;
  double min_u_ = 1e300, max_u_ = -1e300, min_v_ = 1e300, max_v_ = -1e300;
};

/// Per-pixel hit code of the z-buffer: which primitive (in the reference's test order) and
/// which face of it won.
constexpr std::int32_t kNoCode = -1;
std::int32_t hit_code(HitKind kind, int index, int face) {
  return (static_cast<std::int32_t>(kind) << 24) | (index << 3) | face;
}

/// Per-frame constants of shading and of the depth model.
struct ShadeConstants {
  float ambient, diffuse;
  float fb, sigma_disparity, subpixels, min_range, max_range, cos_grazing, dark, image_sigma;
  int channels;
};

ShadeConstants shade_constants(const CameraParams& params) {
  const DepthSensorParams& dp = params.depth;
  ShadeConstants k{};
  k.ambient = static_cast<float>(params.ambient);
  k.diffuse = static_cast<float>(params.diffuse);
  k.fb = static_cast<float>(dp.disparity_focal_px * dp.baseline_m);
  k.sigma_disparity = static_cast<float>(dp.noise_sigma_per_m2) * k.fb;  // sigma_z = k z^2
  k.subpixels = static_cast<float>(dp.disparity_subpixels);
  k.min_range = static_cast<float>(dp.min_range_m);
  k.max_range = static_cast<float>(dp.max_range_m);
  k.cos_grazing = static_cast<float>(std::cos(dp.grazing_max_rad));
  k.dark = static_cast<float>(dp.dark_albedo);
  k.image_sigma = static_cast<float>(params.image_noise_sigma);
  k.channels = params.gray ? 1 : 3;
  return k;
}

/// The camera's pose and light for one frame, as prepare_frame() turns primitives into C.
struct FrameView {
  const geometry::PinholeCamera& cam;
  Eigen::Matrix3d R_N_C;
  Eigen::Matrix3d R_C_N;
  Eigen::Vector3d p_N_C;
  Eigen::Vector3d light_N;  // unit, towards the light
  double ambient, diffuse;

  [[nodiscard]] float lambert(const Eigen::Vector3d& n_N) const {
    return static_cast<float>(ambient + diffuse * std::max(0.0, n_N.dot(light_N)));
  }
  [[nodiscard]] Eigen::Vector3d to_camera(const Eigen::Vector3d& p_N) const {
    return R_C_N * (p_N - p_N_C);
  }
};

void prepare_rects(SceneTables& sc, const FrameView& view) {
  const geometry::PinholeCamera& cam = view.cam;
  for (std::size_t i = 0; i < sc.rects.size(); ++i) {
    const Rectangle& r = sc.rects_world[i];
    RectC& rc = sc.rects[i];
    const Eigen::Vector3d c_c = view.R_C_N * (r.center_m - view.p_N_C);
    Eigen::Vector3d n_N = r.normal;
    if (n_N.dot(view.p_N_C - r.center_m) < 0.0) n_N = -n_N;  // the side we see
    rc.n_c = (view.R_C_N * n_N).cast<float>();
    rc.u_c = (view.R_C_N * r.axis_u).cast<float>();
    rc.v_c = (view.R_C_N * r.axis_v).cast<float>();
    rc.n_dot_c = rc.n_c.dot(c_c.cast<float>());
    rc.u_dot_c = rc.u_c.dot(c_c.cast<float>());
    rc.v_dot_c = rc.v_c.dot(c_c.cast<float>());
    rc.half_u = static_cast<float>(r.half_u_m);
    rc.half_v = static_cast<float>(r.half_v_m);
    rc.shade = view.lambert(n_N);
    const Eigen::Vector3d du = r.half_u_m * r.axis_u;
    const Eigen::Vector3d dv = r.half_v_m * r.axis_v;
    const Eigen::Vector3d quad[4] = {
        view.to_camera(r.center_m - du - dv), view.to_camera(r.center_m + du - dv),
        view.to_camera(r.center_m + du + dv), view.to_camera(r.center_m - du + dv)};
    Footprint footprint(cam);
    footprint.add_polygon(quad, 4);
    rc.footprint = footprint.pixels();
  }
}

void prepare_boxes(SceneTables& sc, const FrameView& view) {
  const geometry::PinholeCamera& cam = view.cam;
  for (std::size_t i = 0; i < sc.boxes.size(); ++i) {
    const Box& b = sc.boxes_world[i];
    BoxC& bc = sc.boxes[i];
    const Eigen::Matrix3d R_N_local = box_R_N_local(b);
    bc.R_local_camera = (R_N_local.transpose() * view.R_N_C).cast<float>();
    bc.o_local = (R_N_local.transpose() * (view.p_N_C - b.center_m)).cast<float>();
    bc.half = (0.5 * b.size_m).cast<float>();
    for (int f = 0; f < 6; ++f) {
      const Eigen::Vector3d n_N = (f % 2 == 0 ? 1.0 : -1.0) * R_N_local.col(f / 2);
      bc.face_shade[f] = view.lambert(n_N);
      bc.face_normal_c[f] = (view.R_C_N * n_N).cast<float>();
    }
    Eigen::Vector3d corners[8];
    Eigen::Vector3d corners_c[8];
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3d sign((k & 1) ? 1.0 : -1.0, (k & 2) ? 1.0 : -1.0, (k & 4) ? 1.0 : -1.0);
      corners[k] = b.center_m + R_N_local * (0.5 * b.size_m.cwiseProduct(sign));
      corners_c[k] = view.to_camera(corners[k]);
    }
    screen_bounds(corners, view.R_C_N, view.p_N_C, cam, bc.u0, bc.u1, bc.v0, bc.v1);
    Footprint footprint(cam);
    footprint.add_box(corners_c);
    bc.footprint = footprint.pixels();
  }
}

void prepare_cylinders(SceneTables& sc, const FrameView& view) {
  const geometry::PinholeCamera& cam = view.cam;
  for (std::size_t i = 0; i < sc.cylinders.size(); ++i) {
    const Cylinder& c = sc.cylinders_world[i];
    CylinderC& cc = sc.cylinders[i];
    cc.ox = static_cast<float>(view.p_N_C.x() - c.center_m.x());
    cc.oy = static_cast<float>(view.p_N_C.y() - c.center_m.y());
    cc.oz = static_cast<float>(view.p_N_C.z() - c.base_z_m);
    cc.radius = static_cast<float>(c.radius_m);
    cc.height = static_cast<float>(c.height_m);
    cc.top_shade = view.lambert(Eigen::Vector3d::UnitZ());
    Eigen::Vector3d corners[8];
    Eigen::Vector3d corners_c[8];
    for (int k = 0; k < 8; ++k) {
      corners[k] = Eigen::Vector3d(c.center_m.x() + ((k & 1) ? c.radius_m : -c.radius_m),
                                   c.center_m.y() + ((k & 2) ? c.radius_m : -c.radius_m),
                                   c.base_z_m + ((k & 4) ? c.height_m : 0.0));
      corners_c[k] = view.to_camera(corners[k]);
    }
    screen_bounds(corners, view.R_C_N, view.p_N_C, cam, cc.u0, cc.u1, cc.v0, cc.v1);
    Footprint footprint(cam);
    footprint.add_box(corners_c);  // the cylinder's bounding box
    cc.footprint = footprint.pixels();
  }
}

/// Each person's cylinder where the person is at t_s. Its texture coordinates are relative to
/// the cylinder (angle about its axis, height above its base), so the clothes move with it.
void place_people(SceneTables& sc, double t_s) {
  for (std::size_t i = 0; i < sc.people.size(); ++i) {
    sc.cylinders_world[sc.first_person + i].center_m = body_at(sc.people[i], t_s).center_m;
  }
}

}  // namespace

void RgbdRenderer::prepare_frame(const Eigen::Isometry3d& T_N_C, double t_s) {
  Scene& sc = *scene_;
  place_people(sc, t_s);
  // Per frame: every primitive in camera coordinates, so that a pixel only dots its fixed ray.
  const Eigen::Vector3d light = params_.light_dir_N.normalized();
  const FrameView view{params_.pinhole,     T_N_C.linear(), T_N_C.linear().transpose(),
                       T_N_C.translation(), light,          params_.ambient,
                       params_.diffuse};
  prepare_rects(sc, view);
  prepare_boxes(sc, view);
  prepare_cylinders(sc, view);
  const Eigen::Vector3d& p_N_C = view.p_N_C;
  for (SurfaceMarker& m : sc.markers) {
    m.visible = m.normal_N.dot(p_N_C.cast<float>() - m.center_world) > 0.0f;
  }
  sc.R_N_C = T_N_C.linear().cast<float>();
  sc.light = light.cast<float>();
}

namespace {

/// Shades one pixel given its nearest hit: texture and markers, Lambert lighting, image noise
/// and the structured-light depth model. Writes the pixel's channels, measured depth and
/// noise-free z (0 without a hit).
inline void shade_pixel(const SceneTables& sc, const ShadeConstants& k, const Hit& hit,
                        const float* ray, int pixel, std::uint8_t* out, float& depth_out,
                        float& z_true_out) {
  const Vec3f d(ray[0], ray[1], 1.0f);
  float pixel_value[3] = {0.0f, 0.0f, 0.0f};
  float z_true = 0.0f;
  float depth = 0.0f;
  if (hit.kind != HitKind::kNone) {
    const Texture* texture = nullptr;
    const Surface* surface = nullptr;
    float shade = 1.0f;
    float cos_incidence = 1.0f;
    switch (hit.kind) {
      case HitKind::kRect: {
        const RectC& r = sc.rects[static_cast<std::size_t>(hit.index)];
        surface = &sc.surfaces[static_cast<std::size_t>(r.surface)];
        shade = r.shade;
        cos_incidence = -r.n_c.dot(d) * ray[2];
        break;
      }
      case HitKind::kBox: {
        const BoxC& b = sc.boxes[static_cast<std::size_t>(hit.index)];
        surface = &sc.surfaces[static_cast<std::size_t>(b.surface0 + hit.face)];
        shade = b.face_shade[hit.face];
        cos_incidence = -b.face_normal_c[hit.face].dot(d) * ray[2];
        break;
      }
      case HitKind::kCylinderSide: {
        const CylinderC& c = sc.cylinders[static_cast<std::size_t>(hit.index)];
        texture = c.texture;
        const float angle = hit.s / c.radius;
        const Vec3f n(std::cos(angle), std::sin(angle), 0.0f);
        const Vec3f dw = sc.R_N_C * d;
        shade = k.ambient + k.diffuse * std::max(0.0f, n.dot(sc.light));
        cos_incidence = -n.dot(dw) * ray[2];
        break;
      }
      case HitKind::kCylinderTop: {
        const CylinderC& c = sc.cylinders[static_cast<std::size_t>(hit.index)];
        texture = c.texture;
        shade = c.top_shade;
        cos_incidence = -(sc.R_N_C * d).z() * ray[2];
        break;
      }
      case HitKind::kNone:
        break;
    }
    if (surface != nullptr) texture = surface->texture;
    Vec3f albedo = texture->albedo(hit.s, hit.u);
    if (surface != nullptr) {
      for (int i : surface->markers) {
        const SurfaceMarker& m = sc.markers[static_cast<std::size_t>(i)];
        const float ds = hit.s - m.s0;
        const float dt = hit.u - m.t0;
        if (!m.visible || std::abs(ds) > m.reach || std::abs(dt) > m.reach) continue;
        const float col = m.a00 * ds + m.a01 * dt + 0.5f * kTagCells;
        const float row = m.a10 * ds + m.a11 * dt + 0.5f * kTagCells;
        if (col < 0.0f || row < 0.0f || col >= kTagCells || row >= kTagCells) continue;
        const bool white = m.cells[static_cast<int>(row) * kTagCells + static_cast<int>(col)] != 0;
        albedo.setConstant(white ? kTagWhiteAlbedo : kTagBlackAlbedo);
        break;
      }
    }
    for (int c = 0; c < 3; ++c) pixel_value[c] = 255.0f * shade * albedo[c];

    z_true = hit.t;
    const float luminance = (albedo[0] + albedo[1] + albedo[2]) * (1.0f / 3.0f);
    if (luminance >= k.dark && cos_incidence >= k.cos_grazing) {
      // Structured light measures disparity fb / z: Gaussian disparity noise and sub-pixel
      // quantisation make sigma_z grow with z^2 (Khoshelham 2012, eq. 9).
      float disparity = k.fb / z_true;
      if (k.sigma_disparity > 0.0f) {
        disparity +=
            k.sigma_disparity *
            gaussian_from_hash(splitmix64(sc.frame_key ^ (2 * static_cast<std::uint64_t>(pixel))));
      }
      if (k.subpixels > 0.0f) disparity = std::round(disparity * k.subpixels) / k.subpixels;
      if (disparity > 0.0f) {
        const float z = k.fb / disparity;
        depth = (z >= k.min_range && z <= k.max_range) ? z : 0.0f;
      }
    }
  }
  z_true_out = z_true;
  depth_out = depth;
  const float noise =
      k.image_sigma > 0.0f
          ? k.image_sigma * gaussian_from_hash(splitmix64(
                                sc.frame_key ^ (2 * static_cast<std::uint64_t>(pixel) + 1)))
          : 0.0f;
  for (int c = 0; c < k.channels; ++c) {
    const float value = k.channels == 1 ? 0.114f * pixel_value[0] + 0.587f * pixel_value[1] +
                                              0.299f * pixel_value[2]
                                        : pixel_value[c];
    out[c] = static_cast<std::uint8_t>(std::clamp(value + noise + 0.5f, 0.0f, 255.0f));
  }
}

}  // namespace

namespace {

/// The planar surface (rectangle or box face) a hit code names; nullptr for a cylinder.
const Surface* surface_of(const SceneTables& sc, std::int32_t code) {
  const int index = (code >> 3) & 0x1fffff;
  switch (static_cast<HitKind>(code >> 24)) {
    case HitKind::kRect:
      return &sc.surfaces[static_cast<std::size_t>(
          sc.rects[static_cast<std::size_t>(index)].surface)];
    case HitKind::kBox:
      return &sc.surfaces[static_cast<std::size_t>(
          sc.boxes[static_cast<std::size_t>(index)].surface0 + (code & 7))];
    default:
      return nullptr;
  }
}

const Texture* cylinder_texture(const SceneTables& sc, std::int32_t code) {
  return sc.cylinders[static_cast<std::size_t>((code >> 3) & 0x1fffff)].texture;
}

/// Replaces the albedo by the cell of the first visible marker of the surface covering (s, w).
inline void paint_markers(const SceneTables& sc, const int* markers, int count, float s, float w,
                          float& b, float& g, float& r) {
  for (int k = 0; k < count; ++k) {
    const SurfaceMarker& m = sc.markers[static_cast<std::size_t>(markers[k])];
    const float ds = s - m.s0;
    const float dt = w - m.t0;
    if (!m.visible || std::abs(ds) > m.reach || std::abs(dt) > m.reach) continue;
    const float col = m.a00 * ds + m.a01 * dt + 0.5f * kTagCells;
    const float row = m.a10 * ds + m.a11 * dt + 0.5f * kTagCells;
    if (col < 0.0f || row < 0.0f || col >= kTagCells || row >= kTagCells) continue;
    const bool white = m.cells[static_cast<int>(row) * kTagCells + static_cast<int>(col)] != 0;
    b = g = r = white ? kTagWhiteAlbedo : kTagBlackAlbedo;
    return;
  }
}

/// The visible markers of a surface that can cover a pixel of the run (s_m, w_m)[0, n), in
/// the surface's order, into near; returns how many. A marker is left out only if its square
/// of half-side reach misses the run's (s, t) bounding box by more than 1 cm, so float
/// rounding cannot leave out one that paint_markers() would paint.
int markers_near_run(const SceneTables& sc, const Surface& surface, const float* s_m,
                     const float* w_m, int n, int* near) {
  float s_lo = s_m[0], s_hi = s_m[0], t_lo = w_m[0], t_hi = w_m[0];
  for (int i = 1; i < n; ++i) {
    s_lo = std::min(s_lo, s_m[i]);
    s_hi = std::max(s_hi, s_m[i]);
    t_lo = std::min(t_lo, w_m[i]);
    t_hi = std::max(t_hi, w_m[i]);
  }
  constexpr float kMargin = 0.01f;
  int count = 0;
  for (int i : surface.markers) {
    const SurfaceMarker& m = sc.markers[static_cast<std::size_t>(i)];
    const float reach = m.reach + kMargin;
    if (!m.visible || m.s0 + reach < s_lo || m.s0 - reach > s_hi || m.t0 + reach < t_lo ||
        m.t0 - reach > t_hi) {
      continue;
    }
    near[count++] = i;
  }
  return count;
}

/// Standard normal draws for the n pixels from index `first` on, of the stream `odd` (0:
/// depth, 1: image): shade_pixel()'s hash per pixel. Built also for AVX-512 (a native 64-bit
/// multiply) and AVX2, picked at load time; integer work but for the last scaling, which
/// -ffp-contract=off keeps from fusing.
HQ_CLONES_AVX512 void noise_draws(std::uint64_t frame_key, std::uint64_t first, std::uint64_t odd,
                                  int n, float* draw) {
#pragma omp simd
  for (int u = 0; u < n; ++u) {
    const std::uint64_t pixel = first + static_cast<std::uint64_t>(u);
    draw[u] = gaussian_from_hash(splitmix64(frame_key ^ (2ull * pixel + odd)));
  }
}

/// One row's inputs and outputs of the colour and depth-model stage.
struct RowStage {
  const std::int32_t* code;
  const float* t;
  const float* shade;
  const float* cos_incidence;
  const float *b, *g, *r;  // albedo
  const float* depth_draw;
  const float* image_draw;
  float* true_depth;
  float* depth;
  std::int32_t *level_b, *level_g, *level_r, *level_gray;
};

/// Colour, depth model and noise: shade_pixel()'s operations, branch-free so that they
/// vectorise, every conditional a select. (GCC 12 if-converts none of it in AVX2 or AVX-512
/// target clones, so it has none.)
void colour_and_depth(const ShadeConstants& k, const RowStage& row, int n) {
  const bool quantise = k.subpixels > 0.0f;
  // std::round (half away from zero) without a library call or a branch (the fraction is as
  // likely above as below one half); exact, as x - trunc(x) is.
  const auto round_half_away = [](float x) {
    // |x| >= 2^23 is an integer already (or not finite): x itself. Clamping first keeps the
    // int32 conversion defined.
    const float bounded = std::min(std::max(x, -8388608.0f), 8388608.0f);
    const auto truncated = static_cast<float>(static_cast<std::int32_t>(bounded));
    const float fraction = bounded - truncated;
    const float rounded =
        truncated + (fraction >= 0.5f ? 1.0f : 0.0f) - (fraction <= -0.5f ? 1.0f : 0.0f);
    return std::abs(x) < 8388608.0f ? rounded : x;
  };
#pragma omp simd
  for (int u = 0; u < n; ++u) {
    // Unconditional loads (stale values where nothing was hit are selected away): a load
    // under a condition would need a masked load, which SSE2 lacks.
    const bool hit = row.code[u] != kNoCode;
    const float light = row.shade[u];
    const float t = row.t[u];
    const float b = row.b[u];
    const float g = row.g[u];
    const float r = row.r[u];
    const float value_b = hit ? 255.0f * light * b : 0.0f;
    const float value_g = hit ? 255.0f * light * g : 0.0f;
    const float value_r = hit ? 255.0f * light * r : 0.0f;
    const float z_true = hit ? t : 0.0f;
    const float luminance = (b + g + r) * (1.0f / 3.0f);
    const bool measured = hit & (luminance >= k.dark) & (row.cos_incidence[u] >= k.cos_grazing);
    // Structured light: disparity fb / z, its noise and quantisation (Khoshelham 2012).
    float disparity = k.fb / z_true + k.sigma_disparity * row.depth_draw[u];
    disparity = quantise ? round_half_away(disparity * k.subpixels) / k.subpixels : disparity;
    const float z = k.fb / disparity;
    const bool in_range = (disparity > 0.0f) & (z >= k.min_range) & (z <= k.max_range);
    row.true_depth[u] = z_true;
    row.depth[u] = (measured & in_range) ? z : 0.0f;
    const float noise = k.image_sigma * row.image_draw[u];
    // Clamped to [0, 255]: truncating to int32 here and to uint8 by the caller gives what a
    // direct cast gives. Planar: GCC vectorises neither a narrowing select nor stores three
    // apart.
    const auto level = [](float x) {
      return static_cast<std::int32_t>(std::min(std::max(x, 0.0f), 255.0f));
    };
    const float gray = 0.114f * value_b + 0.587f * value_g + 0.299f * value_r;
    row.level_gray[u] = level(gray + noise + 0.5f);
    row.level_b[u] = level(value_b + noise + 0.5f);
    row.level_g[u] = level(value_g + noise + 0.5f);
    row.level_r[u] = level(value_r + noise + 0.5f);
  }
}

/// The z-buffer render() fills: per pixel the nearest hit's t (z in C) and its hit code.
struct ZBuffer {
  float* t;
  std::int32_t* code;
  int width;
};

/// Visibility of the rectangles: each tests only the pixels of its footprint and z-tests its
/// hits. Primitives go in the reference's order with the same strict comparisons, so the same
/// one wins a tie.
void zbuffer_rects(const SceneTables& sc, const ZBuffer& zb) {
  const int width = zb.width;
  const float* ray_x = sc.ray_x.data();
  for (std::size_t i = 0; i < sc.rects.size(); ++i) {
    const RectC& r = sc.rects[i];
    const PixelBox& fp = r.footprint;
    const std::int32_t code = hit_code(HitKind::kRect, static_cast<int>(i), 0);
    for (int v = fp.v0; v <= fp.v1; ++v) {
      // n . d with d = (x, y, 1) sums as n_x x + (n_y y + n_z), the order Eigen's dot uses, so
      // the row-constant part can be hoisted without changing a bit.
      const float y = sc.ray_y[static_cast<std::size_t>(v)];
      const float n_y = r.n_c.y() * y + r.n_c.z();
      const float u_y = r.u_c.y() * y + r.u_c.z();
      const float v_y = r.v_c.y() * y + r.v_c.z();
      float* t_row = zb.t + static_cast<std::ptrdiff_t>(v) * width;
      std::int32_t* code_row = zb.code + static_cast<std::ptrdiff_t>(v) * width;
      const int u_end = fp.u1 + 1;  // a < bound lets the vectoriser count the iterations
      for (int u = fp.u0; u < u_end; ++u) {
        const float x = ray_x[u];
        const float denom = r.n_c.x() * x + n_y;
        const float t = r.n_dot_c / denom;
        const float s = t * (r.u_c.x() * x + u_y) - r.u_dot_c;
        const float w = t * (r.v_c.x() * x + v_y) - r.v_dot_c;
        // Seen from the front (n faces the camera), in front of it, nearer, inside; & rather
        // than && keeps the loop free of branches, so it vectorises.
        const bool inside_u = std::abs(s) <= r.half_u;
        const bool inside_v = std::abs(w) <= r.half_v;
        const bool hit = (denom <= -1e-6f) & (t >= kMinT) & (t < t_row[u]) & inside_u & inside_v;
        t_row[u] = hit ? t : t_row[u];
        code_row[u] = hit ? code : code_row[u];
      }
    }
  }
}

/// Visibility of the boxes (slab test), after the rectangles.
void zbuffer_boxes(const SceneTables& sc, const ZBuffer& zb) {
  const int width = zb.width;
  const float* ray_x = sc.ray_x.data();
  for (std::size_t i = 0; i < sc.boxes.size(); ++i) {
    const BoxC& b = sc.boxes[i];
    const PixelBox& fp = b.footprint;
    for (int v = fp.v0; v <= fp.v1; ++v) {
      const float y = sc.ray_y[static_cast<std::size_t>(v)];
      float* t_row = zb.t + static_cast<std::ptrdiff_t>(v) * width;
      std::int32_t* code_row = zb.code + static_cast<std::ptrdiff_t>(v) * width;
      for (int u = fp.u0; u <= fp.u1; ++u) {
        const Vec3f d(ray_x[u], y, 1.0f);
        const Vec3f dl = b.R_local_camera * d;
        float t_near = -kNoHit;
        float t_far = kNoHit;
        int axis = 0;
        for (int k = 0; k < 3; ++k) {
          const float inv = 1.0f / dl[k];
          float t0 = (-b.half[k] - b.o_local[k]) * inv;
          float t1 = (b.half[k] - b.o_local[k]) * inv;
          if (t0 > t1) std::swap(t0, t1);
          if (t0 > t_near) {
            t_near = t0;
            axis = k;
          }
          t_far = std::min(t_far, t1);
        }
        if (t_near > t_far || t_near < kMinT || t_near >= t_row[u]) continue;
        const int face = 2 * axis + (dl[axis] < 0.0f ? 0 : 1);  // entering through +axis
        t_row[u] = t_near;
        code_row[u] = hit_code(HitKind::kBox, static_cast<int>(i), face);
      }
    }
  }
}

/// Visibility of the cylinders (side, then top), after the boxes.
void zbuffer_cylinders(const SceneTables& sc, const ZBuffer& zb) {
  const int width = zb.width;
  const float* ray_x = sc.ray_x.data();
  for (std::size_t i = 0; i < sc.cylinders.size(); ++i) {
    const CylinderC& c = sc.cylinders[i];
    const PixelBox& fp = c.footprint;
    const std::int32_t side_code = hit_code(HitKind::kCylinderSide, static_cast<int>(i), 0);
    const std::int32_t top_code = hit_code(HitKind::kCylinderTop, static_cast<int>(i), 0);
    for (int v = fp.v0; v <= fp.v1; ++v) {
      const float y = sc.ray_y[static_cast<std::size_t>(v)];
      float* t_row = zb.t + static_cast<std::ptrdiff_t>(v) * width;
      std::int32_t* code_row = zb.code + static_cast<std::ptrdiff_t>(v) * width;
      for (int u = fp.u0; u <= fp.u1; ++u) {
        const Vec3f dw = sc.R_N_C * Vec3f(ray_x[u], y, 1.0f);
        const float a = dw.x() * dw.x() + dw.y() * dw.y();
        const float b = c.ox * dw.x() + c.oy * dw.y();
        const float cc = c.ox * c.ox + c.oy * c.oy - c.radius * c.radius;
        const float disc = b * b - a * cc;
        if (a > 1e-12f && disc >= 0.0f) {
          const float t = (-b - std::sqrt(disc)) / a;
          const float z = c.oz + t * dw.z();
          if (t > kMinT && t < t_row[u] && z >= 0.0f && z <= c.height) {
            t_row[u] = t;
            code_row[u] = side_code;
          }
        }
        if (dw.z() < -1e-6f && c.oz > c.height) {
          const float t = (c.height - c.oz) / dw.z();
          const float x = c.ox + t * dw.x();
          const float y_top = c.oy + t * dw.y();
          if (t > kMinT && t < t_row[u] && x * x + y_top * y_top <= c.radius * c.radius) {
            t_row[u] = t;
            code_row[u] = top_code;
          }
        }
      }
    }
  }
}

/// One row of the shading stages' buffers (SceneTables' row_* vectors).
struct ShadeRow {
  float *s_m, *w_m, *shade, *cos_incidence;
  float *b, *g, *r;  // albedo
  float *depth_draw, *image_draw;
  std::int32_t *level_b, *level_g, *level_r, *level_gray;  // planes of width
};

ShadeRow shade_row(SceneTables& sc, int width) {
  ShadeRow row{};
  row.s_m = sc.row_s.data();
  row.w_m = sc.row_w.data();
  row.shade = sc.row_shade.data();
  row.cos_incidence = sc.row_cos.data();
  row.b = sc.row_b.data();
  row.g = sc.row_g.data();
  row.r = sc.row_r.data();
  row.depth_draw = sc.row_depth_draw.data();
  row.image_draw = sc.row_image_draw.data();
  row.level_b = sc.row_levels.data();
  row.level_g = row.level_b + width;
  row.level_r = row.level_g + width;
  row.level_gray = row.level_r + width;
  return row;
}

/// surface_coordinates_row() for one pixel whose hit is not on a run of one rectangle.
inline void surface_coordinates_pixel(const SceneTables& sc, const ShadeConstants& k,
                                      std::int32_t code, float x, float y, float t, float ray_scale,
                                      float& s_m, float& w_m, float& shade, float& cos_incidence) {
  const Vec3f d(x, y, 1.0f);
  const int index = (code >> 3) & 0x1fffff;
  const int face = code & 7;
  switch (static_cast<HitKind>(code >> 24)) {
    case HitKind::kRect: {
      const RectC& rc = sc.rects[static_cast<std::size_t>(index)];
      s_m = t * rc.u_c.dot(d) - rc.u_dot_c;
      w_m = t * rc.v_c.dot(d) - rc.v_dot_c;
      shade = rc.shade;
      cos_incidence = -rc.n_c.dot(d) * ray_scale;
      break;
    }
    case HitKind::kBox: {
      const BoxC& bc = sc.boxes[static_cast<std::size_t>(index)];
      // dl first, as the reference: Eigen folds t * (R * d) into the product, which
      // rounds differently.
      const Vec3f dl = bc.R_local_camera * d;
      const Vec3f p = bc.o_local + t * dl;
      const int axis = face / 2;
      s_m = p[axis == 0 ? 1 : 0];
      w_m = p[axis == 2 ? 1 : 2];
      shade = bc.face_shade[face];
      cos_incidence = -bc.face_normal_c[face].dot(d) * ray_scale;
      break;
    }
    case HitKind::kCylinderSide: {
      const CylinderC& c = sc.cylinders[static_cast<std::size_t>(index)];
      const Vec3f dw = sc.R_N_C * d;
      s_m = std::atan2(c.oy + t * dw.y(), c.ox + t * dw.x()) * c.radius;
      w_m = c.oz + t * dw.z();
      const float angle = s_m / c.radius;
      const Vec3f n(std::cos(angle), std::sin(angle), 0.0f);
      shade = k.ambient + k.diffuse * std::max(0.0f, n.dot(sc.light));
      cos_incidence = -n.dot(dw) * ray_scale;
      break;
    }
    case HitKind::kCylinderTop: {
      const CylinderC& c = sc.cylinders[static_cast<std::size_t>(index)];
      const Vec3f dw = sc.R_N_C * d;
      s_m = c.ox + t * dw.x();
      w_m = c.oy + t * dw.y();
      shade = c.top_shade;
      cos_incidence = -dw.z() * ray_scale;
      break;
    }
    case HitKind::kNone:
      break;
  }
}

/// Row v's winners' surface coordinates, light and incidence, recomputed from their t by the
/// reference's expressions.
void surface_coordinates_row(const SceneTables& sc, const ShadeConstants& k, int v, int width,
                             const float* t_row, const std::int32_t* code_row,
                             const ShadeRow& out) {
  const float* ray_x = sc.ray_x.data();
  const float y = sc.ray_y[static_cast<std::size_t>(v)];
  const float* inv_norm_row = sc.inv_norm.data() + static_cast<std::ptrdiff_t>(v) * width;
  float* s_m = out.s_m;
  float* w_m = out.w_m;
  float* shade = out.shade;
  float* cos_incidence = out.cos_incidence;
  for (int u0 = 0; u0 < width;) {
    const std::int32_t run_code = code_row[u0];
    int u1 = u0 + 1;
    while (u1 < width && code_row[u1] == run_code) ++u1;
    if (run_code != kNoCode && static_cast<HitKind>(run_code >> 24) == HitKind::kRect) {
      // A run on one rectangle (most pixels: floor and walls), vectorised. Its dots sum as
      // x_term + (y_term + z_term), Eigen's order, so the row-constant part is hoisted
      // without changing a bit.
      const RectC& rc = sc.rects[static_cast<std::size_t>((run_code >> 3) & 0x1fffff)];
      const float u_y = rc.u_c.y() * y + rc.u_c.z();
      const float v_y = rc.v_c.y() * y + rc.v_c.z();
      const float n_y = rc.n_c.y() * y + rc.n_c.z();
#pragma omp simd
      for (int u = u0; u < u1; ++u) {
        const float x = ray_x[u];
        s_m[u] = t_row[u] * (rc.u_c.x() * x + u_y) - rc.u_dot_c;
        w_m[u] = t_row[u] * (rc.v_c.x() * x + v_y) - rc.v_dot_c;
        shade[u] = rc.shade;
        cos_incidence[u] = -(rc.n_c.x() * x + n_y) * inv_norm_row[u];
      }
      u0 = u1;
      continue;
    }
    for (int u = u0; u < u1; ++u) {
      s_m[u] = 0.0f;
      w_m[u] = 0.0f;
      if (code_row[u] == kNoCode) continue;
      surface_coordinates_pixel(sc, k, code_row[u], ray_x[u], y, t_row[u], inv_norm_row[u], s_m[u],
                                w_m[u], shade[u], cos_incidence[u]);
    }
    u0 = u1;
  }
}

/// Row v's albedo over runs of one surface (a vectorised texture loop), then its markers.
void albedo_row(SceneTables& sc, int width, const std::int32_t* code_row, const ShadeRow& out) {
  const float* s_m = out.s_m;
  const float* w_m = out.w_m;
  float* b = out.b;
  float* g = out.g;
  float* r = out.r;
  for (int u0 = 0; u0 < width;) {
    const std::int32_t code = code_row[u0];
    int u1 = u0 + 1;
    while (u1 < width && code_row[u1] == code) ++u1;
    if (code != kNoCode) {
      const Surface* surface = surface_of(sc, code);
      const Texture& texture = surface != nullptr ? *surface->texture : *cylinder_texture(sc, code);
      texture.albedo_span(s_m + u0, w_m + u0, u1 - u0, b + u0, g + u0, r + u0);
      if (surface != nullptr && !surface->markers.empty()) {
        // Only the markers near this run (a floor may carry dozens) are tested per pixel.
        int* near = sc.near_markers.data();
        const int count = markers_near_run(sc, *surface, s_m + u0, w_m + u0, u1 - u0, near);
        for (int u = u0; count > 0 && u < u1; ++u) {
          paint_markers(sc, near, count, s_m[u], w_m[u], b[u], g[u], r[u]);
        }
      }
    }
    u0 = u1;
  }
}

/// Row v's standard normal draws of depth and image noise.
void noise_row(const SceneTables& sc, const ShadeConstants& k, int v, int width,
               const ShadeRow& out) {
  float* depth_draw = out.depth_draw;
  float* image_draw = out.image_draw;
  // A zero sigma adds sigma * draw = +-0, which changes no value: the draws can be 0 then.
  const std::uint64_t first = static_cast<std::uint64_t>(v) * static_cast<std::uint64_t>(width);
  if (k.sigma_disparity > 0.0f) {
    noise_draws(sc.frame_key, first, 0ull, width, depth_draw);
  } else {
    std::fill(depth_draw, depth_draw + width, 0.0f);
  }
  if (k.image_sigma > 0.0f) {
    noise_draws(sc.frame_key, first, 1ull, width, image_draw);
  } else {
    std::fill(image_draw, image_draw + width, 0.0f);
  }
}

/// The row's intensity planes into the image row (interleaved BGR, or gray).
void write_image_row(const ShadeConstants& k, int width, const ShadeRow& row, std::uint8_t* out) {
  const std::int32_t* level_b = row.level_b;
  const std::int32_t* level_g = row.level_g;
  const std::int32_t* level_r = row.level_r;
  const std::int32_t* level_gray = row.level_gray;
  if (k.channels == 1) {
#pragma omp simd
    for (int u = 0; u < width; ++u) out[u] = static_cast<std::uint8_t>(level_gray[u]);
  } else {
    for (int u = 0; u < width; ++u) {
      out[3 * u] = static_cast<std::uint8_t>(level_b[u]);
      out[3 * u + 1] = static_cast<std::uint8_t>(level_g[u]);
      out[3 * u + 2] = static_cast<std::uint8_t>(level_r[u]);
    }
  }
}

}  // namespace

void RgbdRenderer::render(const Eigen::Isometry3d& T_N_C, double t_s, std::uint64_t frame_index,
                          cv::Mat& image, cv::Mat& depth_m) {
  const geometry::PinholeCamera& cam = params_.pinhole;
  image.create(cam.height, cam.width, params_.gray ? CV_8UC1 : CV_8UC3);
  depth_m.create(cam.height, cam.width, CV_32F);
  prepare_frame(T_N_C, t_s);
  Scene& sc = *scene_;
  sc.frame_key = splitmix64(seed_ ^ splitmix64(frame_index + 0x51ed27ull));
  const int width = cam.width;

  // 1. Visibility: each primitive tests only the pixels of its footprint and z-tests its hits
  // into (hit_t_, hit_code_).
  std::fill(hit_t_.begin(), hit_t_.end(), kNoHit);
  std::fill(hit_code_.begin(), hit_code_.end(), kNoCode);
  const ZBuffer zb{hit_t_.data(), hit_code_.data(), width};
  zbuffer_rects(sc, zb);
  zbuffer_boxes(sc, zb);
  zbuffer_cylinders(sc, zb);

  // 2. Shading, once per pixel and row by row in stages: the winner's surface coordinates,
  // light and incidence; albedo and markers; noise draws; then colour, depth model and noise.
  // The same operations as shade_pixel() in the same order: the same bits.
  const ShadeConstants k = shade_constants(params_);
  const ShadeRow row = shade_row(sc, width);
  for (int v = 0; v < cam.height; ++v) {
    const float* t_row = hit_t_.data() + static_cast<std::ptrdiff_t>(v) * width;
    const std::int32_t* code_row = hit_code_.data() + static_cast<std::ptrdiff_t>(v) * width;
    surface_coordinates_row(sc, k, v, width, t_row, code_row, row);
    albedo_row(sc, width, code_row, row);
    noise_row(sc, k, v, width, row);
    const RowStage stage{code_row,
                         t_row,
                         row.shade,
                         row.cos_incidence,
                         row.b,
                         row.g,
                         row.r,
                         row.depth_draw,
                         row.image_draw,
                         true_depth_m_.ptr<float>(v),
                         depth_m.ptr<float>(v),
                         row.level_b,
                         row.level_g,
                         row.level_r,
                         row.level_gray};
    colour_and_depth(k, stage, width);
    write_image_row(k, width, row, image.ptr<std::uint8_t>(v));
  }
  drop_depth_at_discontinuities_fast(depth_m);
}

void RgbdRenderer::render_reference(const Eigen::Isometry3d& T_N_C, double t_s,
                                    std::uint64_t frame_index, cv::Mat& image, cv::Mat& depth_m) {
  const geometry::PinholeCamera& cam = params_.pinhole;
  image.create(cam.height, cam.width, params_.gray ? CV_8UC1 : CV_8UC3);
  depth_m.create(cam.height, cam.width, CV_32F);
  prepare_frame(T_N_C, t_s);
  Scene& sc = *scene_;
  sc.frame_key = splitmix64(seed_ ^ splitmix64(frame_index + 0x51ed27ull));
  const Eigen::Matrix3f& R_N_C = sc.R_N_C;
  const ShadeConstants k = shade_constants(params_);

  for (int v = 0; v < cam.height; ++v) {
    std::uint8_t* out = image.ptr<std::uint8_t>(v);
    float* depth_row = depth_m.ptr<float>(v);
    float* true_row = true_depth_m_.ptr<float>(v);
    for (int u = 0; u < cam.width; ++u) {
      const int pixel = v * cam.width + u;
      const float* ray = &ray_c_[static_cast<std::size_t>(3 * pixel)];
      const Vec3f d(ray[0], ray[1], 1.0f);
      Hit hit;

      for (std::size_t i = 0; i < sc.rects.size(); ++i) {
        const RectC& r = sc.rects[i];
        const float denom = r.n_c.dot(d);
        if (denom > -1e-6f) continue;  // parallel or seen from behind (n faces the camera)
        const float t = r.n_dot_c / denom;
        if (t < kMinT || t >= hit.t) continue;
        const float s = t * r.u_c.dot(d) - r.u_dot_c;
        if (std::abs(s) > r.half_u) continue;
        const float w = t * r.v_c.dot(d) - r.v_dot_c;
        if (std::abs(w) > r.half_v) continue;
        hit = Hit{t, HitKind::kRect, static_cast<int>(i), 0, s, w};
      }
      for (std::size_t i = 0; i < sc.boxes.size(); ++i) {
        const BoxC& b = sc.boxes[i];
        if (u < b.u0 || u > b.u1 || v < b.v0 || v > b.v1) continue;
        const Vec3f dl = b.R_local_camera * d;
        float t_near = -kNoHit;
        float t_far = kNoHit;
        int axis = 0;
        for (int slab = 0; slab < 3; ++slab) {
          const float inv = 1.0f / dl[slab];
          float t0 = (-b.half[slab] - b.o_local[slab]) * inv;
          float t1 = (b.half[slab] - b.o_local[slab]) * inv;
          if (t0 > t1) std::swap(t0, t1);
          if (t0 > t_near) {
            t_near = t0;
            axis = slab;
          }
          t_far = std::min(t_far, t1);
        }
        if (t_near > t_far || t_near < kMinT || t_near >= hit.t) continue;
        const Vec3f p = b.o_local + t_near * dl;
        const int face = 2 * axis + (dl[axis] < 0.0f ? 0 : 1);  // entering through +axis
        const int a = axis == 0 ? 1 : 0;
        const int c = axis == 2 ? 1 : 2;
        hit = Hit{t_near, HitKind::kBox, static_cast<int>(i), face, p[a], p[c]};
      }
      if (!sc.cylinders.empty()) {
        const Vec3f dw = R_N_C * d;
        for (std::size_t i = 0; i < sc.cylinders.size(); ++i) {
          const CylinderC& c = sc.cylinders[i];
          if (u < c.u0 || u > c.u1 || v < c.v0 || v > c.v1) continue;
          const float a = dw.x() * dw.x() + dw.y() * dw.y();
          const float b = c.ox * dw.x() + c.oy * dw.y();
          const float cc = c.ox * c.ox + c.oy * c.oy - c.radius * c.radius;
          const float disc = b * b - a * cc;
          if (a > 1e-12f && disc >= 0.0f) {
            const float t = (-b - std::sqrt(disc)) / a;
            const float z = c.oz + t * dw.z();
            if (t > kMinT && t < hit.t && z >= 0.0f && z <= c.height) {
              const float angle = std::atan2(c.oy + t * dw.y(), c.ox + t * dw.x());
              hit = Hit{t, HitKind::kCylinderSide, static_cast<int>(i), 0, angle * c.radius, z};
            }
          }
          if (dw.z() < -1e-6f && c.oz > c.height) {
            const float t = (c.height - c.oz) / dw.z();
            const float x = c.ox + t * dw.x();
            const float y = c.oy + t * dw.y();
            if (t > kMinT && t < hit.t && x * x + y * y <= c.radius * c.radius) {
              hit = Hit{t, HitKind::kCylinderTop, static_cast<int>(i), 0, x, y};
            }
          }
        }
      }
      shade_pixel(sc, k, hit, ray, pixel, out + k.channels * u, depth_row[u], true_row[u]);
    }
  }
  drop_depth_at_discontinuities(depth_m);
}

void RgbdRenderer::drop_depth_at_discontinuities(cv::Mat& depth_m) const {
  // Structured light loses the pattern at depth discontinuities. On any plane inverse depth is
  // affine in the pixel coordinates, so its second difference vanishes (however oblique the
  // plane); a jump makes it large. Pixels on both sides of a jump, and next to empty space
  // (inverse depth 0), lose their depth. Image borders are left alone.
  const geometry::PinholeCamera& cam = params_.pinhole;
  const float jump = static_cast<float>(params_.depth.edge_jump_ratio);
  if (jump <= 0.0f) return;
  const auto inverse = [](float z) { return z > 0.0f ? 1.0f / z : 0.0f; };
  for (int v = 1; v + 1 < cam.height; ++v) {
    float* depth_row = depth_m.ptr<float>(v);
    const float* row = true_depth_m_.ptr<float>(v);
    const float* up = true_depth_m_.ptr<float>(v - 1);
    const float* down = true_depth_m_.ptr<float>(v + 1);
    for (int u = 1; u + 1 < cam.width; ++u) {
      if (depth_row[u] == 0.0f) continue;
      const float w = 1.0f / row[u];
      const float limit = jump * w;
      if (std::abs(inverse(row[u - 1]) + inverse(row[u + 1]) - 2.0f * w) > limit ||
          std::abs(inverse(up[u]) + inverse(down[u]) - 2.0f * w) > limit) {
        depth_row[u] = 0.0f;
      }
    }
  }
}

void RgbdRenderer::drop_depth_at_discontinuities_fast(cv::Mat& depth_m) {
  // drop_depth_at_discontinuities() with each inverse depth computed once instead of five
  // times: 1 / z is the same float wherever it is computed.
  const geometry::PinholeCamera& cam = params_.pinhole;
  const float jump = static_cast<float>(params_.depth.edge_jump_ratio);
  if (jump <= 0.0f) return;
  Scene& sc = *scene_;
  const int width = cam.width;
  for (int v = 0; v < cam.height; ++v) {
    const float* row = true_depth_m_.ptr<float>(v);
    float* inverse = sc.inverse_depth.data() + static_cast<std::ptrdiff_t>(v) * width;
#pragma omp simd
    for (int u = 0; u < width; ++u) inverse[u] = row[u] > 0.0f ? 1.0f / row[u] : 0.0f;
  }
  for (int v = 1; v + 1 < cam.height; ++v) {
    float* depth_row = depth_m.ptr<float>(v);
    const float* w = sc.inverse_depth.data() + static_cast<std::ptrdiff_t>(v) * width;
    const float* up = w - width;
    const float* down = w + width;
#pragma omp simd
    for (int u = 1; u < width - 1; ++u) {
      // A valid depth has a hit, so w[u] is the reference's 1.0f / row[u].
      const float limit = jump * w[u];
      const bool jump_u = std::abs(w[u - 1] + w[u + 1] - 2.0f * w[u]) > limit;
      const bool jump_v = std::abs(up[u] + down[u] - 2.0f * w[u]) > limit;
      const bool edge = jump_u | jump_v;
      depth_row[u] = edge ? 0.0f : depth_row[u];
    }
  }
}

}  // namespace hq::sim
