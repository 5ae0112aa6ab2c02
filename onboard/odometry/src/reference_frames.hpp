#pragma once
// Which frame the next ones are aligned against (private to hq_odometry): when a keyframe
// ends (DVO-SLAM's entropy ratio, its age, how much of the image it still explains), whether
// the keyframe chain broke against the direct alignment to the previous frame, and which pixels
// a frame about to become the reference saw move on their own.

#include "hq/odometry/dense_odometry.hpp"

#include "alignment.hpp"
#include "frame.hpp"
#include "reference_points.hpp"
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

namespace hq::odometry::detail {

/// Differential entropy of a Gaussian with this information, up to a constant; 0 when it is
/// not positive definite.
double entropy_of(const Matrix6d& information);

/// Frame to keyframe: when the keyframe is replaced.
class KeyframeSelection {
 public:
  KeyframeSelection(const OdometryConfig& config, int finest_pixels)
      : config_(config), finest_pixels_(finest_pixels) {}

  /// Whether a frame aligned with information H on `valid` finest-level points becomes the
  /// next reference: frame to frame always; frame to keyframe when the keyframe has aged, its
  /// alignments' entropy has fallen by keyframe_entropy_ratio from the first one's
  /// (DVO-SLAM), or the alignment used less of the image than keyframe_min_valid_ratio (a
  /// keyframe with little in view, as the floor right after take-off, or one the motion has
  /// mostly left).
  [[nodiscard]] bool reference_ends_with(const Matrix6d& H, int valid) const;

  /// Counts an accepted alignment against the keyframe (the first one's entropy is the ratio's
  /// denominator).
  void count_alignment(const Matrix6d& H);

  /// A new reference.
  void restart();

 private:
  const OdometryConfig& config_;
  int finest_pixels_;
  int age_ = 0;
  double first_entropy_ = 0.0;
};

/// The keyframe check's verdict: T_prev_cur through the keyframe chain (T_ref_prev, then a)
/// against the direct alignment to the previous frame. True when the keyframe alignment is not
/// usable or they disagree by more than keyframe_check_max_translation_m or _rotation_deg.
bool keyframe_chain_broke(const OdometryConfig& config, int finest_pixels, const Alignment& a,
                          const Alignment& to_previous, const Eigen::Isometry3d& T_ref_prev);

/// The pixels of a frame about to become the reference that its own alignment saw move, per
/// level (1 = moving), for ReferencePreparer::prepare to leave out.
class MovingPixels {
 public:
  MovingPixels(const OdometryConfig& config, const LevelCameras& cameras);

  /// Marks the pixels of `current` that the final alignment a against `reference` saw move on
  /// their own: where a reference point lands with a photometric residual beyond
  /// moving_residual_sigmas of the robust scale, or with a depth that disagrees
  /// (occlusion_depth_ratio), and their four neighbours; coarser levels by the 2x2 maximum.
  /// When current becomes the reference, a person already seen walking is left out of it, so
  /// that the next frames are not aligned to them. Nothing is marked when more than
  /// max_moving_ratio of the points would be: then the alignment itself, not the scene, is in
  /// doubt.
  ///
  /// Then every pixel of `current` with depth is taken back into the reference frame
  /// `reference_frame` by the same motion (dense_moving_marks): it is marked where the
  /// reference saw farther than its point by more than occlusion_depth_ratio (it was not
  /// there), or, where their depths agree, where the reference's pixel was seen moving
  /// (`seen`: the keyframe's SeenMovingPoints marks, nullptr: none). The points of the reference
  /// only mark where they land; a person walking onto low-contrast floor holds pixels that no
  /// reference point lands on, which then pulled the first frame aligned to the new reference.
  void mark(Aligner& aligner, const ReferenceSet& reference, const FrameSlot& reference_frame,
            const FrameSlot& current, const Alignment& a, const cv::Mat* seen);

  /// The marks, or nullptr when there are none to leave out.
  [[nodiscard]] const PerLevel<cv::Mat>* known() const { return known_ ? &marks_ : nullptr; }
  void forget() { known_ = false; }

 private:
  int mark_finest(const ReferenceLevel& ref, const Aligner& aligner, const Alignment& a, int& used);
  int mark_dense(const FrameSlot& reference_frame, const FrameSlot& current, const Alignment& a,
                 const cv::Mat* seen, int& used);
  void spread_to_coarser_levels();

  const OdometryConfig& config_;
  const LevelCameras& cameras_;
  PerLevel<cv::Mat> marks_;
  bool known_ = false;
};

/// Frame to keyframe: the keyframe's points that an alignment against it saw move stay out of
/// every later alignment against that keyframe. A person in the keyframe walks on while frames
/// are aligned to it; the frames in which they have moved little, or back to where the
/// keyframe saw them, find their pixels again and are pulled along by them (people.yaml's
/// circle: docs/odometry.md). A point is seen moving where the estimated motion puts it on a
/// photometric residual beyond moving_residual_sigmas of the robust scale or on a surface
/// farther than its own depth by more than occlusion_depth_ratio (the surface it was on has
/// gone; a nearer one only hides it); its pixel and their four neighbours are left out, on
/// every level (a coarse pixel where any of its four finer ones is). Nothing is left out when
/// more than max_moving_ratio of the points would be: then the alignment is in doubt.
class SeenMovingPoints {
 public:
  SeenMovingPoints(const OdometryConfig& config, const LevelCameras& cameras);

  /// After an accepted alignment a of current against the keyframe `reference`: leaves out of
  /// `reference` the points seen moving (their masks zeroed). Returns how many finest-level
  /// points were newly left out.
  int leave_out(Aligner& aligner, ReferenceSet& reference, const FrameSlot& current,
                const Alignment& a);

  /// A new keyframe: nothing is left out of it yet.
  void restart();

 private:
  int mark_finest(const ReferenceLevel& ref, const FrameSlot& current, const Aligner& aligner,
                  const Alignment& a, int& used);
  static void zero_marked(const cv::Mat& marks, ReferenceLevel& level);

 public:
  /// The finest level's marks (keyframe pixels, 1 = seen moving).
  [[nodiscard]] const cv::Mat& finest_marks() const { return at_level(marks_, cameras_.finest()); }

 private:
  const OdometryConfig& config_;
  const LevelCameras& cameras_;
  PerLevel<cv::Mat> marks_;  // keyframe pixels left out (1), per level
};

}  // namespace hq::odometry::detail
