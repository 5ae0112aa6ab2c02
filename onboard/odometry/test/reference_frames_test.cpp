// When the reference changes: DVO-SLAM's entropy ratio, the keyframe's age and coverage, the
// keyframe check's verdict, and the pixels a new reference leaves out because they moved.
#include "reference_frames.hpp"

#include "prepared_plane.hpp"
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace hq::odometry::detail {
namespace {

using test::pose;
using test::PreparedPlane;

TEST(EntropyOf, IsMinusHalfTheLogDeterminant) {
  EXPECT_DOUBLE_EQ(entropy_of(Matrix6d::Identity()), 0.0);
  EXPECT_NEAR(entropy_of(2.0 * Matrix6d::Identity()), -3.0 * std::log(2.0), 1e-12);
  // More information, less entropy.
  EXPECT_LT(entropy_of(10.0 * Matrix6d::Identity()), entropy_of(5.0 * Matrix6d::Identity()));
  EXPECT_EQ(entropy_of(-Matrix6d::Identity()), 0.0);  // not an information matrix
}

constexpr int kFinestPixels = 320 * 240;
constexpr int kMostPixels = kFinestPixels / 2;

TEST(KeyframeSelection, FrameToFrameEveryFrameIsTheNextReference) {
  OdometryConfig config;
  config.reference_mode = ReferenceMode::kFrameToFrame;
  const KeyframeSelection keyframes(config, kFinestPixels);
  EXPECT_TRUE(keyframes.reference_ends_with(10.0 * Matrix6d::Identity(), kMostPixels));
}

TEST(KeyframeSelection, KeyframeEndsWhenTheEntropyRatioFalls) {
  const OdometryConfig config;  // ratio 0.9
  KeyframeSelection keyframes(config, kFinestPixels);
  const Matrix6d first = 10.0 * Matrix6d::Identity();
  EXPECT_FALSE(keyframes.reference_ends_with(first, kMostPixels));
  keyframes.count_alignment(first);
  // entropy(9.5 I) / entropy(10 I) = ln 9.5 / ln 10 = 0.98: kept; ln 5 / ln 10 = 0.70: ends.
  EXPECT_FALSE(keyframes.reference_ends_with(9.5 * Matrix6d::Identity(), kMostPixels));
  EXPECT_TRUE(keyframes.reference_ends_with(5.0 * Matrix6d::Identity(), kMostPixels));
}

TEST(KeyframeSelection, KeyframeEndsWithAge) {
  OdometryConfig config;
  config.max_keyframe_age = 3;
  KeyframeSelection keyframes(config, kFinestPixels);
  const Matrix6d H = 10.0 * Matrix6d::Identity();
  keyframes.count_alignment(H);
  EXPECT_FALSE(keyframes.reference_ends_with(H, kMostPixels));  // second frame
  keyframes.count_alignment(H);
  EXPECT_TRUE(keyframes.reference_ends_with(H, kMostPixels));  // third
  keyframes.restart();
  EXPECT_FALSE(keyframes.reference_ends_with(H, kMostPixels));
}

TEST(KeyframeSelection, KeyframeWithLittleInViewEnds) {
  const OdometryConfig config;  // keyframe_min_valid_ratio 0.05
  const KeyframeSelection keyframes(config, kFinestPixels);
  const Matrix6d H = 10.0 * Matrix6d::Identity();
  EXPECT_FALSE(keyframes.reference_ends_with(H, kFinestPixels / 10));
  EXPECT_TRUE(keyframes.reference_ends_with(H, kFinestPixels / 25));
}

Alignment aligned(const Eigen::Isometry3d& T_cur_ref) {
  Alignment a;
  a.T_cur_ref = T_cur_ref;
  a.valid = kMostPixels;
  return a;
}

TEST(KeyframeChainBroke, AgreeingChainsHold) {
  const OdometryConfig config;
  const Eigen::Isometry3d T_ref_prev = pose(0.05, 0.0, 0.0, 0.0, 0.02, 0.0);
  const Eigen::Isometry3d T_prev_cur = pose(0.01, 0.0, 0.0, 0.0, 0.0, 0.003);
  const Alignment to_keyframe = aligned((T_ref_prev * T_prev_cur).inverse());
  const Alignment to_previous = aligned(T_prev_cur.inverse());
  EXPECT_FALSE(keyframe_chain_broke(config, kFinestPixels, to_keyframe, to_previous, T_ref_prev));
}

TEST(KeyframeChainBroke, DisagreementBeyondTheBoundsBreaksIt) {
  const OdometryConfig config;  // 1 cm, 0.5 deg
  const Eigen::Isometry3d T_ref_prev = pose(0.05, 0.0, 0.0, 0.0, 0.02, 0.0);
  const Eigen::Isometry3d T_prev_cur = pose(0.01, 0.0, 0.0, 0.0, 0.0, 0.003);
  const Alignment to_previous = aligned(T_prev_cur.inverse());
  const Eigen::Isometry3d slipped = pose(0.0, 0.02, 0.0, 0.0, 0.0, 0.0);  // 2 cm
  EXPECT_TRUE(keyframe_chain_broke(config, kFinestPixels,
                                   aligned((T_ref_prev * T_prev_cur * slipped).inverse()),
                                   to_previous, T_ref_prev));
  const Eigen::Isometry3d turned = pose(0.0, 0.0, 0.0, 0.0, 0.0, 0.0175);  // 1 deg
  EXPECT_TRUE(keyframe_chain_broke(config, kFinestPixels,
                                   aligned((T_ref_prev * T_prev_cur * turned).inverse()),
                                   to_previous, T_ref_prev));
  Alignment unusable = aligned((T_ref_prev * T_prev_cur).inverse());
  unusable.valid = 5;
  EXPECT_TRUE(keyframe_chain_broke(config, kFinestPixels, unusable, to_previous, T_ref_prev));
}

int marked_in(const cv::Mat& marks, const cv::Rect& area) {
  return cv::countNonZero(marks(area & cv::Rect(0, 0, marks.cols, marks.rows)));
}

TEST(MovingPixels, PatchThatChangedIsMarkedAndLeftOutOfTheNextReference) {
  const OdometryConfig config;  // 4 sigma, finest level 1 (320x240)
  PreparedPlane plane(config);
  // GIVEN a reference and a current frame seen from the same pose, but for a patch that
  // changed between them (something moved there)
  plane.prepare_reference(Eigen::Isometry3d::Identity());
  cv::Mat gray, depth_m;
  PreparedPlane::render(Eigen::Isometry3d::Identity(), gray, depth_m);
  const cv::Rect patch(200, 160, 120, 100);  // full resolution
  cv::Mat changed = gray(patch);
  cv::bitwise_not(changed, changed);
  plane.frames.build(plane.current, gray, depth_m, false);
  Aligner aligner(config, plane.cameras);
  Alignment a;
  a.variance = 4.0;  // a residual sigma of 2 grey levels
  // WHEN the alignment at the identity marks the current frame's moving pixels
  MovingPixels moving(config, plane.cameras);
  ASSERT_EQ(moving.known(), nullptr);
  moving.mark(aligner, plane.reference, plane.reference_frame, plane.current, a, nullptr);
  // THEN the patch is marked on the finest level and the coarser ones, and little else
  ASSERT_NE(moving.known(), nullptr);
  const cv::Mat& finest = at_level(*moving.known(), 1);
  const cv::Rect patch_finest(100, 80, 60, 50);
  EXPECT_GT(marked_in(finest, patch_finest), patch_finest.area() / 2);
  const cv::Rect around(96, 76, 68, 58);
  EXPECT_LT(cv::countNonZero(finest) - marked_in(finest, around), 50);
  EXPECT_GT(marked_in(at_level(*moving.known(), 2), cv::Rect(50, 40, 30, 25)), 30 * 25 / 2);
  // ... and the current frame prepared as the reference leaves every marked pixel out.
  plane.prepare_reference(gray, depth_m);
  const int unmarked_points = at_level(plane.reference, 1).count;
  plane.prepare_reference(gray, depth_m, moving.known());
  const ReferenceLevel& ref = at_level(plane.reference, 1);
  EXPECT_LT(ref.count, unmarked_points - 1000);
  const Intrinsics k = plane.cameras.intrinsics(1);
  for (std::size_t i = 0; i < static_cast<std::size_t>(ref.count); ++i) {
    const auto u = static_cast<int>(std::lround(k.fx * ref.x[i] / ref.z[i] + k.cx));
    const auto v = static_cast<int>(std::lround(k.fy * ref.y[i] / ref.z[i] + k.cy));
    ASSERT_EQ(finest.at<std::uint8_t>(v, u), 0) << u << ", " << v;
  }
  moving.forget();
  EXPECT_EQ(moving.known(), nullptr);
}

TEST(MovingPixels, WhenMostOfTheViewMovedNothingIsMarkedOrLeftOut) {
  const OdometryConfig config;  // max_moving_ratio 0.5
  PreparedPlane plane(config);
  plane.prepare_reference(Eigen::Isometry3d::Identity());
  cv::Mat gray, depth_m;
  PreparedPlane::render(Eigen::Isometry3d::Identity(), gray, depth_m);
  gray = 255 - gray;  // everything changed: the alignment, not the scene, is in doubt
  plane.frames.build(plane.current, gray, depth_m, false);
  Aligner aligner(config, plane.cameras);
  Alignment a;
  a.variance = 4.0;
  MovingPixels moving(config, plane.cameras);
  moving.mark(aligner, plane.reference, plane.reference_frame, plane.current, a, nullptr);
  EXPECT_EQ(moving.known(), nullptr);
  // ... and no keyframe point leaves either
  SeenMovingPoints seen(config, plane.cameras);
  EXPECT_EQ(seen.leave_out(aligner, plane.reference, plane.current, a), 0);
  EXPECT_EQ(cv::countNonZero(seen.finest_marks()), 0);
  const ReferenceLevel& finest = at_level(plane.reference, 1);
  int kept = 0;
  for (std::size_t i = 0; i < static_cast<std::size_t>(finest.count); ++i) {
    kept += finest.photometric[i] > 0.0f ? 1 : 0;
  }
  EXPECT_GT(kept, finest.count / 2);
}

TEST(MovingPixels, OffMarksNothing) {
  OdometryConfig config;
  config.moving_residual_sigmas = 0.0;
  PreparedPlane plane(config);
  plane.prepare_reference(Eigen::Isometry3d::Identity());
  plane.build_current(pose(0.05, 0.0, 0.0, 0.0, 0.0, 0.0));  // 5 cm off: large residuals
  Aligner aligner(config, plane.cameras);
  MovingPixels moving(config, plane.cameras);
  moving.mark(aligner, plane.reference, plane.reference_frame, plane.current, Alignment{}, nullptr);
  EXPECT_EQ(moving.known(), nullptr);
}

TEST(MovingPixels, DenseMarksCoverAPatchThatCameNearer) {
  OdometryConfig config;  // occlusion_depth_ratio 0.2
  config.dense_moving_marks = true;
  PreparedPlane plane(config);
  // GIVEN a reference of the plane, and a current frame in which a patch without texture
  // stands at half the plane's depth (something walked in front of it): no reference point's
  // residual tells, as the reference points behind it are hidden
  plane.prepare_reference(Eigen::Isometry3d::Identity());
  cv::Mat gray, depth_m;
  PreparedPlane::render(Eigen::Isometry3d::Identity(), gray, depth_m);
  const cv::Rect patch(200, 160, 120, 100);  // full resolution
  gray(patch) = 128;
  depth_m(patch) *= 0.5;
  plane.frames.build(plane.current, gray, depth_m, false);
  Aligner aligner(config, plane.cameras);
  Alignment a;
  a.variance = 4.0;
  const cv::Rect patch_finest(100, 80, 60, 50);
  // WHEN the current frame's moving pixels are marked, densely and not
  OdometryConfig sparse_config = config;
  sparse_config.dense_moving_marks = false;
  MovingPixels dense(config, plane.cameras);
  MovingPixels sparse(sparse_config, plane.cameras);
  dense.mark(aligner, plane.reference, plane.reference_frame, plane.current, a, nullptr);
  sparse.mark(aligner, plane.reference, plane.reference_frame, plane.current, a, nullptr);
  // THEN the dense marks cover the whole patch, and little else
  ASSERT_NE(dense.known(), nullptr);
  const cv::Mat& finest = at_level(*dense.known(), 1);
  EXPECT_EQ(marked_in(finest, patch_finest), patch_finest.area());
  EXPECT_LT(cv::countNonZero(finest) - marked_in(finest, cv::Rect(96, 76, 68, 58)), 50);
  // (the textured plane's hidden points mark most of it too; on a floor of little texture
  // they are few, and the first frames aligned to the new keyframe were pulled by the rest)
  EXPECT_LT(sparse.known() != nullptr ? marked_in(at_level(*sparse.known(), 1), patch_finest) : 0,
            patch_finest.area());
}

TEST(MovingPixels, DenseMarksKeepWhatTheOldReferenceSawMove) {
  OdometryConfig config;
  config.dense_moving_marks = true;
  PreparedPlane plane(config);
  plane.prepare_reference(Eigen::Isometry3d::Identity());
  plane.build_current(Eigen::Isometry3d::Identity());
  Aligner aligner(config, plane.cameras);
  Alignment a;
  a.variance = 4.0;
  // GIVEN nothing changed between the frames, but the old reference saw a region move
  cv::Mat seen(240, 320, CV_8UC1, cv::Scalar(0));  // the finest level's size
  const cv::Rect region(20, 20, 30, 30);
  seen(region) = 1;
  // WHEN the current frame's pixels are marked
  MovingPixels moving(config, plane.cameras);
  moving.mark(aligner, plane.reference, plane.reference_frame, plane.current, a, &seen);
  // THEN that region stays marked (the same surface is still there), and nothing else
  ASSERT_NE(moving.known(), nullptr);
  const cv::Mat& finest = at_level(*moving.known(), 1);
  EXPECT_EQ(marked_in(finest, region), region.area());
  EXPECT_EQ(cv::countNonZero(finest), region.area());
}

TEST(SeenMovingPoints, PointsSeenMovingLeaveTheKeyframeOnEveryLevel) {
  const OdometryConfig config;  // 4 sigma
  PreparedPlane plane(config);
  // GIVEN a keyframe and a frame seen from the same pose, but for a patch that changed
  plane.prepare_reference(Eigen::Isometry3d::Identity());
  const ReferenceSet untouched = plane.reference;
  cv::Mat gray, depth_m;
  PreparedPlane::render(Eigen::Isometry3d::Identity(), gray, depth_m);
  const cv::Rect patch(200, 160, 120, 100);  // full resolution
  cv::Mat changed = gray(patch);
  cv::bitwise_not(changed, changed);
  plane.frames.build(plane.current, gray, depth_m, false);
  Aligner aligner(config, plane.cameras);
  Alignment a;
  a.variance = 4.0;
  // WHEN the points seen moving leave the keyframe
  SeenMovingPoints seen(config, plane.cameras);
  const int left_out = seen.leave_out(aligner, plane.reference, plane.current, a);
  // THEN the patch's points no longer carry a residual, on every level, and the others do
  EXPECT_GT(left_out, 500);
  for (int l = 1; l < config.pyramid_levels; ++l) {
    const ReferenceLevel& ref = at_level(plane.reference, l);
    const ReferenceLevel& before = at_level(untouched, l);
    ASSERT_EQ(ref.count, before.count);
    const Intrinsics k = plane.cameras.intrinsics(l);
    const double scale = 1.0 / (1 << l);
    const cv::Rect area(static_cast<int>(patch.x * scale), static_cast<int>(patch.y * scale),
                        static_cast<int>(patch.width * scale),
                        static_cast<int>(patch.height * scale));
    const cv::Rect far_from_it(area.x - 4, area.y - 4, area.width + 8, area.height + 8);
    int inside_kept = 0, outside_dropped = 0, inside = 0;
    for (std::size_t i = 0; i < static_cast<std::size_t>(ref.count); ++i) {
      if (before.photometric[i] <= 0.0f) continue;
      const cv::Point p(static_cast<int>(std::lround(k.fx * ref.x[i] / ref.z[i] + k.cx)),
                        static_cast<int>(std::lround(k.fy * ref.y[i] / ref.z[i] + k.cy)));
      const bool kept = ref.photometric[i] > 0.0f;
      if (area.contains(p)) {
        ++inside;
        inside_kept += kept ? 1 : 0;
      } else if (!far_from_it.contains(p)) {
        outside_dropped += kept ? 0 : 1;
      }
    }
    // Marks come from the finest level's points (and their neighbours); a coarser level has
    // points where the finest one's gradient is too weak for any, which keep: measured 0 %
    // on the finest level, 25 % and 23 % on the next two.
    EXPECT_LT(inside_kept, l == 1 ? inside / 10 : inside / 3) << "level " << l;
    EXPECT_EQ(outside_dropped, 0) << "level " << l;
  }
  // ... and a new keyframe starts with nothing left out.
  seen.restart();
  EXPECT_EQ(cv::countNonZero(seen.finest_marks()), 0);
}

// Keyframe points left out by `config` after an alignment at the keyframe's own pose against
// the same image shifted right by `shift_px` (full-resolution pixels), with `markers` painted
// black (sharp edges) and `patch` shifted by `patch_shift_px` more; `on_edges` counts those
// left out within 2 finest-level pixels of a marker's edge, `in_patch` those inside the patch.
struct LeftOut {
  int on_edges = 0;
  int in_patch = 0;
  int beyond_patch = 0;  ///< outside the patch grown by 12 px (the radius 5 at level 1, and one)
};
LeftOut left_out_after_shift(const OdometryConfig& config, double shift_px,
                             const std::vector<cv::Rect>& markers, const cv::Rect& patch,
                             double patch_shift_px) {
  PreparedPlane plane(config);
  cv::Mat gray, depth_m;
  PreparedPlane::render(Eigen::Isometry3d::Identity(), gray, depth_m);
  for (const cv::Rect& m : markers) gray(m) = 0;
  plane.prepare_reference(gray, depth_m);
  const ReferenceSet untouched = plane.reference;
  const auto shifted = [](const cv::Mat& in, double dx) {
    cv::Mat out;
    const cv::Matx23d M(1, 0, dx, 0, 1, 0);
    cv::warpAffine(in, out, M, in.size(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    return out;
  };
  cv::Mat current = shifted(gray, shift_px);
  shifted(gray, shift_px + patch_shift_px)(patch).copyTo(current(patch));
  plane.frames.build(plane.current, current, depth_m, false);
  Aligner aligner(config, plane.cameras);
  Alignment a;
  a.variance = 4.0;
  SeenMovingPoints seen(config, plane.cameras);
  seen.leave_out(aligner, plane.reference, plane.current, a);
  const ReferenceLevel& ref = at_level(plane.reference, 1);
  const ReferenceLevel& before = at_level(untouched, 1);
  const Intrinsics k = plane.cameras.intrinsics(1);
  LeftOut out;
  for (std::size_t i = 0; i < static_cast<std::size_t>(ref.count); ++i) {
    if (before.photometric[i] <= 0.0f || ref.photometric[i] > 0.0f) continue;
    const cv::Point p(static_cast<int>(std::lround(k.fx * ref.x[i] / ref.z[i] + k.cx)),
                      static_cast<int>(std::lround(k.fy * ref.y[i] / ref.z[i] + k.cy)));
    const cv::Point full(2 * p.x, 2 * p.y);
    if (patch.contains(full)) ++out.in_patch;
    const cv::Rect grown(patch.x - 12, patch.y - 12, patch.width + 24, patch.height + 24);
    if (!grown.contains(full)) ++out.beyond_patch;
    for (const cv::Rect& m : markers) {
      const cv::Rect outer(m.x - 4, m.y - 4, m.width + 8, m.height + 8);
      const cv::Rect inner(m.x + 4, m.y + 4, m.width - 8, m.height - 8);
      if (outer.contains(full) && !inner.contains(full)) ++out.on_edges;
    }
  }
  return out;
}

TEST(SeenMovingPoints, SharpEdgesOffByLessThanAPixelStayWhatMovedByPixelsLeaves) {
  // GIVEN black markers on the textured plane (edges of 100+ grey levels per pixel), the whole
  // image off by 0.4 px from where the alignment put it, and a patch that moved 6 px more
  const std::vector<cv::Rect> markers{{60, 60, 80, 80}, {420, 80, 80, 80}, {100, 320, 80, 80}};
  const cv::Rect patch(380, 280, 160, 140);
  OdometryConfig config;  // moving_min_displacement_px 1
  // WHEN the points seen moving leave the keyframe
  const LeftOut kept_edges = left_out_after_shift(config, 0.4, markers, patch, 6.0);
  config.moving_min_displacement_px = 0.0;  // the residual's sigmas alone
  const LeftOut residual_alone = left_out_after_shift(config, 0.4, markers, patch, 6.0);
  // THEN the markers' edges stay (their residuals are many sigmas, their image moved 0.2
  // finest-level pixels), the moved patch leaves; judged by the residual alone, the edges left
  // too (the marker field's explore flight then lost its best points: docs/odometry.md)
  EXPECT_EQ(kept_edges.on_edges, 0);
  EXPECT_GT(kept_edges.in_patch, 200);
  EXPECT_GT(residual_alone.on_edges, 100);
}

TEST(SeenMovingPoints, AWiderMarkRadiusTakesThePixelsAroundWhatMovedAndNoFarther) {
  // GIVEN the shifted image and moved patch of the test above
  const std::vector<cv::Rect> markers{{60, 60, 80, 80}};
  const cv::Rect patch(380, 280, 160, 140);
  OdometryConfig config;
  const LeftOut four_neighbours = left_out_after_shift(config, 0.4, markers, patch, 6.0);
  // WHEN a point seen moving takes the pixels within 5 (finest level, here half resolution)
  config.moving_mark_radius_px = 5;
  const LeftOut wide = left_out_after_shift(config, 0.4, markers, patch, 6.0);
  // THEN more of the patch leaves (its low-gradient points between those seen moving), and
  // nothing beyond the patch's reach or on the marker's still edges
  EXPECT_GT(wide.in_patch, four_neighbours.in_patch + 100);
  EXPECT_EQ(wide.beyond_patch, 0);
  EXPECT_EQ(wide.on_edges, 0);
}

}  // namespace
}  // namespace hq::odometry::detail
