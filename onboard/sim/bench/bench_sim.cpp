// hq-bench-sim: render time per frame at 320x240 and 640x480, render() against the reference
// ray caster (render_reference()) on the same poses in the same run, and the real-time factor
// of a full simulation (dynamics 1 kHz + IMU + RGB-D at 30 Hz) on one core. Each figure in wall
// time and in this thread's CPU time: on a shared, loaded machine the wall clock also counts
// the time other processes hold the core. Not run by ctest.
//   hq-bench-sim [world.yaml]   (default onboard/sim/worlds/room.yaml, run from the repo root)
#include "hq/base/log.hpp"
#include "hq/base/program.hpp"
#include "hq/sim/simulator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <exception>
#include <fmt/format.h>
#include <optional>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;
constexpr std::int64_t kMs = 1'000'000;

double ms_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

/// CPU time consumed by the calling thread.
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

/// A scripted hover-and-circle so the camera sweeps the room.
hq::sim::AttitudeCommand script(const hq::sim::Simulator& sim, double t_s) {
  const hq::sim::TruthState& truth = sim.truth();
  const double m = sim.config().vehicle.mass_kg;
  const double a_z = 3.0 * (1.0 - truth.T_N_B.translation().z()) - 2.5 * truth.v_N_mps.z();
  const double roll = t_s > 2.0 ? 0.08 * std::sin(0.8 * t_s) : 0.0;
  const double pitch = t_s > 2.0 ? 0.08 * std::cos(0.8 * t_s) - 0.08 : 0.0;
  return {m * (9.81 + a_z) / (std::cos(roll) * std::cos(pitch)), roll, pitch, 0.3};
}

void run(const hq::sim::World& world, int width, int height) {
  hq::sim::SimConfig config = hq::sim::default_sim_config(width, height);
  // 1. Rendering alone, along a flown trajectory: each pose by render() and by the reference,
  // alternating, so that both see the same machine load.
  {
    hq::sim::Simulator sim(config, world);
    std::vector<Eigen::Isometry3d> poses;
    for (std::int64_t t = 0; t < 10'000 * kMs; t += kMs) {
      sim.set_command(script(sim, static_cast<double>(t) * 1e-9));
      sim.step_to(t + kMs);
      if (sim.camera_due()) {
        poses.push_back(sim.camera_T_N_C());
        cv::Mat unused_image, unused_depth;
        sim.render_camera(unused_image, unused_depth);
      }
    }
    hq::sim::RgbdRenderer renderer(config.camera, world, 1);
    cv::Mat image, depth;
    std::vector<double> new_ms, new_cpu_ms, reference_ms, reference_cpu_ms;
    for (std::size_t i = 0; i < poses.size(); ++i) {
      Clock::time_point start = Clock::now();
      double cpu_start = thread_cpu_ms();
      renderer.render(poses[i], i, image, depth);
      new_ms.push_back(ms_since(start));
      new_cpu_ms.push_back(thread_cpu_ms() - cpu_start);
      start = Clock::now();
      cpu_start = thread_cpu_ms();
      renderer.render_reference(poses[i], i, image, depth);
      reference_ms.push_back(ms_since(start));
      reference_cpu_ms.push_back(thread_cpu_ms() - cpu_start);
    }
    const auto print = [&](const char* name, std::vector<double>& wall, std::vector<double>& cpu) {
      std::sort(wall.begin(), wall.end());
      std::sort(cpu.begin(), cpu.end());
      fmt::print(
          "{}x{} render {:<9}: median {:6.2f} ms/frame, p90 {:6.2f} ms (wall); median {:6.2f}, p90 "
          "{:6.2f} ms (thread CPU); {} frames\n",
          width, height, name, wall[wall.size() / 2], wall[wall.size() * 9 / 10],
          cpu[cpu.size() / 2], cpu[cpu.size() * 9 / 10], wall.size());
    };
    print("new", new_ms, new_cpu_ms);
    print("reference", reference_ms, reference_cpu_ms);
  }
  // 2. Full simulation: physics, IMU draining and every camera frame rendered.
  {
    hq::sim::Simulator sim(config, world);
    cv::Mat image, depth;
    std::vector<hq::sim::ImuSample> imu(1000);
    const double sim_s = 10.0;
    const Clock::time_point start = Clock::now();
    const double cpu_start = thread_cpu_ms();
    for (std::int64_t t = 0; t < static_cast<std::int64_t>(sim_s * 1e3) * kMs; t += kMs) {
      sim.set_command(script(sim, static_cast<double>(t) * 1e-9));
      sim.step_to(t + kMs);
      sim.take_imu(imu.data(), imu.size());
      if (sim.camera_due()) sim.render_camera(image, depth);
    }
    const double wall_s = ms_since(start) * 1e-3;
    const double cpu_s = (thread_cpu_ms() - cpu_start) * 1e-3;
    fmt::print(
        "{}x{} full sim (1 kHz dynamics + {:g} Hz IMU + {:g} Hz RGB-D): {:.2f} s simulated in "
        "{:.2f} s wall, real-time factor {:.1f}x; {:.2f} s thread CPU, {:.1f}x\n",
        width, height, config.imu.rate_hz, config.camera.rate_hz, sim_s, wall_s, sim_s / wall_s,
        cpu_s, sim_s / cpu_s);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"hq-bench-sim: the simulator's render and step time at two resolutions"};
  std::string path = "onboard/sim/worlds/room.yaml";
  app.add_option("world", path, "simulator world");
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  try {
    const hq::sim::World world = hq::sim::load_world(path);
    fmt::print("world {}: {} walls, {} boxes, {} cylinders, {} markers\n", path, world.walls.size(),
               world.boxes.size(), world.cylinders.size(), world.markers.size());
    run(world, 320, 240);
    run(world, 640, 480);
  } catch (const std::exception& e) {
    hq::log::error("hq-bench-sim: {}\n", e.what());
    return 2;
  }
  return 0;
}
