// hq-bench-obstacles: ObstacleField::compute per frame at 320x240 and 640x480 on synthetic depth
// (a camera 1 m above a floor, tilted 30 deg down, turning in front of a wall and a box, with
// structured-light-like noise and holes), median and p90 over every frame, wall and thread CPU
// time. Depth is made once before timing, so only compute() is measured. Not run by ctest.
//   hq-bench-obstacles [--frames 600]
#include "hq/base/program.hpp"
#include "hq/obstacles/obstacle_field.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fmt/format.h>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

/// Depth (z in C) of the nearest of: the floor z = 0, a wall x = 3 m and the box
/// [1.2, 1.8] x [-0.3, 0.3] x [0, 1] (N: x forward, y left, z up), seen from p_N_C with R_N_C.
float depth_at(const Eigen::Vector3d& ray_C, const Eigen::Matrix3d& R_N_C,
               const Eigen::Vector3d& p_N_C) {
  const Eigen::Vector3d d = R_N_C * ray_C;  // z of ray_C is 1: t along it is the depth
  double t_best = 1e9;
  if (d.z() < -1e-9) t_best = std::min(t_best, -p_N_C.z() / d.z());
  if (d.x() > 1e-9) t_best = std::min(t_best, (3.0 - p_N_C.x()) / d.x());
  const Eigen::Vector3d lo(1.2, -0.3, 0.0);
  const Eigen::Vector3d hi(1.8, 0.3, 1.0);
  double t_near = -1e9;
  double t_far = 1e9;
  for (int k = 0; k < 3; ++k) {
    const double inv = 1.0 / d[k];
    double t0 = (lo[k] - p_N_C[k]) * inv;
    double t1 = (hi[k] - p_N_C[k]) * inv;
    if (t0 > t1) std::swap(t0, t1);
    t_near = std::max(t_near, t0);
    t_far = std::min(t_far, t1);
  }
  if (t_near <= t_far && t_near > 0.0) t_best = std::min(t_best, t_near);
  return t_best < 1e8 ? static_cast<float>(t_best) : 0.0f;
}

std::vector<cv::Mat> make_frames(const hq::geometry::PinholeCamera& camera, int count) {
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  // Optical axes in N for a level camera looking along +x: x right = -y, y down = -z.
  Eigen::Matrix3d R_N_look;
  R_N_look << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  std::vector<cv::Mat> frames;
  for (int i = 0; i < count; ++i) {
    const double yaw = 0.6 * std::sin(0.05 * i);
    const Eigen::Matrix3d R_N_C =
        Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
        Eigen::AngleAxisd(0.52, Eigen::Vector3d::UnitY()).toRotationMatrix() * R_N_look;
    const Eigen::Vector3d p_N_C(0.2 * std::cos(0.03 * i), 0.0, 1.0);
    cv::Mat depth(camera.height, camera.width, CV_32F);
    for (int v = 0; v < camera.height; ++v) {
      for (int u = 0; u < camera.width; ++u) {
        float z = depth_at(camera.ray(u, v), R_N_C, p_N_C);
        z += 1.425e-3f * z * z * noise(rng);
        if (z < 0.5f || z > 6.0f || unit(rng) < 0.02f) z = 0.0f;
        depth.at<float>(v, u) = z;
      }
    }
    frames.push_back(depth);
  }
  return frames;
}

void run(int width, int height, int frame_count) {
  hq::geometry::PinholeCamera camera;
  camera.width = width;
  camera.height = height;
  camera.fx = camera.fy = 0.5 * width / std::tan(0.5 * 58.0 * M_PI / 180.0);
  camera.cx = 0.5 * (width - 1);
  camera.cy = 0.5 * (height - 1);
  Eigen::Matrix3d R_B_C;  // forward-looking, 30 deg down (B: FRD)
  R_B_C << 0, 0, 1, 1, 0, 0, 0, 1, 0;
  R_B_C = Eigen::AngleAxisd(-0.52, Eigen::Vector3d::UnitY()).toRotationMatrix() * R_B_C;
  hq::obstacles::ObstacleField field(hq::obstacles::ObstacleConfig{}, camera, R_B_C,
                                     Eigen::Vector3d(0.12, 0.0, 0.05));
  const std::vector<cv::Mat> frames = make_frames(camera, 60);
  std::vector<double> wall_ms, cpu_ms;
  double checksum = 0.0;
  for (int i = 0; i < frame_count; ++i) {
    const cv::Mat& depth = frames[static_cast<std::size_t>(i) % frames.size()];
    const Clock::time_point start = Clock::now();
    const double cpu_start = thread_cpu_ms();
    const hq::obstacles::ObstacleResult result = field.compute(depth, Eigen::Matrix3d::Identity());
    cpu_ms.push_back(thread_cpu_ms() - cpu_start);
    wall_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - start).count());
    checksum += result.v_obs_H_mps.norm() + result.count;
  }
  std::sort(wall_ms.begin(), wall_ms.end());
  std::sort(cpu_ms.begin(), cpu_ms.end());
  fmt::print(
      "{}x{} ObstacleField::compute: median {:.3f} ms, p90 {:.3f} ms (wall); median {:.3f}, p90 "
      "{:.3f} ms (thread CPU); {} frames; checksum {:.6f}\n",
      width, height, wall_ms[wall_ms.size() / 2], wall_ms[wall_ms.size() * 9 / 10],
      cpu_ms[cpu_ms.size() / 2], cpu_ms[cpu_ms.size() * 9 / 10], frame_count, checksum);
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 600;
  CLI::App app{"hq-bench-obstacles: the obstacle field's time per frame at two resolutions"};
  app.add_option("--frames", frames, "frames per resolution")->check(CLI::Range(1, 1'000'000));
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  run(320, 240, frames);
  run(640, 480, frames);
  return 0;
}
