// Dense odometry on real recorded depth (TUM RGB-D) against motion-capture ground truth.
// Each bound sits beside the figure measured when it was set (hq-bench-odometry, same code),
// with a margin of at most 25 %.
#include "hq/config/camera_info.hpp"
#include "hq/evaluation/trajectory_error.hpp"
#include "hq/odometry/dense_odometry.hpp"
#include "hq/recording/data_dir.hpp"
#include "hq/sources/tum_frame_source.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fmt/format.h>
#include <map>
#include <string>
#include <vector>

namespace {

struct Bounds {
  double measured_rpe_trans_mps, max_rpe_trans_mps;
  double measured_rpe_rot_degps, max_rpe_rot_degps;
  double measured_ate_m, max_ate_m;
};

// Keyed by sequence folder and reference mode. RPE windows are clipped to the 0.27 s that the
// five bundled fr1_360 frames span (see ../shared/data/SOURCES.md).
const std::map<std::string, Bounds> kBounds = {
    {"rgbd_dataset_freiburg1_360/frame_to_frame", {0.0464, 0.056, 1.956, 2.40, 0.0016, 0.0020}},
    {"rgbd_dataset_freiburg1_360/frame_to_keyframe", {0.0395, 0.048, 1.719, 2.10, 0.0016, 0.0020}},
};

struct SequenceRun {
  std::vector<hq::recording::StampedPose> trajectory;
  std::vector<hq::recording::StampedPose> ground_truth;
  int lost = 0;
};

SequenceRun run_sequence(const std::string& dir, hq::odometry::ReferenceMode mode) {
  hq::sources::TumFrameSource source(dir, hq::config::load_camera_info("calib/tum_fr1.yaml"));
  hq::odometry::OdometryConfig config;
  config.reference_mode = mode;
  hq::odometry::DenseOdometry odometry(config, source.camera());
  SequenceRun run;
  run.ground_truth = source.sequence().ground_truth();
  hq::sources::RgbdFrame frame;
  while (source.next(frame) == hq::sources::FrameStatus::kFrame) {
    const auto result = odometry.track(frame.t_ns, frame.gray, frame.depth_m);
    if (result.status == hq::odometry::TrackingStatus::kLost) ++run.lost;
    run.trajectory.push_back({frame.t_ns, result.T_O_C});
  }
  return run;
}

class OdometryOnRecordedDepth : public ::testing::TestWithParam<hq::odometry::ReferenceMode> {};

TEST_P(OdometryOnRecordedDepth, RpeAndAteStayWithinMeasuredBounds) {
  const auto data = hq::recording::find_data_dir();
  if (!data) GTEST_SKIP() << "no real data: " << hq::recording::data_dir_search_description();
  const std::string mode_name = GetParam() == hq::odometry::ReferenceMode::kFrameToFrame
                                    ? "frame_to_frame"
                                    : "frame_to_keyframe";
  int checked = 0;
  for (const auto& entry : std::filesystem::directory_iterator(*data + "/tum")) {
    const std::string name = entry.path().filename().string();
    const auto bounds = kBounds.find(name + "/" + mode_name);
    if (bounds == kBounds.end()) {
      fmt::print("{}: no bounds recorded for this sequence; measure and add them\n", name);
      continue;
    }
    const SequenceRun run = run_sequence(entry.path().string(), GetParam());
    ASSERT_FALSE(run.ground_truth.empty()) << name << " has no groundtruth.txt";
    EXPECT_EQ(run.lost, 0) << name;
    const auto rpe = hq::evaluation::relative_pose_error(run.ground_truth, run.trajectory);
    const auto ate = hq::evaluation::absolute_trajectory_error(run.ground_truth, run.trajectory);
    const Bounds& b = bounds->second;
    fmt::print(
        "{} {}: RPE {:.4f} m/s (measured {:.4f}, bound {:.4f}), {:.3f} deg/s ({:.3f}, {:.3f}), ATE "
        "{:.4f} m ({:.4f}, {:.4f})\n",
        name, mode_name, rpe.trans_mps.rmse, b.measured_rpe_trans_mps, b.max_rpe_trans_mps,
        rpe.rot_degps.rmse, b.measured_rpe_rot_degps, b.max_rpe_rot_degps, ate.trans_m.rmse,
        b.measured_ate_m, b.max_ate_m);
    EXPECT_LT(rpe.trans_mps.rmse, b.max_rpe_trans_mps) << name;
    EXPECT_LT(rpe.rot_degps.rmse, b.max_rpe_rot_degps) << name;
    EXPECT_LT(ate.trans_m.rmse, b.max_ate_m) << name;
    ++checked;
  }
  EXPECT_GT(checked, 0) << "the data folder " << *data << "/tum holds no sequence with bounds";
}

INSTANTIATE_TEST_SUITE_P(ReferenceModes, OdometryOnRecordedDepth,
                         ::testing::Values(hq::odometry::ReferenceMode::kFrameToFrame,
                                           hq::odometry::ReferenceMode::kFrameToKeyframe));

}  // namespace
