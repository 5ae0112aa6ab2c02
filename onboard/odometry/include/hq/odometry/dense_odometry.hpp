#pragma once
/// Dense photometric RGB-D odometry (DVO: Kerl, Sturm, Cremers, ICRA 2013).
///
/// Coarse-to-fine iteratively re-weighted Gauss-Newton on se(3) with Student-t weights. The
/// Jacobians are taken on the reference frame (inverse compositional form), so each reference
/// is prepared once and every iteration only warps, samples and accumulates the 6x6 normal
/// equations in one pass. All buffers are sized at construction: after the first frame,
/// track() allocates nothing.

#include "hq/geometry/pinhole_camera.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <string>

namespace hq::config {
class StrictMap;
}

namespace hq::odometry {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

enum class TrackingStatus {
  kFirstFrame,  ///< No reference yet: this frame became the reference, pose is identity.
  kOk,
  kLost,  ///< Too few usable pixels or no convergence; T_ref_cur is identity.
};

/// Which frame the current one is aligned against.
enum class ReferenceMode {
  kFrameToFrame,     ///< The previous frame, as the core paper uses DVO.
  kFrameToKeyframe,  ///< A keyframe, replaced when the entropy ratio falls (Kerl IROS 2013).
};

struct OdometryConfig {
  int pyramid_levels = 4;  ///< Levels built: 0 = input resolution.
  int finest_level = 1;    ///< Finest level optimised (1 = half resolution, as DVO).
  int max_iterations_per_level = 20;
  double step_tolerance = 2e-4;  ///< Stop the finest level when |delta xi| (m, rad) falls
                                 ///< below this; level l stops at 2^(l - finest) times it.
  double min_depth_m = 0.3;
  double max_depth_m = 6.0;
  double min_gradient = 4.0;            ///< Reference pixels with smaller |grad I| (0..255 units)
                                        ///< carry no photometric information and are skipped.
  double student_t_dof = 5.0;           ///< nu of the Student-t weights (Kerl 2013).
  double min_valid_ratio = 0.02;        ///< Fraction of finest-level pixels that must be usable.
  bool use_motion_prior = false;        ///< Constant-velocity prior term (Kerl 2013, eq. 16).
  double motion_prior_precision = 1.0;  ///< Prior information = this x last frame's information.
  bool initialize_with_previous_motion = true;  ///< Start from the last frame's motion
                                                ///< (frame-to-frame only; also gates the prior).
  bool estimate_brightness_offset = true;       ///< Also estimate a global intensity offset.
  ReferenceMode reference_mode = ReferenceMode::kFrameToFrame;
  double keyframe_entropy_ratio = 0.9;  ///< New keyframe when H(kf,t)/H(kf,kf+1) drops below.
  int max_keyframe_age = 30;            ///< Frames; bounds drift-free reuse of one keyframe.
  /// Keyframe check: each frame is also aligned to its predecessor; when T_prev_cur through
  /// the keyframe disagrees with it by more than these, the frame re-anchors on its predecessor
  /// and becomes the keyframe.
  bool keyframe_check = false;
  double keyframe_check_max_translation_m = 0.01;
  double keyframe_check_max_rotation_deg = 0.5;
  /// Adds DVO-SLAM's depth residual (Kerl, Sturm, Cremers IROS 2013, eq. 11-13) to the same
  /// Gauss-Newton, with the bivariate Student-t weights of the pair (intensity, depth).
  bool use_depth_term = false;
  double depth_noise_per_m = 0.0015;     ///< sigma_z = this x z^2 (m), the Kinect noise model.
  int depth_point_stride = 2;            ///< Pixels without photometric gradient still add a depth
                                         ///< residual on this grid (1 = every pixel).
  double depth_max_spread_ratio = 0.05;  ///< Depth residual skipped where the four sampled
                                         ///< depths, or the reference pixel's four neighbours,
                                         ///< spread by more than this fraction (an edge).
  /// The depth term acts on this many pyramid levels from finest_level up (0 = every level);
  /// coarser levels align intensity only. Measured (README): on real Kinect depth (fr1_360) one
  /// level loses less rotation, but the coarse levels' depth is what carries textureless scenes
  /// and fast yaw without the gyro in simulation, so every level is the default.
  int depth_levels = 0;
  /// Uses a RotationPrior given to track() as initial guess and prior (else it is ignored).
  bool use_rotation_prior = true;
  double rotation_prior_information_scale = 1.0;  ///< Prior information = this x the given one.
  /// The data term's Gauss-Newton information (Student-t weighted, pixels assumed independent)
  /// times this is its honest information: what the gyro prior is weighed against and what
  /// OdometryResult::information reports. Neighbouring pixels' errors are correlated
  /// (interpolation, blur, the pyramid, model error), so the independent-pixel Hessian is
  /// overconfident: on the six simulated flights (exact truth, no gyro) the mean rotation NEES
  /// e^T Sigma_rr^-1 e / 3 of each frame's T_ref_cur was 7-220, geometric mean 25 over 18
  /// runs (`hq-bench-odometry --nees`, README "Honest information"), i.e. 0.04. The default
  /// stays 1: with 0.04 the gyro rows gain on fr1_360 but lose rotation in simulation, where
  /// the synthetic gyro's constant residual bias, not white per step, is what the stronger
  /// prior lets through.
  double vision_information_scale = 1.0;
};

/// Rotation of the current camera in the previous frame's camera, integrated from the gyro
/// by the caller (bias removed), with its information: a prior on the twist's rotation part.
struct RotationPrior {
  Eigen::Matrix3d R_prev_cur = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d information = Eigen::Matrix3d::Identity();  ///< rad^-2, symmetric PSD.
};

/// Checks every field's range and their relations; throws hq::InputError naming where.key, the
/// value and the expectation ("onboard.yaml: odometry.finest_level = 5, expected <
/// pyramid_levels (4)"). read_config and the DenseOdometry constructor both run it, so no value
/// is clamped silently.
void validate(const OdometryConfig& config, const std::string& where = "OdometryConfig");

/// Reads the `odometry:` section of a YAML config strictly (unknown keys rejected), then
/// validate()s it.
void read_config(config::StrictMap& section, OdometryConfig& out);

/// One frame's outcome. Never contains NaN: on failure the pose is identity and status kLost.
struct OdometryResult {
  TrackingStatus status = TrackingStatus::kLost;
  const char* reason = "";  ///< Static text saying why, when status != kOk.
  std::int64_t t_ns = 0;
  Eigen::Isometry3d T_ref_cur = Eigen::Isometry3d::Identity();  ///< current camera in reference.
  /// The camera pose in the odometry origin O (= C0, hq/geometry/frames.hpp), accumulated.
  Eigen::Isometry3d T_O_C = Eigen::Isometry3d::Identity();
  Matrix6d information = Matrix6d::Zero();  ///< (v, omega) order, of T_ref_cur's twist.
  double valid_ratio = 0.0;                 ///< usable finest-level pixels / finest-level pixels.
  double mean_weighted_error = 0.0;         ///< final mean of w * r^2 (intensity units^2).
  int iterations = 0;                       ///< Gauss-Newton iterations over all levels.
  bool new_keyframe = false;                ///< This frame became the reference for the next ones.

  [[nodiscard]] bool ok() const { return status == TrackingStatus::kOk; }
};

class DenseOdometry {
 public:
  /// @param camera  intrinsics of the (undistorted) input images; sizes every buffer.
  /// @throws hq::InputError if validate(config) does.
  DenseOdometry(const OdometryConfig& config, const geometry::PinholeCamera& camera);
  ~DenseOdometry();
  DenseOdometry(const DenseOdometry&) = delete;
  DenseOdometry& operator=(const DenseOdometry&) = delete;

  /// Aligns a frame to the reference and makes it the next reference as configured.
  /// @param gray   CV_8UC1, camera.width x camera.height.
  /// @param depth_m CV_32FC1 metres, same size; 0, NaN or out of range means no depth.
  OdometryResult track(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m);
  /// As above, with the gyro's rotation since the previous frame (nullptr: none). A prior
  /// that is not finite is ignored.
  OdometryResult track(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m,
                       const RotationPrior* prior);

  /// Forgets the reference and the motion history (next frame is a first frame).
  void reset();

  [[nodiscard]] const OdometryConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

const char* to_string(TrackingStatus status);

}  // namespace hq::odometry
