#pragma once
/// Simulated worlds: textured planes, boxes and vertical cylinders with AprilTag 36h11 markers,
/// and people walking among them, read strictly from YAML. World frame W is NWU (z up), as in
/// the core paper §3; the floor is the plane z = 0. Time t_s is seconds since the run started
/// (the Simulator's time).

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace hq::sim {

/// Procedural albedo pattern evaluated at surface coordinates (s, t) in metres.
struct Texture {
  enum class Kind { kChecker, kNoise, kStripes };
  Kind kind = Kind::kNoise;
  Eigen::Vector3f color_bgr = Eigen::Vector3f(0.7f, 0.7f, 0.7f);  ///< albedo in [0, 1].
  float scale_m = 0.2f;    ///< checker square / noise cell / stripe period.
  float contrast = 0.5f;   ///< 0: flat colour, 1: pattern spans black to the colour.
  std::uint32_t salt = 0;  ///< decorrelates the noise of different surfaces (set at load).
  /// Albedo (BGR, [0, 1]) at surface coordinates; deterministic in (s, t).
  [[nodiscard]] Eigen::Vector3f albedo(float s_m, float t_m) const;
  /// albedo() at n points at once, bit for bit, in a loop the compiler vectorises: channels
  /// into b[i], g[i], r[i].
  void albedo_span(const float* s_m, const float* t_m, int n, float* b, float* g, float* r) const;
};

/// An AprilTag 36h11 marker lying on a surface. size_m is the side of its black border square
/// (the size cv::aruco reports); a two-cell white margin is drawn around it.
struct Marker {
  int id = 0;
  Eigen::Vector3d center_N_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal_N = Eigen::Vector3d::UnitZ();  ///< out of the surface.
  double size_m = 0.2;
  double rotation_rad = 0.0;  ///< about the normal, from the default "up" direction.
};

/// Finite rectangle: centre, unit normal, in-plane axes u, v with half extents.
struct Rectangle {
  Eigen::Vector3d center_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d axis_u = Eigen::Vector3d::UnitX();
  Eigen::Vector3d axis_v = Eigen::Vector3d::UnitY();
  double half_u_m = 1.0;
  double half_v_m = 1.0;
  Texture texture;
};

/// Box yawed about the world z axis.
struct Box {
  Eigen::Vector3d center_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d size_m = Eigen::Vector3d::Ones();
  double yaw_rad = 0.0;
  Texture texture;
};

/// Vertical cylinder standing on z = base_z_m.
struct Cylinder {
  Eigen::Vector2d center_m = Eigen::Vector2d::Zero();
  double radius_m = 0.2;
  double base_z_m = 0.0;
  double height_m = 1.0;
  Texture texture;
};

/// A person: a textured vertical cylinder standing on the floor that walks back and forth
/// along the segment from_m -> to_m at a constant speed, turning round at each end at once.
struct Walker {
  Eigen::Vector2d from_m = Eigen::Vector2d::Zero();  ///< where it is at t_s + phase_s = 0.
  Eigen::Vector2d to_m = Eigen::Vector2d::UnitX();   ///< the other end; != from_m.
  double speed_mps = 1.0;                            ///< in (0, 3]: walking pace.
  double phase_s = 0.0;    ///< at t_s it stands where a phase of 0 puts it at t_s + phase_s.
  double radius_m = 0.25;  ///< of the body's cylinder (shoulder half-width).
  double height_m = 1.75;
  Texture texture;  ///< clothes: fixed to the body, so they move with it.
};

struct World {
  std::string name;
  std::uint64_t seed = 1;  ///< default seed of runs in this world.
  Rectangle floor;         ///< z = 0, normal +z.
  std::vector<Rectangle> walls;
  std::vector<Box> boxes;
  std::vector<Cylinder> cylinders;
  std::vector<Marker> markers;
  std::vector<Walker> people;
  Eigen::Vector3d start_N_m = Eigen::Vector3d::Zero();  ///< vehicle position on the floor.
  double start_yaw_rad = 0.0;  ///< yaw of the vehicle (NED heading from world x) at start.
};

/// Loads a world file (strict: unknown keys rejected, ranges checked). Throws hq::InputError
/// naming the file and the key, e.g. `arena.yaml: boxes[0].size_m[2] = -1, expected > 0`.
World load_world(const std::string& path);

/// The cylinder `walker` occupies at t_s (ping-pong along its segment; any t_s, also < 0).
Cylinder body_at(const Walker& walker, double t_s);

/// Signed distance (m) from a point to the nearest obstacle surface at t_s (walls, boxes,
/// cylinders, and the people where they are then; the floor is excluded: ground contact
/// handles it). Negative inside a box, cylinder or person.
double distance_to_obstacles(const World& world, const Eigen::Vector3d& p_N_m, double t_s);
/// distance_to_obstacles() at t_s = 0: the people stand where the run starts them.
double distance_to_obstacles(const World& world, const Eigen::Vector3d& p_N_m);

}  // namespace hq::sim
