#include "hq/sim/simulator.hpp"

#include "hq/base/error.hpp"
#include "hq/sim/scripted_flight.hpp"
#include "hq/sim/tum_writer.hpp"
#include "hq/testing/allocation_counter.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <string>
#include <vector>

namespace hq::sim {
namespace {

using ::testing::HasSubstr;

constexpr std::int64_t kMs = 1'000'000;

/// Altitude hold on truth plus a fixed attitude: enough to fly scripted tests.
AttitudeCommand hold_altitude(const Simulator& sim, double z_ref_m, double roll, double pitch) {
  const TruthState& t = sim.truth();
  const double m = sim.config().vehicle.mass_kg;
  const double a_z = 3.0 * (z_ref_m - t.T_N_B.translation().z()) - 2.5 * t.v_N_mps.z();
  return {m * (9.81 + a_z) / (std::cos(roll) * std::cos(pitch)), roll, pitch, 0.0};
}

TEST(SimulatorTest, TakesOffAndHoversOnAltitudeHold) {
  const World world = load_world("onboard/sim/worlds/arena.yaml");
  Simulator sim(default_sim_config(32, 24), world);
  EXPECT_TRUE(sim.truth().on_ground);
  for (std::int64_t t = 0; t < 6000 * kMs; t += 10 * kMs) {
    sim.set_command(hold_altitude(sim, 1.0, 0.0, 0.0));
    sim.step_to(t + 10 * kMs);
  }
  EXPECT_FALSE(sim.truth().on_ground);
  EXPECT_NEAR(sim.truth().T_N_B.translation().z(), 1.0, 0.05);
  EXPECT_FALSE(sim.collided());
  EXPECT_GT(sim.truth().clearance_m, 0.0);
}

TEST(SimulatorTest, CollisionFlagWhenFlownIntoAWall) {
  const World world = load_world("onboard/sim/worlds/arena.yaml");
  SimConfig config = default_sim_config(32, 24);
  config.vehicle.gust_sigma_mps = 0.0;
  Simulator sim(config, world);
  for (std::int64_t t = 0; t < 3000 * kMs; t += 10 * kMs) {
    sim.set_command(hold_altitude(sim, 1.0, 0.0, 0.0));
    sim.step_to(t + 10 * kMs);
  }
  ASSERT_FALSE(sim.collided());
  // Nose down (NED pitch < 0): accelerate north into the wall at x = 3 m.
  double x_at_collision = 0.0;
  double previous_clearance = sim.truth().clearance_m;
  for (std::int64_t t = 3000 * kMs; t < 12000 * kMs && !sim.truth().collision; t += kMs) {
    sim.set_command(hold_altitude(sim, 1.0, 0.0, -0.15));
    sim.step_to(t + kMs);
    x_at_collision = sim.truth().T_N_B.translation().x();
    if (!sim.truth().collision) previous_clearance = sim.truth().clearance_m;
  }
  EXPECT_TRUE(sim.truth().collision);
  EXPECT_TRUE(sim.collided());
  EXPECT_LT(sim.truth().clearance_m, 0.0);
  EXPECT_GE(previous_clearance, 0.0);
  EXPECT_NEAR(x_at_collision, 3.0 - config.vehicle_radius_m, 0.02);
  // Truth in H: flying north with yaw 0 is +x in H (NED).
  EXPECT_GT(sim.truth().v_H_mps.x(), 0.5);
}

// Issue 39: a vehicle that idled its motors in the air hit the floor at 11-13 m/s, and the flight
// summary read "collision ticks 0". Every time the floor stops the vehicle is counted with its
// speed; a gentle touchdown is not a collision, a fall is.
TEST(SimulatorTest, FloorImpactsAreCountedWithTheirSpeedAndAFallIsACollision) {
  const World world = load_world("onboard/sim/worlds/arena.yaml");
  SimConfig config = default_sim_config(32, 24);
  config.vehicle.gust_sigma_mps = 0.0;
  Simulator sim(config, world);
  std::int64_t t = 0;
  for (; t < 4000 * kMs; t += 10 * kMs) {
    sim.set_command(hold_altitude(sim, 1.0, 0.0, 0.0));
    sim.step_to(t + 10 * kMs);
  }
  ASSERT_FALSE(sim.truth().on_ground);
  // A slow descent to the floor (0.3 m/s): one touchdown, no collision.
  const double m = config.vehicle.mass_kg;
  for (; t < 12000 * kMs && !sim.truth().on_ground; t += 10 * kMs) {
    const TruthState& s = sim.truth();
    sim.set_command({m * (9.81 + 2.5 * (-0.3 - s.v_N_mps.z())), 0.0, 0.0, 0.0});
    sim.step_to(t + 10 * kMs);
  }
  ASSERT_TRUE(sim.truth().on_ground);
  EXPECT_EQ(sim.floor_impacts(), 1);
  EXPECT_NEAR(sim.max_floor_impact_speed_mps(), 0.3, 0.1);
  EXPECT_FALSE(sim.collided());
  // Up to 3 m, then the motors off: a fall at about sqrt(2 g 3) = 7.7 m/s is a collision.
  for (const std::int64_t end = t + 8000 * kMs; t < end; t += 10 * kMs) {
    sim.set_command(hold_altitude(sim, 3.0, 0.0, 0.0));
    sim.step_to(t + 10 * kMs);
  }
  ASSERT_NEAR(sim.truth().T_N_B.translation().z(), 3.0, 0.1);
  bool hit = false;
  for (const std::int64_t end = t + 2000 * kMs; t < end; t += kMs) {
    sim.set_command({0.0, 0.0, 0.0, 0.0});
    sim.step_to(t + kMs);
    hit = hit || sim.truth().collision;
  }
  EXPECT_TRUE(sim.truth().on_ground);
  EXPECT_EQ(sim.floor_impacts(), 2);
  EXPECT_GT(sim.max_floor_impact_speed_mps(), 7.0);
  EXPECT_TRUE(hit);
  EXPECT_TRUE(sim.collided());
}

// GIVEN a vehicle resting at the origin and a person walking at 1 m/s from 3 m ahead through it,
// THEN the clearance follows the person, and the run records a collision once they overlap
// (person radius + vehicle radius = 0.6 m, so from t = 2.4 s).
TEST(SimulatorTest, PersonWalkingIntoAVehicleStandingStillIsACollision) {
  World world;
  world.floor.half_u_m = world.floor.half_v_m = 10.0;
  Walker walker;
  walker.from_m = Eigen::Vector2d(3.0, 0.0);
  walker.to_m = Eigen::Vector2d(-3.0, 0.0);
  walker.speed_mps = 1.0;
  world.people.push_back(walker);
  SimConfig config = default_sim_config(32, 24);
  config.vehicle.gust_sigma_mps = 0.0;
  Simulator sim(config, world);
  const double reach_m = walker.radius_m + config.vehicle_radius_m;
  EXPECT_NEAR(sim.truth().clearance_m, 3.0 - reach_m, 1e-9);
  sim.step_to(2000 * kMs);
  EXPECT_TRUE(sim.truth().on_ground);
  EXPECT_NEAR(sim.truth().T_N_B.translation().head<2>().norm(), 0.0, 1e-9);  // still
  EXPECT_NEAR(sim.truth().clearance_m, 1.0 - reach_m, 1e-9);
  sim.step_to(2390 * kMs);
  EXPECT_FALSE(sim.collided());
  EXPECT_NEAR(sim.truth().clearance_m, 0.01, 1e-9);
  sim.step_to(2410 * kMs);
  EXPECT_TRUE(sim.truth().collision);
  EXPECT_TRUE(sim.collided());
  EXPECT_NEAR(sim.truth().clearance_m, -0.01, 1e-9);
  sim.step_to(6000 * kMs);  // walked through and back out: the collision stays on record
  EXPECT_FALSE(sim.truth().collision);
  EXPECT_TRUE(sim.collided());
}

// The simulator renders each frame with the people where they are at the frame's stamp: its
// image is a lone renderer's at camera_t_ns(), and differs from one with the people at t = 0.
TEST(SimulatorTest, FramesShowThePeopleWhereTheyAreAtTheFramesTime) {
  const World world = load_world("onboard/sim/worlds/people.yaml");
  SimConfig config = default_sim_config(80, 60);
  Simulator sim(config, world);
  for (std::int64_t t = 0; t < 3000 * kMs; t += 10 * kMs) {
    sim.set_command(hold_altitude(sim, 1.0, 0.0, 0.0));
    sim.step_to(t + 10 * kMs);
  }
  ASSERT_TRUE(sim.camera_due());
  const double t_frame_s = static_cast<double>(sim.camera_t_ns()) * 1e-9;
  ASSERT_GT(t_frame_s, 2.9);
  const Eigen::Isometry3d T = sim.camera_T_N_C();
  const std::uint64_t frame_index = sim.camera_frame_index();
  cv::Mat image, depth;
  sim.render_camera(image, depth);

  RgbdRenderer renderer(config.camera, world, config.seed * 3u + 3u);  // the simulator's seed
  cv::Mat image_then, depth_then, image_at_start, depth_at_start;
  renderer.render(T, t_frame_s, frame_index, image_then, depth_then);
  renderer.render(T, 0.0, frame_index, image_at_start, depth_at_start);
  EXPECT_EQ(cv::norm(image, image_then, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(depth, depth_then, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(depth, depth_at_start, cv::NORM_INF), 0.5);  // a person moved in the view
}

// The people of worlds/people.yaml keep clear of the vehicle on hq-sim's hover and circle (the
// world file says >= 0.6 m; these bounds leave 0.05 m for the flight's own wobble).
TEST(SimulatorTest, PeopleWorldsWalksKeepClearOfTheScriptedFlights) {
  const World world = load_world("onboard/sim/worlds/people.yaml");
  World people_only;
  people_only.people = world.people;
  for (const FlightScript::Kind kind : {FlightScript::Kind::kHover, FlightScript::Kind::kCircle}) {
    Simulator sim(default_sim_config(32, 24), world);
    const FlightScript script = script_for_world(world, kind);
    double min_clearance_m = 1e9;
    for (std::int64_t t = 0; t <= 16000 * kMs; t += kScriptControlPeriodNs) {
      sim.set_command(scripted_command(sim, script, static_cast<double>(t) * 1e-9));
      sim.step_to(t);
      min_clearance_m = std::min(min_clearance_m,
                                 distance_to_obstacles(people_only, sim.truth().T_N_B.translation(),
                                                       static_cast<double>(sim.t_ns()) * 1e-9) -
                                     sim.config().vehicle_radius_m);
    }
    fmt::print("people.yaml, {}: min clearance to the people {:.3f} m\n",
               kind == FlightScript::Kind::kHover ? "hover" : "circle", min_clearance_m);
    EXPECT_FALSE(sim.collided());
    EXPECT_GT(min_clearance_m, kind == FlightScript::Kind::kHover ? 1.9 : 0.55);
  }
}

TEST(SimulatorTest, ProducesImuAtItsRateAndFramesAtThirtyHertz) {
  const World world = load_world("onboard/sim/worlds/arena.yaml");
  Simulator sim(default_sim_config(32, 24), world);
  std::vector<ImuSample> imu(1000);
  cv::Mat image, depth;
  int frames = 0;
  std::int64_t last_frame_ns = -1;
  std::size_t imu_total = 0;
  std::int64_t last_imu_ns = 0;
  for (std::int64_t t = 0; t <= 1000 * kMs; t += 5 * kMs) {
    sim.step_to(t);
    const std::size_t n = sim.take_imu(imu.data(), imu.size());
    for (std::size_t i = 0; i < n; ++i) {
      EXPECT_EQ(imu[i].t_ns - last_imu_ns, 2 * kMs);
      last_imu_ns = imu[i].t_ns;
    }
    imu_total += n;
    if (sim.camera_due()) {
      EXPECT_GT(sim.camera_t_ns(), last_frame_ns);
      last_frame_ns = sim.camera_t_ns();
      sim.render_camera(image, depth);
      ++frames;
      EXPECT_FALSE(sim.camera_due());
    }
  }
  EXPECT_EQ(imu_total, 500u);
  EXPECT_EQ(frames, 31);  // t = 0 and 30 more within 1 s
  EXPECT_EQ(sim.dropped_frames(), 0);
  EXPECT_EQ(last_frame_ns, 1000 * kMs);
}

TEST(SimulatorTest, SameSeedSameRunIdenticalImagesAndTruth) {
  const World world = load_world("onboard/sim/worlds/room.yaml");
  const auto run = [&](std::uint64_t seed, cv::Mat& image, cv::Mat& depth) {
    SimConfig config = default_sim_config(80, 60);
    config.seed = seed;
    config.vehicle.gust_sigma_mps = 0.3;  // the seed then changes the flight, too
    Simulator sim(config, world);
    for (std::int64_t t = 0; t < 2000 * kMs; t += 10 * kMs) {
      sim.set_command(hold_altitude(sim, 1.0, 0.05, -0.05));
      sim.step_to(t + 10 * kMs);
    }
    sim.render_camera(image, depth);
    return sim.truth().T_N_B.translation().eval();
  };
  cv::Mat image_a, depth_a, image_b, depth_b, image_c, depth_c;
  const Eigen::Vector3d p_a = run(4, image_a, depth_a);
  const Eigen::Vector3d p_b = run(4, image_b, depth_b);
  const Eigen::Vector3d p_c = run(5, image_c, depth_c);
  EXPECT_EQ(p_a, p_b);
  EXPECT_EQ(cv::norm(image_a, image_b, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(depth_a, depth_b, cv::NORM_INF), 0.0);
  EXPECT_NE(p_a, p_c);
}

TEST(SimulatorTest, StepAndRenderAllocateNothingAfterTheFirstFrame) {
  const World world = load_world("onboard/sim/worlds/room.yaml");
  Simulator sim(default_sim_config(80, 60), world);
  std::vector<ImuSample> imu(1000);
  cv::Mat image, depth;
  sim.render_camera(image, depth);
  const long before = hq::testing::allocation_count();
  for (std::int64_t t = 0; t < 1000 * kMs; t += 5 * kMs) {
    sim.set_command(hold_altitude(sim, 1.0, 0.0, 0.0));
    sim.step_to(t + 5 * kMs);
    sim.take_imu(imu.data(), imu.size());
    if (sim.camera_due()) sim.render_camera(image, depth);
  }
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
}

TEST(SimulatorTest, RecordsATumSequenceThatReadsBack) {
  const std::string dir =
      (std::filesystem::temp_directory_path() / "hq_sim_tum_writer_test").string();
  std::filesystem::remove_all(dir);
  const World world = load_world("onboard/sim/worlds/arena.yaml");
  Simulator sim(default_sim_config(64, 48), world);
  TumWriter writer(dir, sim.config().camera.pinhole, sim.config().camera.T_B_C);
  std::vector<ImuSample> imu(1000);
  cv::Mat image, depth;
  Eigen::Isometry3d T_first = Eigen::Isometry3d::Identity();
  int frames = 0;
  // Take off first: resting on the floor, the camera sees nothing beyond its 0.5 m min range.
  for (std::int64_t t = 0; t <= 2100 * kMs; t += kMs) {
    sim.set_command(hold_altitude(sim, 1.0, 0.0, 0.0));
    sim.step_to(t);
    const bool recording = t >= 2000 * kMs;
    const std::size_t n = sim.take_imu(imu.data(), imu.size());
    for (std::size_t i = 0; i < n && recording; ++i) writer.write_imu(imu[i]);
    if (sim.camera_due()) {
      const std::int64_t t_frame = sim.camera_t_ns();
      const Eigen::Isometry3d T = sim.camera_T_N_C();
      sim.render_camera(image, depth);
      if (recording) {
        writer.write_frame(t_frame, image, depth, T);
        ++frames;
        if (frames == 1) T_first = T;
      }
    }
  }
  writer.close();
  EXPECT_EQ(frames, 4);  // 2.000, 2.034, 2.067, 2.100 s: each the first 1 ms step at k / 30 s

  std::ifstream rgb(dir + "/rgb.txt");
  std::string line;
  std::getline(rgb, line);
  EXPECT_EQ(line, "# color images");
  std::getline(rgb, line);
  std::getline(rgb, line);
  EXPECT_EQ(line, "# timestamp filename");
  std::getline(rgb, line);
  EXPECT_EQ(line, "2.000000 rgb/2.000000.png");
  std::getline(rgb, line);
  EXPECT_EQ(line, "2.034000 rgb/2.034000.png");

  const cv::Mat depth_png = cv::imread(dir + "/depth/2.100000.png", cv::IMREAD_UNCHANGED);
  ASSERT_EQ(depth_png.type(), CV_16UC1);
  int checked = 0;
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const float z = depth.at<float>(v, u);
      EXPECT_NEAR(depth_png.at<std::uint16_t>(v, u), z * 5000.0f, 0.51f);
      checked += z > 0.0f;
    }
  }
  EXPECT_GT(checked, depth.total() / 2);
  const cv::Mat rgb_png = cv::imread(dir + "/rgb/2.100000.png", cv::IMREAD_UNCHANGED);
  EXPECT_EQ(cv::norm(rgb_png, image, cv::NORM_INF), 0.0);

  std::ifstream gt(dir + "/groundtruth.txt");
  for (int i = 0; i < 3; ++i) std::getline(gt, line);
  EXPECT_EQ(line, "# timestamp tx ty tz qx qy qz qw");
  double t, tx, ty, tz, qx, qy, qz, qw;
  gt >> t >> tx >> ty >> tz >> qx >> qy >> qz >> qw;
  const Eigen::Isometry3d& T0 = T_first;
  EXPECT_DOUBLE_EQ(t, 2.0);
  EXPECT_NEAR(tx, T0.translation().x(), 1e-6 + 1e-9);
  EXPECT_NEAR(tz, T0.translation().z(), 1e-6);
  EXPECT_NEAR(std::abs(Eigen::Quaterniond(qw, qx, qy, qz).dot(Eigen::Quaterniond(T0.linear()))),
              1.0, 1e-6);

  std::ifstream acc(dir + "/accelerometer.txt");
  int lines = 0;
  while (std::getline(acc, line)) lines += line.empty() || line[0] == '#' ? 0 : 1;
  EXPECT_EQ(lines, 51);  // 2.000 .. 2.100 s inclusive at 500 Hz
  EXPECT_TRUE(std::filesystem::exists(dir + "/gyro.txt"));
  EXPECT_EQ(TumWriter::stamp(1'305'031'102'175'304'000), "1305031102.175304");
}

TEST(SimulatorTest, UnwritableRecordingDirectoryIsAnInputError) {
  try {
    TumWriter writer("/proc/hq_sim_cannot_write_here", default_sim_config().camera.pinhole,
                     Eigen::Isometry3d::Identity());
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("/proc/hq_sim_cannot_write_here"));
  }
}

}  // namespace
}  // namespace hq::sim
