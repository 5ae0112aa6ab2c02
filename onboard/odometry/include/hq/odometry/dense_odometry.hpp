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
  /// Frame to keyframe with the gyro is the default (docs/odometry.md, "Reference mode").
  ReferenceMode reference_mode = ReferenceMode::kFrameToKeyframe;
  double keyframe_entropy_ratio = 0.9;  ///< New keyframe when H(kf,t)/H(kf,kf+1) drops below.
  int max_keyframe_age = 30;            ///< Frames; bounds drift-free reuse of one keyframe.
  /// New keyframe when the alignment used less than this fraction of the finest-level pixels:
  /// a keyframe with little in view (the floor just after take-off) or one the motion has
  /// mostly left (measured: 0.15-0.26 in steady flight in simulation).
  double keyframe_min_valid_ratio = 0.05;
  /// Keyframe check: each frame is also aligned to its predecessor; when T_prev_cur through
  /// the keyframe disagrees with it by more than these, the frame re-anchors on its predecessor
  /// and becomes the keyframe.
  bool keyframe_check = false;
  double keyframe_check_max_translation_m = 0.01;
  double keyframe_check_max_rotation_deg = 0.5;
  /// A reference point whose warped depth disagrees with the current frame's depth at the same
  /// pixel by more than this fraction of it adds no residual in that iteration: something came
  /// between (a person walking into view) or the point itself moved away. The Student-t weights
  /// only down-weight such points; a crowd of them (a person filling a third of the view)
  /// shifts the minimum. 0 = off. Measured on the whole fr1/xyz through the chain: 0.1 left
  /// the velocity on 97.3 % of frames (the Kinect's depth at edges, misregistered to the
  /// colour by a few pixels, disagreed), 0.2 on 98.5 % (none: 99.2 %); people.yaml's circle
  /// 4.9x and 6.4x the RPE without people.
  double occlusion_depth_ratio = 0.2;
  /// A frame about to become the reference leaves out the pixels its own alignment saw move:
  /// where a reference point landed with a photometric residual beyond this many robust
  /// sigmas, or with disagreeing depth (a person walking, seen in one frame, is not aligned to
  /// in the next). 0 = off.
  double moving_residual_sigmas = 4.0;
  /// ... unless more than this share of the points would be left out: then the alignment, not
  /// the scene, is in doubt.
  double max_moving_ratio = 0.5;
  /// Frame to keyframe: a keyframe point that an alignment against the keyframe saw move (by
  /// the two tests above: a residual beyond moving_residual_sigmas, or the current surface
  /// behind it beyond occlusion_depth_ratio) stays out of every later alignment against that
  /// keyframe, with its four neighbours (under the same max_moving_ratio): a person in the
  /// keyframe walks on, and frames aligned to it later would find their pixels again.
  bool drop_moving_keyframe_points = true;
  /// ... where its photometric residual also says its image moved this far along the gradient
  /// (|r| / |grad I|, in pixels of the finest level): at a sharp edge (a marker's, a printed
  /// pattern's) a sub-pixel misalignment leaves a residual of many sigmas, and those points
  /// are the ones that fix the pose; a person walking shifts their image by pixels.
  double moving_min_displacement_px = 1.0;
  /// A keyframe point seen moving leaves the keyframe with the pixels within this city-block
  /// distance (finest level; 1 = its four neighbours): a walking person's low-contrast pixels
  /// between the points seen moving move too, with residuals no test tells from noise. Wider
  /// also takes more around a static scene's falsely seen points: 5 brings people.yaml's circle
  /// with the gyro from 1.8x to 1.3x the RPE without people (five seeds), costs the whole
  /// fr1/xyz 0.0145 -> 0.0166 m/s, and the explore flight loses the marker field's edges
  /// (docs/odometry.md, "People in view"). For flights among people, without markers.
  int moving_mark_radius_px = 1;
  /// When an alignment saw more than this share of its points move (newly left out), the frame
  /// is aligned again without them: they pulled it. 1 = never.
  double moving_realign_ratio = 0.03;
  /// A frame about to become the reference also marks, among its own pixels with depth, those
  /// that disagree with the old reference where the estimated motion takes them (the reference
  /// saw through them by occlusion_depth_ratio, or saw that pixel move:
  /// drop_moving_keyframe_points), not only where the old reference's points land: a person
  /// walking onto low-contrast floor holds pixels no reference point lands on. Off: on
  /// people.yaml's circle it halves the RPE again (with the gyro 0.00354 -> 0.00107 m/s), but
  /// on the whole fr1/xyz it costs the odometry alone 0.0183 -> 0.0210 m/s, 1.07 -> 1.18 deg/s
  /// (docs/odometry.md, "People in view").
  bool dense_moving_marks = false;
  /// Adds DVO-SLAM's depth residual (Kerl, Sturm, Cremers IROS 2013, eq. 11-13) to the same
  /// Gauss-Newton, with the bivariate Student-t weights of the pair (intensity, depth).
  /// Off by default: in the closed-loop campaigns a textureless world still "tracks" on depth
  /// alone and the vehicle flew off at up to 12 m/s, where intensity alone is lost and hovers.
  bool use_depth_term = false;
  double depth_noise_per_m = 0.0015;     ///< sigma_z = this x z^2 (m), the Kinect noise model.
  int depth_point_stride = 2;            ///< Pixels without photometric gradient still add a depth
                                         ///< residual on this grid (1 = every pixel).
  double depth_max_spread_ratio = 0.05;  ///< Depth residual skipped where the four sampled
                                         ///< depths, or the reference pixel's four neighbours,
                                         ///< spread by more than this fraction (an edge).
  /// The depth term acts on this many pyramid levels from finest_level up (0 = every level);
  /// coarser levels align intensity only. Measured (docs/odometry.md, "Depth-term options"): on
  /// real Kinect depth (fr1_360) one level loses less rotation, but the coarse levels' depth is
  /// what carries textureless scenes and fast yaw without the gyro in simulation, so every level is
  /// the default.
  int depth_levels = 0;
  /// The depth residual's Jacobian from the reference surface's normal, d r / d q = -(q_z /
  /// n.q) n^T / sigma_z (point-to-plane along the viewing ray: exact for a locally planar
  /// surface), instead of the current depth's gradient. The gradient of a single depth map of a
  /// plane is mostly noise (its noise against the plane's true gradient is about
  /// f sigma_z / z: 0.15 at 1 m on Kinect v1 at 320x240, 0.8 at 2 m), and a noisy Jacobian
  /// claims information the scene does not hold. The normals come from the depth
  /// depth_normal_smoothing_levels pyramid levels coarser (block means). Measured
  /// (docs/odometry.md, "Depth-term options"): better in simulation (frame to frame most, the
  /// textureless world most of all), worse on the real fr1_360 frames (f2kf I+D+gyro 0.0276 ->
  /// 0.0305 m/s), so off by default.
  bool depth_jacobian_from_normals = false;
  int depth_normal_smoothing_levels = 2;
  /// Surfaces seen more obliquely than this (normal against the viewing ray) add no depth
  /// residual: the ray-to-plane factor 1 / cos grows without bound, and such depth is poor.
  double depth_max_incidence_deg = 75.0;
  /// Turns each frame's depth by the gyro's RotationPrior::R_depth_colour to the colour
  /// image's exposure before anything uses it (a rotation only: the translation in those few
  /// milliseconds is not known to the gyro). Independent of use_rotation_prior.
  bool align_depth_to_colour = true;
  /// Uses a RotationPrior given to track() as initial guess and prior (else it is ignored).
  bool use_rotation_prior = true;
  double rotation_prior_information_scale = 1.0;  ///< Prior information = this x the given one.
  /// The data term's Gauss-Newton information (Student-t weighted, pixels assumed independent)
  /// times this is its honest information: what the gyro prior is weighed against and what
  /// OdometryResult::information reports. Neighbouring pixels' errors are correlated
  /// (interpolation, blur, the pyramid, model error), so the independent-pixel Hessian is
  /// overconfident: on the six simulated flights (exact truth, no gyro) the mean rotation NEES
  /// e^T Sigma_rr^-1 e / 3 of each frame's T_ref_cur was 7-220, geometric mean 25 over 18
  /// runs (`hq-bench-odometry --nees`, docs/odometry.md, "The vision's information"), i.e. 0.04; on
  /// real Kinect frames (fr1_360) 1500-6000. With a gyro it is only the start:
  /// adapt_vision_information.
  double vision_information_scale = 0.04;
  /// The gyro rotations given to track() carry white noise (their information) and a rate
  /// bias left over by the caller's estimate, which is this component's: per axis it is
  /// allowed for as gyro_bias_sigma_radps x the frame interval in every prior, and
  /// (estimate_gyro_bias, frame to keyframe) estimated from the vision's own rotation against
  /// each keyframe by a 3-state Kalman filter (bias as a random walk), removed from each prior,
  /// and then allowed for only as far as the filter is unsure of it. Frame to frame it is not
  /// estimated: the vision's per-step drift is as constant as a bias and indistinguishable. The
  /// caller's bias estimate (the complementary filter's) cannot see yaw, and a bias is an error
  /// correlated over every step that no per-step weighting of the prior averages out.
  bool estimate_gyro_bias = true;
  double gyro_bias_sigma_radps = 0.005;  ///< Per axis, before (or without) the estimate.
  double gyro_bias_random_walk = 2e-4;   ///< rad/s/sqrt(s): how fast the bias may drift.
  /// Observations whose squared Mahalanobis distance exceeds this are not used (3 degrees of
  /// freedom: 16.27 rejects 0.1 % of consistent ones): a frame where vision slipped must not
  /// teach the filter a bias.
  double gyro_bias_gate_chi2 = 16.27;
  /// With a gyro prior, vision_information_scale becomes only where the honest scale starts:
  /// each tracked frame's vision-only rotation against the gyro's gives a moment estimate of
  /// the data term's overconfidence (innovation-based adaptive estimation, Mehra 1972), averaged
  /// in the log domain over the last vision_information_frames frames. Off by default: it
  /// cannot tell which of the two is wrong when they disagree. On real Kinect frames (fr1_360,
  /// gyro synthesised from the ground truth) it trusted the gyro 1000x more than the vision and
  /// the chain's velocity got worse (eq. 1 |v| RMSE 0.101 -> 0.146 m/s, docs/odometry.md, "The
  /// vision's information").
  bool adapt_vision_information = false;
  int vision_information_frames = 30;
  /// Gauss-Newton iterations of the finest level without the prior, from the joint minimum,
  /// that find the vision's own rotation for the two estimates above (frames with a gyro only).
  int vision_only_iterations = 3;
  /// A frame whose translation is this unsure (standard deviation along the least constrained
  /// direction, under vision_information_scale) is lost, not tracked: with the depth term a
  /// textureless wall still "tracks", but says nothing of the motion along it.
  double max_translation_sigma_m = 0.02;
  /// ... or whose translation information (rotation held) along its least constrained
  /// direction is under this share of what the depth rows give their best direction: the
  /// depth Jacobians' own noise adds about that much to every direction (with normals, about
  /// their angular noise squared), so a plain wall's depth "constrains" the motion along it
  /// past any absolute bound. Scale-free, and no bound without the depth term. Measured in the
  /// unseen-space campaign with the depth term and depth_jacobian_from_normals (docs/odometry.md,
  /// "Depth-term options"): at 0.01 no wrong frame was accepted (259 of 5690 before), but it also
  /// loses the textureless world's slow circle, which the depth term tracks, and noise-free
  /// synthetic depth (whose re-estimated scale makes its information 10^4 times the intensity's): 0
  /// (off) by default.
  double min_translation_information_ratio = 0.0;
  /// A Gauss-Newton step leaves the translation alone along directions whose information
  /// (rotation held) on that level and iteration is under this share of the best direction's:
  /// they keep the prediction (Zhang, Kaess and Singh, ICRA 2016, "solution remapping"). A
  /// plain wall and the floor say nothing of the motion along their common line, and without
  /// this the coarsest level's first step, taken before the robust scales are known, moved
  /// the pose 2-4 cm along it per frame of a hover, which the finer levels could not undo
  /// (docs/odometry.md, "Depth-term options"). 0: off.
  double degenerate_step_ratio = 0.0;
};

/// Rotation of the current camera in the previous frame's camera, integrated from the gyro
/// by the caller (its bias estimate removed), with the information of its white noise: a
/// prior on the twist's rotation part. The residual bias is the odometry's to allow for
/// (OdometryConfig::gyro_bias_sigma_radps, estimate_gyro_bias), not part of the information.
///
/// R_depth_colour: the camera at the colour image's exposure in the camera at the depth map's,
/// integrated from the gyro over the time between the two (identity when they are taken
/// together). Cameras without a shared trigger (Kinect v1, whose TUM recordings stamp depth
/// 3.7-7.7 ms before colour) see the depth from where the camera was a moment earlier; with
/// OdometryConfig::align_depth_to_colour the depth is turned to the colour's exposure.
struct RotationPrior {
  Eigen::Matrix3d R_prev_cur = Eigen::Matrix3d::Identity();
  /// rad^-2, symmetric PSD; zero: no rotation since the previous frame is known (a first
  /// frame), only R_depth_colour.
  Eigen::Matrix3d information = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R_depth_colour = Eigen::Matrix3d::Identity();
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
  /// The gyro rate bias removed from the rotation prior (camera axes, rad/s), after this frame.
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  /// The data term's honest scale in use after this frame (see adapt_vision_information).
  double vision_information_scale = 1.0;

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

  /// Forgets the reference, the motion history and the gyro bias estimate (next frame is a
  /// first frame).
  void reset();

  [[nodiscard]] const OdometryConfig& config() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

const char* to_string(TrackingStatus status);

}  // namespace hq::odometry
