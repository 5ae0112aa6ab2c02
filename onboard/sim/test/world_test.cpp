#include "hq/sim/world.hpp"

#include "hq/base/error.hpp"
#include "hq/sim/simulator.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace hq::sim {
namespace {

using ::testing::HasSubstr;

// Named after the test too: ctest runs this binary's tests in parallel processes, and two of
// them writing one file read each other's halves.
std::string write_temp(const std::string& name, const std::string& text) {
  const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
  const std::string path = (std::filesystem::temp_directory_path() / (test + "." + name)).string();
  std::ofstream(path) << text;
  return path;
}

std::string error_of(const std::string& yaml) {
  const std::string path = write_temp("hq_sim_world_test.yaml", yaml);
  try {
    load_world(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(WorldTest, ShippedWorldsLoadWithTheirContent) {
  const World arena = load_world("onboard/sim/worlds/arena.yaml");
  EXPECT_EQ(arena.name, "arena");
  EXPECT_EQ(arena.walls.size(), 4u);
  ASSERT_EQ(arena.boxes.size(), 1u);
  EXPECT_NEAR(arena.boxes[0].size_m.x(), 0.5, 0.1);
  EXPECT_EQ(arena.markers.size(), 4u);
  // 6 m x 4 m: the north wall is 4 m long, the east wall 6 m.
  EXPECT_NEAR(arena.walls[0].half_u_m, 2.0, 1e-9);
  EXPECT_NEAR(arena.walls[1].half_u_m, 3.0, 1e-9);

  const World room = load_world("onboard/sim/worlds/room.yaml");
  EXPECT_GE(room.boxes.size(), 3u);
  EXPECT_GE(room.cylinders.size(), 2u);

  const World grid = load_world("onboard/sim/worlds/marker_grid.yaml");
  ASSERT_EQ(grid.markers.size(), 25u);
  EXPECT_EQ(grid.markers.front().id, 0);
  EXPECT_EQ(grid.markers.back().id, 24);
  EXPECT_NEAR((grid.markers[0].center_N_m - grid.markers[1].center_N_m).norm(), 0.6, 1e-9);
  // Every shipped world's markers lie on a surface (the renderer checks).
  for (const World* w : {&arena, &room, &grid}) {
    EXPECT_NO_THROW(Simulator(default_sim_config(32, 24), *w));
  }
}

TEST(WorldTest, ErrorsNameTheFileAndKey) {
  EXPECT_THAT(error_of("boxes:\n  - {center_m: [0, 0, 1], size_m: [1, -2, 1]}\n"),
              HasSubstr("hq_sim_world_test.yaml: boxes[0].size_m[1] = -2"));
  EXPECT_THAT(error_of("boxs: []\n"), HasSubstr("boxs is not a known key"));
  EXPECT_THAT(error_of("walls:\n  - {from_m: [0, 0], to_m: [1, 0], colour: red}\n"),
              HasSubstr("walls[0].colour is not a known key"));
  EXPECT_THAT(error_of("walls:\n  - {from_m: [0, 0]}\n"), HasSubstr("walls[0].to_m is missing"));
  EXPECT_THAT(error_of("cylinders:\n  - {center_m: [0, 0], radius_m: 0}\n"),
              HasSubstr("cylinders[0].radius_m = 0, expected > 0"));
  EXPECT_THAT(error_of("floor: {texture: {type: marble}}\n"),
              HasSubstr("floor.texture.type = marble, expected one of checker | noise | stripes"));
  EXPECT_THAT(error_of("markers:\n  - {id: 900, center_m: [0, 0, 0]}\n"),
              HasSubstr("markers[0].id = 900"));
  EXPECT_THAT(error_of("marker_grid: {rows: 5, cols: 5, spacing_m: 0.2, size_m: 0.2}\n"),
              HasSubstr("marker_grid.spacing_m"));
  EXPECT_THAT(error_of("walls: {from_m: [0, 0]}\n"), HasSubstr("walls is not a list"));
  try {
    load_world("onboard/sim/worlds/no_such_world.yaml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("no_such_world.yaml: file not found"));
  }
}

TEST(WorldTest, DistanceToObstaclesIsExactForEachPrimitive) {
  World world;
  Box box;
  box.center_m = Eigen::Vector3d(0.0, 0.0, 0.5);
  box.size_m = Eigen::Vector3d(1.0, 1.0, 1.0);
  world.boxes.push_back(box);
  EXPECT_NEAR(distance_to_obstacles(world, {2.0, 0.0, 0.5}), 1.5, 1e-12);
  EXPECT_NEAR(distance_to_obstacles(world, {0.0, 0.0, 0.5}), -0.5, 1e-12);  // inside
  world.boxes[0].yaw_rad = 0.7853981633974483;
  EXPECT_NEAR(distance_to_obstacles(world, {2.0, 0.0, 0.5}), 2.0 - std::sqrt(0.5), 1e-9);

  World pillars;
  Cylinder c;
  c.center_m = Eigen::Vector2d(1.0, 1.0);
  c.radius_m = 0.3;
  c.height_m = 2.0;
  pillars.cylinders.push_back(c);
  EXPECT_NEAR(distance_to_obstacles(pillars, {1.0, 2.0, 1.0}), 0.7, 1e-12);
  EXPECT_NEAR(distance_to_obstacles(pillars, {1.0, 1.0, 3.0}), 1.0, 1e-12);  // above the top

  const World arena = load_world("onboard/sim/worlds/arena.yaml");
  EXPECT_NEAR(distance_to_obstacles(arena, {2.5, 1.0, 1.0}), 0.5, 1e-9);  // north wall x = 3
}

TEST(WorldTest, PeopleWorldIsTheRoomWithTwoPeople) {
  const World room = load_world("onboard/sim/worlds/room.yaml");
  const World people = load_world("onboard/sim/worlds/people.yaml");
  EXPECT_EQ(people.name, "people");
  EXPECT_TRUE(room.people.empty());
  EXPECT_EQ(people.walls.size(), room.walls.size());
  EXPECT_EQ(people.boxes.size(), room.boxes.size());
  EXPECT_EQ(people.cylinders.size(), room.cylinders.size());
  EXPECT_EQ(people.markers.size(), room.markers.size());
  EXPECT_EQ(people.start_N_m, room.start_N_m);
  ASSERT_EQ(people.people.size(), 2u);
  const Walker& near = people.people[0];
  EXPECT_EQ(near.from_m, Eigen::Vector2d(-1.0, 0.3));
  EXPECT_EQ(near.to_m, Eigen::Vector2d(-2.1, -0.6));
  EXPECT_DOUBLE_EQ(near.speed_mps, 1.0);
  EXPECT_DOUBLE_EQ(near.phase_s, 0.0);
  const Walker& far = people.people[1];
  EXPECT_DOUBLE_EQ(far.speed_mps, 1.4);
  EXPECT_DOUBLE_EQ(far.phase_s, 1.3);
  // Person-sized by default, standing on the floor.
  EXPECT_DOUBLE_EQ(far.radius_m, 0.25);
  EXPECT_DOUBLE_EQ(far.height_m, 1.75);
  EXPECT_DOUBLE_EQ(body_at(far, 2.0).base_z_m, 0.0);
  // Each texture its own salt, after the room's: the room's textures are unchanged.
  EXPECT_EQ(people.cylinders.back().texture.salt, room.cylinders.back().texture.salt);
  EXPECT_EQ(far.texture.salt, near.texture.salt + 1u);
  EXPECT_GT(near.texture.salt, room.cylinders.back().texture.salt);
  EXPECT_EQ(far.texture.kind, Texture::Kind::kChecker);
  EXPECT_NO_THROW(Simulator(default_sim_config(32, 24), people));
}

// Nobody walks through the furniture or the walls: over two minutes of walking, each person's
// axis keeps its radius plus 0.18 m (measured: 0.20) from every static obstacle, ankle to head.
TEST(WorldTest, PeopleWalkClearOfTheFurniture) {
  World furniture = load_world("onboard/sim/worlds/people.yaml");
  const std::vector<Walker> people = furniture.people;
  furniture.people.clear();
  for (const Walker& walker : people) {
    double min_gap_m = 1e9;
    for (int i = 0; i <= 12000; ++i) {
      const Cylinder body = body_at(walker, 0.01 * i);
      for (const double z_m : {0.1, 0.5, 0.9, 1.7}) {
        const Eigen::Vector3d axis_m(body.center_m.x(), body.center_m.y(), z_m);
        min_gap_m = std::min(min_gap_m, distance_to_obstacles(furniture, axis_m) - body.radius_m);
      }
    }
    EXPECT_GT(min_gap_m, 0.18) << "person walking from " << walker.from_m.transpose();
  }
}

TEST(WorldTest, PeopleErrorsNameTheFileAndKey) {
  const std::string good = "people:\n  - {from_m: [0, 0], to_m: [2, 0]}\n";
  EXPECT_EQ(error_of(good), "no error");
  EXPECT_THAT(error_of(good + "  - {from_m: [0, 1], to_m: [2, 1], speed_mps: 0}\n"),
              HasSubstr("hq_sim_world_test.yaml: people[1].speed_mps = 0, expected > 0"));
  EXPECT_THAT(error_of("people:\n  - {from_m: [0, 0], to_m: [2, 0], speed_mps: 3.5}\n"),
              HasSubstr("people[0].speed_mps = 3.5, expected in [0, 3]"));
  EXPECT_THAT(error_of("people:\n  - {from_m: [0, 0], to_m: [2, 0], phase_s: -4000}\n"),
              HasSubstr("people[0].phase_s = -4000, expected in [-3600, 3600]"));
  EXPECT_THAT(error_of("people:\n  - {from_m: [0, 0], to_m: [2, 0], radius_m: -0.1}\n"),
              HasSubstr("people[0].radius_m = -0.1, expected > 0"));
  EXPECT_THAT(error_of("people:\n  - {from_m: [0, 0], to_m: [2, 0], height_m: 4}\n"),
              HasSubstr("people[0].height_m = 4, expected in [0, 3]"));
  EXPECT_THAT(error_of("people:\n  - {from_m: [1, 1], to_m: [1, 1]}\n"),
              HasSubstr("people[0].to_m equals from_m, expected a walk of length > 0"));
  EXPECT_THAT(error_of("people:\n  - {from_m: [0, 0]}\n"), HasSubstr("people[0].to_m is missing"));
  EXPECT_THAT(error_of("people:\n  - {from_m: [0, 2000], to_m: [2, 0]}\n"),
              HasSubstr("people[0].from_m[1] = 2000, expected within +-1000 m"));
  EXPECT_THAT(error_of("people:\n  - {from_m: [0, 0], to_m: [2, 0], speed: 1}\n"),
              HasSubstr("people[0].speed is not a known key"));
  EXPECT_THAT(error_of("people:\n  - {from_m: [0, 0], to_m: [2, 0], texture: {type: fur}}\n"),
              HasSubstr("people[0].texture.type = fur, expected one of"));
  EXPECT_THAT(error_of("people: {from_m: [0, 0]}\n"), HasSubstr("people is not a list"));
}

// A walk of 2 m along +y from (1, 1) at 1 m/s, out at t = 0, back from t = 2 s: a lap is 4 s.
TEST(WorldTest, BodyAtWalksBackAndForthAlongItsSegment) {
  Walker walker;
  walker.from_m = Eigen::Vector2d(1.0, 1.0);
  walker.to_m = Eigen::Vector2d(1.0, 3.0);
  walker.speed_mps = 1.0;
  walker.radius_m = 0.3;
  walker.height_m = 1.6;
  const auto y_at = [&](double t_s) { return body_at(walker, t_s).center_m.y(); };
  EXPECT_EQ(body_at(walker, 0.0).center_m, Eigen::Vector2d(1.0, 1.0));
  EXPECT_DOUBLE_EQ(y_at(0.5), 1.5);
  EXPECT_DOUBLE_EQ(y_at(2.0), 3.0);    // turns at to_m
  EXPECT_DOUBLE_EQ(y_at(2.5), 2.5);    // on the way back
  EXPECT_DOUBLE_EQ(y_at(4.0), 1.0);    // one lap
  EXPECT_DOUBLE_EQ(y_at(9.25), 2.25);  // two laps and 1.25 s
  EXPECT_DOUBLE_EQ(y_at(-0.5), 1.5);   // before the start, the walk continues backwards
  EXPECT_DOUBLE_EQ(body_at(walker, 0.5).center_m.x(), 1.0);
  // The phase shifts the walk in time; the speed scales it.
  walker.phase_s = 1.0;
  EXPECT_DOUBLE_EQ(y_at(0.5), 2.5);
  EXPECT_DOUBLE_EQ(y_at(1.5), 2.5);
  walker.phase_s = 0.0;
  walker.speed_mps = 0.5;
  EXPECT_DOUBLE_EQ(y_at(1.0), 1.5);
  EXPECT_DOUBLE_EQ(y_at(5.0), 2.5);
  // A diagonal walk: (0, 0) -> (3, 4) is 5 m; at 1 m/s, 2.5 s is half way and 7.5 s too.
  walker.from_m = Eigen::Vector2d(0.0, 0.0);
  walker.to_m = Eigen::Vector2d(3.0, 4.0);
  walker.speed_mps = 1.0;
  EXPECT_NEAR((body_at(walker, 2.5).center_m - Eigen::Vector2d(1.5, 2.0)).norm(), 0.0, 1e-12);
  EXPECT_NEAR((body_at(walker, 7.5).center_m - Eigen::Vector2d(1.5, 2.0)).norm(), 0.0, 1e-12);
  const Cylinder body = body_at(walker, 1.0);
  EXPECT_DOUBLE_EQ(body.radius_m, 0.3);
  EXPECT_DOUBLE_EQ(body.height_m, 1.6);
  EXPECT_DOUBLE_EQ(body.base_z_m, 0.0);
}

TEST(WorldTest, DistanceToObstaclesCountsPeopleWhereTheyAreAtThatTime) {
  World world;
  Walker walker;  // (0, 0) -> (4, 0) at 2 m/s: at (2, 0) at t = 1 s, back at (0, 0) at t = 4 s
  walker.from_m = Eigen::Vector2d(0.0, 0.0);
  walker.to_m = Eigen::Vector2d(4.0, 0.0);
  walker.speed_mps = 2.0;
  walker.radius_m = 0.25;
  walker.height_m = 1.75;
  world.people.push_back(walker);
  const Eigen::Vector3d p(2.0, 1.0, 1.0);
  EXPECT_NEAR(distance_to_obstacles(world, p, 1.0), 0.75, 1e-12);
  EXPECT_NEAR(distance_to_obstacles(world, p, 0.0), std::sqrt(5.0) - 0.25, 1e-12);
  EXPECT_NEAR(distance_to_obstacles(world, p, 4.0), std::sqrt(5.0) - 0.25, 1e-12);
  EXPECT_EQ(distance_to_obstacles(world, p), distance_to_obstacles(world, p, 0.0));
  EXPECT_NEAR(distance_to_obstacles(world, {2.0, 0.1, 1.0}, 1.0), -0.15, 1e-12);  // inside
  EXPECT_NEAR(distance_to_obstacles(world, {2.0, 0.0, 2.75}, 1.0), 1.0, 1e-12);   // above
  // The nearest of people and static obstacles.
  Cylinder pillar;
  pillar.center_m = Eigen::Vector2d(2.0, 1.5);
  pillar.radius_m = 0.2;
  pillar.height_m = 3.0;
  world.cylinders.push_back(pillar);
  EXPECT_NEAR(distance_to_obstacles(world, p, 1.0), 0.3, 1e-12);
  EXPECT_NEAR(distance_to_obstacles(world, p, 0.0), 0.3, 1e-12);
}

TEST(WorldTest, TexturesAreDeterministicAndTextured) {
  Texture t;
  t.kind = Texture::Kind::kNoise;
  t.salt = 9;
  EXPECT_EQ(t.albedo(0.37f, 1.2f), t.albedo(0.37f, 1.2f));
  float min_v = 1.0f;
  float max_v = 0.0f;
  for (int i = 0; i < 200; ++i) {
    const float v = t.albedo(0.013f * static_cast<float>(i), 0.007f * static_cast<float>(i)).x();
    min_v = std::min(min_v, v);
    max_v = std::max(max_v, v);
  }
  EXPECT_GT(max_v - min_v, 0.1f);  // enough texture for photometric odometry
  t.kind = Texture::Kind::kChecker;
  EXPECT_GT(std::abs(t.albedo(0.1f, 0.1f).x() - t.albedo(0.3f, 0.1f).x()), 0.1f);
}

// albedo_span() is the renderer's vectorised albedo(): the same bits for every kind, on both
// sides of zero (floor without libm), at lattice and checker boundaries, at -0 and far out.
TEST(WorldTest, AlbedoSpanEqualsAlbedoBitForBit) {
  std::vector<float> s, t;
  for (float x : {0.0f, -0.0f, 0.2f, -0.2f, 0.6f, -0.6f, 1e-7f, -1e-7f, 37.5f, -123.4f}) {
    s.push_back(x);
    t.push_back(-x);
  }
  std::uint32_t state = 12345u;
  for (int i = 0; i < 997; ++i) {  // odd count: the vector loops' remainders run too
    state = state * 1664525u + 1013904223u;
    s.push_back(static_cast<float>(state >> 8) * (1.0f / 16777216.0f) * 40.0f - 20.0f);
    state = state * 1664525u + 1013904223u;
    t.push_back(static_cast<float>(state >> 8) * (1.0f / 16777216.0f) * 40.0f - 20.0f);
  }
  const int n = static_cast<int>(s.size());
  for (Texture::Kind kind :
       {Texture::Kind::kChecker, Texture::Kind::kNoise, Texture::Kind::kStripes}) {
    Texture texture;
    texture.kind = kind;
    texture.salt = 7u;
    texture.scale_m = 0.2f;
    std::vector<float> b(s.size()), g(s.size()), r(s.size());
    texture.albedo_span(s.data(), t.data(), n, b.data(), g.data(), r.data());
    for (std::size_t i = 0; i < s.size(); ++i) {
      const Eigen::Vector3f expected = texture.albedo(s[i], t[i]);
      ASSERT_EQ(b[i], expected[0]) << "kind " << static_cast<int>(kind) << " at " << s[i];
      ASSERT_EQ(g[i], expected[1]);
      ASSERT_EQ(r[i], expected[2]);
    }
  }
}

TEST(WorldTest, SimConfigLoadsAndNamesBadKeys) {
  const SimConfig config = load_sim_config("onboard/sim/config/sim.yaml");
  EXPECT_EQ(config.camera.pinhole.width, 320);
  EXPECT_DOUBLE_EQ(config.imu.rate_hz, 500.0);
  // The camera looks 45 deg right and 30 deg down: its optical axis in body NED.
  const Eigen::Vector3d z_B = config.camera.T_B_C.linear().col(2);
  EXPECT_NEAR(z_B.x(), std::cos(0.5236) * std::cos(0.7854), 1e-3);
  EXPECT_NEAR(z_B.y(), std::cos(0.5236) * std::sin(0.7854), 1e-3);
  EXPECT_NEAR(z_B.z(), std::sin(0.5236), 1e-3);
  // Mass and extrinsics come from the vehicle file hq::control reads (core paper's ^Q p_C).
  EXPECT_EQ(config.vehicle_file, "calib/vehicle_core_paper.yaml");
  EXPECT_DOUBLE_EQ(config.vehicle.mass_kg, 1.0);
  EXPECT_TRUE(config.camera.T_B_C.translation().isApprox(Eigen::Vector3d(0.10, 0.05, 0.03)));

  const auto error_of_config = [](const std::string& yaml) -> std::string {
    try {
      load_sim_config(write_temp("hq_sim_config_test.yaml", yaml));
    } catch (const InputError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_THAT(error_of_config("imu: {rate_hz: 300}\n"),
              HasSubstr("imu.rate_hz = 300.000000, expected a divisor of dynamics_rate_hz"));
  EXPECT_THAT(error_of_config("camera: {depth: {min_range_m: 3, max_range_m: 2}}\n"),
              HasSubstr("camera.depth.max_range_m"));
  EXPECT_THAT(error_of_config("vehicle: {mass_kg: 5}\n"),
              HasSubstr("vehicle.max_rotor_speed_radps"));
  EXPECT_THAT(
      error_of_config("vehicle_file: calib/vehicle_core_paper.yaml\n"
                      "vehicle: {mass_kg: 2}\n"),
      HasSubstr("vehicle.mass_kg is set, but vehicle_file = calib/vehicle_core_paper.yaml"));
  EXPECT_THAT(error_of_config("vehicle_file: calib/no_such_vehicle.yaml\n"),
              HasSubstr("calib/no_such_vehicle.yaml"));
  EXPECT_THAT(error_of_config("camera: {T_B_C: {yaw_deg: 4}}\n"),
              HasSubstr("camera.T_B_C.yaw_deg is not a known key"));
}

// Values without physical sense are refused with the file, key and value named: a start of
// 1e300 m gave a flight summary of NaN, 100k boxes never rendered a frame.
TEST(WorldTest, PositionsAndPrimitiveCountHavePhysicalBounds) {
  EXPECT_THAT(
      error_of("start: {xy_m: [1e300, 0]}\n"),
      HasSubstr("hq_sim_world_test.yaml: start.xy_m[0] = 1e+300, expected within +-1000 m"));
  EXPECT_THAT(error_of("floor: {half_size_m: [6, 6]}\nstart: {xy_m: [7, 0]}\n"),
              HasSubstr("hq_sim_world_test.yaml: start.xy_m = [7, 0], expected on the floor "
                        "(|x| <= 6, |y| <= 6 m, floor.half_size_m)"));
  EXPECT_THAT(error_of("boxes:\n  - {center_m: [0, 5000, 1], size_m: [1, 1, 1]}\n"),
              HasSubstr("boxes[0].center_m[1] = 5000, expected within +-1000 m"));
  std::string many = "boxes:\n";
  for (int i = 0; i < 10001; ++i) many += "  - {center_m: [0, 0, 1], size_m: [1, 1, 1]}\n";
  EXPECT_THAT(error_of(many),
              HasSubstr("hq_sim_world_test.yaml: 10001 primitives (0 walls, 10001 boxes, 0 "
                        "cylinders, 0 markers, 0 people), expected at most 10000"));
}

// A normal of length 2 or 0.5 was normalised without a word: a typo in a direction is refused.
TEST(WorldTest, MarkerNormalOfNonUnitLengthIsRefusedNamingIdAndFile) {
  EXPECT_THAT(error_of("markers:\n  - {id: 7, center_m: [0, 0, 0], normal: [0, 0, 2]}\n"),
              HasSubstr("hq_sim_world_test.yaml: markers[0].normal (id 7) = [0, 0, 2] has length "
                        "2, expected a unit vector (|length - 1| <= 0.001)"));
  EXPECT_THAT(error_of("markers:\n  - {id: 8, center_m: [0, 0, 0], normal: [0, 0, 0.99]}\n"),
              HasSubstr("markers[0].normal (id 8) = [0, 0, 0.99] has length 0.99"));
  EXPECT_NO_THROW(load_world(
      write_temp("hq_sim_world_unit_normal_test.yaml",
                 "markers:\n  - {id: 9, center_m: [0, 0, 0], normal: [0, 0, 0.9999]}\n")));
}

// A flipped normal faces into the floor or a box: the tag is printed on the side no camera can
// see, and the marker modes wait for a marker that never appears.
TEST(WorldTest, MarkerNormalFacingIntoTheFloorOrABoxIsRefused) {
  EXPECT_THAT(error_of("markers:\n  - {id: 3, center_m: [1, 0, 0], normal: [0, 0, -1]}\n"),
              HasSubstr("hq_sim_world_test.yaml: markers[0].normal (id 3) = [0, 0, -1] faces "
                        "into the floor, expected it to face free space"));
  EXPECT_THAT(error_of("boxes:\n  - {center_m: [0, 0, 0.5], size_m: [1, 1, 1]}\n"
                       "markers:\n  - {id: 4, center_m: [0.5, 0, 0.5], normal: [-1, 0, 0]}\n"),
              HasSubstr("markers[0].normal (id 4) = [-1, 0, 0] faces into boxes[0], expected it "
                        "to face free space"));
  EXPECT_NO_THROW(load_world(
      write_temp("hq_sim_world_box_marker_test.yaml",
                 "boxes:\n  - {center_m: [0, 0, 0.5], size_m: [1, 1, 1]}\n"
                 "markers:\n  - {id: 4, center_m: [0.5, 0, 0.5], normal: [1, 0, 0]}\n")));
}

TEST(WorldTest, SimCameraFocalLengthHasPhysicalBounds) {
  const std::string path =
      write_temp("hq_sim_config_fov_test.yaml", "camera: {width: 16, height: 16, hfov_deg: 170}\n");
  try {
    load_sim_config(path);
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("camera.hfov_deg = 170 with width 16 gives fx = 0.69"));
    EXPECT_THAT(e.what(), HasSubstr("px, expected in [10, 10000] px"));
  }
}

}  // namespace
}  // namespace hq::sim
