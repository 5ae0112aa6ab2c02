#pragma once
/// Ray-cast RGB-D camera for the simulated worlds: per-pixel rays precomputed once in the
/// camera frame C (optical: z forward, x right, y down), analytic intersections tested only on
/// the pixels a primitive's projection covers (z-buffered; people are cylinders moved each frame
/// to where they are at its time), one shading pass per pixel with procedural textures and
/// AprilTag 36h11 bitmaps, and a structured-light depth model (Khoshelham and Oude Elberink
/// 2012: disparity noise and quantisation, sigma_z growing with z^2, no depth at
/// discontinuities, on dark or grazing surfaces). One thread; render() allocates nothing.

#include "hq/geometry/pinhole_camera.hpp"
#include "hq/sim/world.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <vector>

namespace hq::sim {

/// Structured-light depth sensor (Kinect / Xtion class).
struct DepthSensorParams {
  double min_range_m = 0.5;              ///< closer returns read 0 (invalid).
  double max_range_m = 6.0;              ///< farther returns read 0.
  double noise_sigma_per_m2 = 1.425e-3;  ///< sigma_z = k z^2 (Khoshelham 2012); 0: noise-free.
  double baseline_m = 0.075;             ///< projector-camera baseline.
  double disparity_focal_px = 580.0;     ///< focal length of the IR camera measuring disparity.
  int disparity_subpixels = 8;           ///< disparity quantised to 1/n px; 0: not quantised.
  double edge_jump_ratio = 0.04;         ///< |second difference of 1/z| > ratio / z: no depth.
  double dark_albedo = 0.05;             ///< surfaces darker than this return no depth.
  double grazing_max_rad = 1.40;         ///< incidence beyond this (from the normal): no depth.
};

struct CameraParams {
  geometry::PinholeCamera pinhole;  ///< image size and intrinsics.
  Eigen::Isometry3d T_B_C = Eigen::Isometry3d::Identity();
  double rate_hz = 30.0;
  bool gray = false;               ///< CV_8UC1 instead of BGR CV_8UC3.
  double image_noise_sigma = 1.0;  ///< 8-bit intensity units.
  double ambient = 0.45;           ///< light: ambient + diffuse * max(0, n . l).
  double diffuse = 0.55;
  Eigen::Vector3d light_dir_N = Eigen::Vector3d(0.3, 0.2, 1.0).normalized();  ///< to light.
  DepthSensorParams depth;
};

/// Pinhole intrinsics of a width x height image with the given horizontal field of view.
geometry::PinholeCamera pinhole_from_fov(int width, int height, double hfov_rad);

class RgbdRenderer {
 public:
  /// Precomputes rays and marker bitmaps; throws hq::InputError if a marker lies on no planar
  /// surface of the world.
  RgbdRenderer(const CameraParams& params, const World& world, std::uint64_t seed);
  ~RgbdRenderer();
  RgbdRenderer(const RgbdRenderer&) = delete;
  RgbdRenderer& operator=(const RgbdRenderer&) = delete;

  /// Renders the view from T_N_C (the camera in the simulator's world N) at time t_s (seconds
  /// since the run started: where the world's people are). frame_index selects the noise
  /// realisation, so the same (seed, frame_index, pose, t_s) gives identical images.
  /// image: CV_8UC3 BGR (CV_8UC1 if gray); depth_m: CV_32F metres, 0 = invalid. Reuses the
  /// buffers if already sized.
  void render(const Eigen::Isometry3d& T_N_C, double t_s, std::uint64_t frame_index, cv::Mat& image,
              cv::Mat& depth_m);
  /// render() at t_s = 0: a world without people looks the same at any time.
  void render(const Eigen::Isometry3d& T_N_C, std::uint64_t frame_index, cv::Mat& image,
              cv::Mat& depth_m) {
    render(T_N_C, 0.0, frame_index, image, depth_m);
  }

  /// The per-pixel ray caster render() replaced (every ray against every primitive, shading
  /// the nearest): same outputs, several times slower. Kept as the reference render() is
  /// tested and benchmarked against; not for simulation.
  void render_reference(const Eigen::Isometry3d& T_N_C, double t_s, std::uint64_t frame_index,
                        cv::Mat& image, cv::Mat& depth_m);
  /// render_reference() at t_s = 0.
  void render_reference(const Eigen::Isometry3d& T_N_C, std::uint64_t frame_index, cv::Mat& image,
                        cv::Mat& depth_m) {
    render_reference(T_N_C, 0.0, frame_index, image, depth_m);
  }

  [[nodiscard]] const CameraParams& params() const { return params_; }

 private:
  struct Scene;
  CameraParams params_;
  std::uint64_t seed_;
  std::vector<float> ray_c_;      ///< per pixel (x/z, y/z, 1/|d|) of the camera ray with z = 1.
  cv::Mat true_depth_m_;          ///< noise-free z per pixel (0 = no hit), for edge detection.
  std::unique_ptr<Scene> scene_;  ///< intersection tables (defined in the .cpp).
  std::vector<float> hit_t_;      ///< per pixel: nearest hit's t (z in C), +inf if none.
  std::vector<std::int32_t> hit_code_;  ///< per pixel: which primitive and face won, -1 none.

  void prepare_frame(const Eigen::Isometry3d& T_N_C, double t_s);
  void drop_depth_at_discontinuities(cv::Mat& depth_m) const;  ///< the reference's
  void drop_depth_at_discontinuities_fast(cv::Mat& depth_m);
};

}  // namespace hq::sim
