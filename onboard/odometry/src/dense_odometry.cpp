// DenseOdometry: each frame is built into pyramids, aligned to the reference (with the gyro's
// rotation as prior), checked for what the scene leaves unmeasured, and perhaps made the next
// reference. The parts live apart: frame.cpp (pyramids, depth turned to the colour's exposure),
// reference_points.cpp (a frame prepared as reference), alignment.cpp (the Gauss-Newton),
// gyro_fusion.cpp (the rotation prior and the gyro bias), degeneracy.cpp, reference_frames.cpp
// (keyframes, moving pixels) and odometry_config.cpp (validation, YAML).

#include "hq/odometry/dense_odometry.hpp"

#include "alignment.hpp"
#include "degeneracy.hpp"
#include "frame.hpp"
#include "gyro_fusion.hpp"
#include "reference_frames.hpp"
#include "reference_points.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>

namespace hq::odometry {

namespace {

using detail::Alignment;
using detail::FrameSlot;
using detail::GyroObservation;
using detail::GyroSteps;
using detail::NormalEquations;
using detail::Prediction;

const OdometryConfig& validated(const OdometryConfig& config) {
  validate(config);
  return config;
}

}  // namespace

struct DenseOdometry::Impl {
  OdometryConfig config;
  geometry::PinholeCamera camera;
  detail::LevelCameras cameras;
  detail::FrameBuilder frames;
  detail::ReferencePreparer preparer;
  detail::Aligner aligner;
  detail::GyroFusion gyro;
  detail::KeyframeSelection keyframes;
  detail::MovingPixels moving;
  detail::SeenMovingPoints seen_moving;

  // Three slots: the reference (keyframe), the previous frame (for the keyframe check) and the
  // current frame; frame to frame the previous frame is the reference.
  std::array<FrameSlot, 3> slots;
  int reference_slot = 0;
  int previous_slot = 0;
  // Prepared points of the reference and, with the keyframe check, of the previous frame.
  detail::ReferenceSet reference;
  detail::ReferenceSet previous;
  bool has_reference = false;
  bool has_previous = false;  // `previous` holds the previous frame

  Eigen::Isometry3d T_O_ref = Eigen::Isometry3d::Identity();
  // Last accepted estimate of the current frame in the reference (constant-velocity guess).
  Eigen::Isometry3d T_ref_last = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d last_motion = Eigen::Isometry3d::Identity();  // T_prev_cur of last frame
  Matrix6d last_information = Matrix6d::Zero();
  bool has_motion = false;
  std::int64_t last_frame_t_ns = -1;  // any frame's, for the gyro step's interval

  Impl(const OdometryConfig& c, const geometry::PinholeCamera& cam)
      : config(validated(c)),
        camera(cam),
        cameras(camera, config.pyramid_levels, config.finest_level),
        frames(config, cameras),
        preparer(config, cameras),
        aligner(config, cameras),
        gyro(config),
        keyframes(config, cameras.finest_pixels()),
        moving(config, cameras),
        seen_moving(config, cameras) {
    for (auto& slot : slots) frames.allocate(slot);
    preparer.reserve(reference);
    if (keyframe_check()) preparer.reserve(previous);
  }

  [[nodiscard]] bool keyframe_check() const {
    return config.reference_mode == ReferenceMode::kFrameToKeyframe && config.keyframe_check;
  }
  // Keyframe points seen moving leave the keyframe (frame to frame, every frame is a new one).
  [[nodiscard]] bool drops_seen_moving() const {
    return config.reference_mode == ReferenceMode::kFrameToKeyframe &&
           config.drop_moving_keyframe_points;
  }

  [[nodiscard]] double finest_ratio(int points) const {
    return static_cast<double>(points) / cameras.finest_pixels();
  }

  FrameSlot& slot(int index) { return slots[static_cast<std::size_t>(index)]; }

  OdometryResult lost(OdometryResult result, const char* reason) {
    result.status = TrackingStatus::kLost;
    result.reason = reason;
    result.T_ref_cur = Eigen::Isometry3d::Identity();
    result.information.setZero();
    has_motion = false;
    return result;
  }

  [[nodiscard]] bool reference_usable() const {
    return detail::at_level(reference, cameras.finest()).count >=
           std::max(6, static_cast<int>(config.min_valid_ratio * cameras.finest_pixels()));
  }

  void make_reference(int slot_index, const Eigen::Isometry3d& T_O_C) {
    reference_slot = slot_index;
    preparer.prepare(slot(slot_index), moving.known(), reference);
    moving.forget();
    previous_slot = slot_index;
    has_previous = false;
    has_reference = reference_usable();
    T_O_ref = T_O_C;
    T_ref_last.setIdentity();
    gyro.restart_chain();
    keyframes.restart();
    seen_moving.restart();
  }

  // The information of the pose twist, times the data term's honest share of the
  // independent-pixel one.
  [[nodiscard]] Matrix6d pose_information(const NormalEquations& normal) const {
    return gyro.vision_scale() *
           detail::independent_pixel_information(normal, config.estimate_brightness_offset);
  }

  // Constant-velocity initial guess (and prior mean) for T_ref_cur, with the gyro's rotation.
  [[nodiscard]] Prediction predict_motion(const GyroSteps* steps) const {
    Prediction p;
    // Frame to frame only: against a keyframe, the part of each step that the optimiser leaves
    // uncorrected is carried into the next prediction, so the predicted velocity random-walks
    // (measured on a simulated circle: RPE 69 m/s with it, 1 mm/s without).
    p.predict = has_motion && config.initialize_with_previous_motion &&
                config.reference_mode == ReferenceMode::kFrameToFrame;
    p.T_ref_predicted = p.predict ? T_ref_last * last_motion : T_ref_last;
    p.last_information = last_information;
    // The gyro's rotation since the reference replaces the predicted one: photometric
    // alignment fails first under fast yaw, where the gyro is at its best.
    p.use_prior = config.use_rotation_prior && steps != nullptr;
    if (p.use_prior) {
      p.R_ref_prior = steps->chain.R_ref_cur;
      p.prior_information = gyro.prior_information(steps->chain_covariance);
      p.step_information = gyro.prior_information(steps->step_covariance);
      p.T_ref_predicted.linear() = p.R_ref_prior;
    }
    return p;
  }

  // Keyframe check, first half: aligns the current frame to the previous one. Returns whether
  // that alignment is usable as the keyframe alignment's start and check.
  bool align_to_previous(const FrameSlot& current, const Prediction& to_reference,
                         const GyroSteps* steps, Alignment& to_previous) {
    Prediction p;
    p.use_prior = to_reference.use_prior;
    p.prior_information = to_reference.step_information;
    if (p.use_prior) p.R_ref_prior = steps->R_prev_cur;
    p.T_ref_predicted = has_motion && config.initialize_with_previous_motion
                            ? last_motion
                            : Eigen::Isometry3d::Identity();
    if (p.use_prior) p.T_ref_predicted.linear() = steps->R_prev_cur;
    to_previous = aligner.align(previous, current, p.T_ref_predicted.inverse(), p);
    return to_previous.T_cur_ref.matrix().allFinite() && to_previous.normal.H.allFinite() &&
           to_previous.valid >= 6 && finest_ratio(to_previous.valid) >= config.min_valid_ratio;
  }

  // The keyframe chain broke (Kerl IROS 2013 re-anchors on such failures): this frame's pose
  // comes from the previous frame, and this frame becomes the keyframe.
  OdometryResult re_anchor_on_previous(OdometryResult result, const Alignment& a,
                                       const Alignment& to_previous, int current_slot) {
    const NormalEquations& normal = to_previous.normal;
    const Eigen::Isometry3d T_prev_cur = to_previous.T_cur_ref.inverse();
    result.iterations = a.iterations + to_previous.iterations;
    result.valid_ratio = finest_ratio(to_previous.valid);
    result.mean_weighted_error = to_previous.weighted_error;
    result.status = TrackingStatus::kOk;
    result.reason = "";
    result.T_ref_cur = T_prev_cur;
    result.information = pose_information(normal);
    result.T_O_C = T_O_ref * T_ref_last * T_prev_cur;
    last_motion = T_prev_cur;
    last_information = normal.H;
    has_motion = true;
    make_reference(current_slot, result.T_O_C);
    result.new_keyframe = has_reference;
    return result;
  }

  // After a good alignment: the next frame's reference is this frame (frame to frame, or a
  // keyframe that has aged or lost too much information) or stays, with this frame prepared
  // as the previous one for the keyframe check.
  void update_reference(int current_slot, const FrameSlot& current,
                        const Eigen::Isometry3d& T_ref_cur, const Alignment& a,
                        OdometryResult& result) {
    const bool new_reference = keyframes.reference_ends_with(a.normal.H, a.valid);
    keyframes.count_alignment(a.normal.H);
    if (new_reference) {
      moving.mark(aligner, reference, slot(reference_slot), current, a,
                  drops_seen_moving() ? &seen_moving.finest_marks() : nullptr);
      make_reference(current_slot, result.T_O_C);
      // The motion of this frame relative to its predecessor stays the prediction.
      result.new_keyframe = has_reference;
      return;
    }
    T_ref_last = T_ref_cur;
    previous_slot = current_slot;
    if (keyframe_check()) {
      preparer.prepare(current, nullptr, previous);
      has_previous = true;
    }
  }

  // The outcome of the alignment to the reference: lost if it did not converge on enough
  // pixels or the scene leaves the translation unmeasured (the frame then becomes the
  // reference), else the pose and the next reference.
  OdometryResult accept(OdometryResult result, const Alignment& a, int current_slot,
                        const FrameSlot& current) {
    const Eigen::Isometry3d& T_cur_ref = a.T_cur_ref;
    const NormalEquations& normal = a.normal;
    result.iterations = a.iterations;
    result.valid_ratio = finest_ratio(a.valid);
    result.mean_weighted_error = a.weighted_error;
    const bool converged_numbers =
        T_cur_ref.matrix().allFinite() && normal.H.allFinite() && a.valid >= 6;
    const char* lost_because = nullptr;
    if (!converged_numbers || result.valid_ratio < config.min_valid_ratio) {
      lost_because = "too few reference pixels visible in the current frame";
    } else if (detail::translation_unconstrained(normal, config)) {
      // A textureless wall seen with the depth term: translation along it is not measured,
      // and a pose from it would read as standing still while the vehicle slides.
      lost_because = "degenerate: the scene does not constrain the translation in some direction";
    }
    if (lost_because != nullptr) {
      // Keep flying on the newest frame: it becomes the reference if it has depth.
      const Eigen::Isometry3d T_O_C = result.T_O_C;
      OdometryResult out = lost(result, lost_because);
      make_reference(current_slot, T_O_C);
      return out;
    }
    const Eigen::Isometry3d T_ref_cur = T_cur_ref.inverse();
    result.status = TrackingStatus::kOk;
    result.reason = "";
    result.T_ref_cur = T_ref_cur;
    result.information = pose_information(normal);
    result.T_O_C = T_O_ref * T_ref_cur;
    last_motion = T_ref_last.inverse() * T_ref_cur;
    last_information = normal.H;
    has_motion = true;
    update_reference(current_slot, current, T_ref_cur, a, result);
    return result;
  }

  // Frame to keyframe: the keyframe points this alignment saw move are left out of it for
  // good, and when they were more than moving_realign_ratio of its points, the frame is
  // aligned again without them: they pulled it (the first frames against a new keyframe that
  // holds a walking person, whose pixels no earlier alignment saw move).
  void align_again_without_moving_points(const FrameSlot& current, const Prediction& p,
                                         Alignment& a) {
    if (!drops_seen_moving() || !a.T_cur_ref.matrix().allFinite() || a.valid < 6) return;
    const int left_out = seen_moving.leave_out(aligner, reference, current, a);
    if (left_out == 0 || left_out <= config.moving_realign_ratio * a.valid) return;
    const int iterations = a.iterations;
    a = aligner.align(reference, current, a.T_cur_ref, p);
    a.iterations += iterations;
  }

  // Builds the frame into a slot that is neither the reference nor the previous frame.
  int build_frame(const cv::Mat& gray, const cv::Mat& depth_m, const RotationPrior* prior) {
    int current_slot = 0;
    while (current_slot == reference_slot || current_slot == previous_slot) ++current_slot;
    FrameSlot& current = slot(current_slot);
    const bool turn_depth = frames.should_align_depth(prior);
    frames.build(current, gray, depth_m, turn_depth);
    if (turn_depth) frames.align_depth(current, prior->R_depth_colour);
    return current_slot;
  }

  OdometryResult first_frame(OdometryResult result, int current_slot) {
    make_reference(current_slot, result.T_O_C);
    result.status = has_reference ? TrackingStatus::kFirstFrame : TrackingStatus::kLost;
    result.reason = has_reference ? "first frame: became the reference"
                                  : "no usable depth: too few pixels with depth and gradient";
    result.new_keyframe = has_reference;
    return result;
  }

  // The vision's own rotation, against the gyro's, costs a few more iterations: found only
  // for what learns from it (the bias against a keyframe about to end, the honest scale).
  bool observe_gyro(const FrameSlot& current, const Alignment& a, const Prediction& p,
                    const GyroSteps& steps, bool learn_bias, GyroObservation& observation) {
    if (!(learn_bias || config.adapt_vision_information) || !p.use_prior) return false;
    const Alignment vision = aligner.vision_only(reference, current, a);
    return gyro.observe(vision.T_cur_ref, vision.normal, p.R_ref_prior, steps, observation);
  }

  OdometryResult track(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m,
                       const RotationPrior* prior) {
    OdometryResult result;
    result.t_ns = t_ns;
    result.T_O_C = T_O_ref * T_ref_last;
    if (gray.type() != CV_8UC1 || depth_m.type() != CV_32FC1 || gray.cols != camera.width ||
        gray.rows != camera.height || depth_m.size() != gray.size()) {
      return lost(result, "input is not CV_8UC1 gray and CV_32FC1 depth of the camera's size");
    }
    const int current_slot = build_frame(gray, depth_m, prior);
    const FrameSlot& current = slot(current_slot);
    const double step_s =
        last_frame_t_ns >= 0 ? 1e-9 * static_cast<double>(t_ns - last_frame_t_ns) : 0.0;
    last_frame_t_ns = t_ns;
    result.gyro_bias_radps = gyro.bias();
    result.vision_information_scale = gyro.vision_scale();
    if (!has_reference) return first_frame(result, current_slot);

    // The gyro, with the bias estimate removed and its uncertainty allowed for, before anything
    // uses it. The chain is kept when this frame is accepted against the same reference.
    gyro.propagate(t_ns);
    GyroSteps steps;
    const bool have_gyro = prior != nullptr && gyro.steps(*prior, step_s, steps);
    const GyroSteps* gyro_steps = have_gyro ? &steps : nullptr;

    const Prediction p = predict_motion(gyro_steps);
    Eigen::Isometry3d T_cur_ref_guess = p.T_ref_predicted.inverse();
    // Keyframe check: align to the previous frame as well, start the keyframe alignment from
    // that, and re-anchor on the previous frame when the two disagree.
    Alignment to_previous;
    const bool previous_ok =
        keyframe_check() && has_previous && align_to_previous(current, p, gyro_steps, to_previous);
    if (previous_ok) T_cur_ref_guess = (T_ref_last * to_previous.T_cur_ref.inverse()).inverse();

    Alignment a = aligner.align(reference, current, T_cur_ref_guess, p);
    if (previous_ok &&
        detail::keyframe_chain_broke(config, cameras.finest_pixels(), a, to_previous, T_ref_last)) {
      return re_anchor_on_previous(result, a, to_previous, current_slot);
    }
    if (previous_ok) a.iterations += to_previous.iterations;
    align_again_without_moving_points(current, p, a);
    const bool learn_bias = config.estimate_gyro_bias &&
                            config.reference_mode == ReferenceMode::kFrameToKeyframe &&
                            keyframes.reference_ends_with(a.normal.H, a.valid);
    GyroObservation observation;
    const bool observed = have_gyro && observe_gyro(current, a, p, steps, learn_bias, observation);
    // Before accept(): a new reference starts a new chain.
    gyro.keep_chain(gyro_steps);
    result = accept(result, a, current_slot, current);
    if (observed && result.ok()) gyro.learn(observation, learn_bias);
    result.gyro_bias_radps = gyro.bias();
    result.vision_information_scale = gyro.vision_scale();
    return result;
  }

  void reset() {
    has_reference = false;
    has_motion = false;
    has_previous = false;
    T_O_ref.setIdentity();
    T_ref_last.setIdentity();
    gyro.reset();
    last_frame_t_ns = -1;
  }
};

DenseOdometry::DenseOdometry(const OdometryConfig& config, const geometry::PinholeCamera& camera)
    : impl_(std::make_unique<Impl>(config, camera)) {}

DenseOdometry::~DenseOdometry() = default;

OdometryResult DenseOdometry::track(std::int64_t t_ns, const cv::Mat& gray,
                                    const cv::Mat& depth_m) {
  return impl_->track(t_ns, gray, depth_m, nullptr);
}

OdometryResult DenseOdometry::track(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m,
                                    const RotationPrior* prior) {
  return impl_->track(t_ns, gray, depth_m, prior);
}

void DenseOdometry::reset() { impl_->reset(); }

const OdometryConfig& DenseOdometry::config() const { return impl_->config; }

}  // namespace hq::odometry
