// Dense odometry on simulated RGB-D runs with exact ground truth: 8 s of hq-sim's scripted
// circle in worlds/room.yaml at 320x240, far longer than the five bundled real frames, so RPE
// over 1 s windows and ATE measure drift. Frames go from the renderer to the odometry in
// memory. Each bound sits beside the figure measured when it was set (this test, same code and
// seed), with a margin of at most 25 %.
#include "hq/evaluation/trajectory_error.hpp"
#include "hq/geometry/lie.hpp"
#include "hq/odometry/dense_odometry.hpp"
#include "hq/recording/tum_io.hpp"
#include "hq/sim/scripted_flight.hpp"
#include "hq/sim/simulator.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fmt/format.h>
#include <optional>
#include <string>
#include <vector>

namespace {

constexpr std::uint64_t kSeed = 7;
// The camera starts on the floor, closer than the depth sensor's 0.5 m minimum range, so no
// frame has depth before take-off (1 s); by 3 s the vehicle hovers at 0.97 m. Tracking starts
// there and covers the end of the hover, the circle's speed ramp and the circle itself.
constexpr std::int64_t kTrackStartNs = 3'000'000'000;
constexpr std::int64_t kTrackDurationNs = 8'000'000'000;

struct Bounds {
  double measured_rpe_trans_mps, max_rpe_trans_mps;
  double measured_rpe_rot_degps, max_rpe_rot_degps;
  double measured_ate_m, max_ate_m;
};

struct Case {
  const char* name;
  hq::odometry::ReferenceMode mode;
  bool initialize_with_previous_motion;
  Bounds bounds;
  bool use_depth_term = false;
};

struct SimRun {
  std::vector<hq::recording::StampedPose> trajectory;
  std::vector<hq::recording::StampedPose> ground_truth;  ///< T_N_C, simulator truth.
  int lost = 0;
  std::int64_t dropped_frames = 0;
  bool collided = false;
};

/// Where and how a run flies, and the odometry's options beyond the case's.
struct Flight {
  const char* world = "onboard/sim/worlds/room.yaml";
  std::optional<double> start_yaw_deg;  ///< the world's own when empty
  hq::sim::FlightScript::Kind script = hq::sim::FlightScript::Kind::kCircle;
  bool depth_jacobian_from_normals = false;
  double degenerate_step_ratio = 0.0;
  /// The simulator's gyro between frames as the rotation prior, as the vehicle flies
  /// (config/onboard.yaml: chain.gyro_rotation_prior, gyro_prior_sigma_radps 0.01).
  bool with_gyro = false;
  int moving_mark_radius_px = hq::odometry::OdometryConfig{}.moving_mark_radius_px;
};

constexpr double kGyroPriorSigmaRadps = 0.01;

SimRun fly_and_track(const Case& c, const Flight& flight = {}) {
  hq::sim::World world = hq::sim::load_world(flight.world);
  if (flight.start_yaw_deg) world.start_yaw_rad = *flight.start_yaw_deg * M_PI / 180.0;
  hq::sim::SimConfig config = hq::sim::load_sim_config("onboard/sim/config/sim.yaml");
  const double hfov_rad =
      2.0 * std::atan(0.5 * config.camera.pinhole.width / config.camera.pinhole.fx);
  config.camera.pinhole = hq::sim::pinhole_from_fov(320, 240, hfov_rad);
  config.camera.gray = true;  // DenseOdometry takes CV_8UC1
  config.seed = kSeed;
  hq::sim::Simulator sim(config, world);
  const hq::sim::FlightScript script = hq::sim::script_for_world(world, flight.script);

  hq::odometry::OdometryConfig odometry_config;
  odometry_config.reference_mode = c.mode;
  odometry_config.initialize_with_previous_motion = c.initialize_with_previous_motion;
  odometry_config.use_depth_term = c.use_depth_term;
  odometry_config.depth_jacobian_from_normals = flight.depth_jacobian_from_normals;
  odometry_config.degenerate_step_ratio = flight.degenerate_step_ratio;
  odometry_config.moving_mark_radius_px = flight.moving_mark_radius_px;
  hq::odometry::DenseOdometry odometry(odometry_config, config.camera.pinhole);

  SimRun run;
  cv::Mat gray, depth_m;
  std::vector<hq::sim::ImuSample> imu(256);
  Eigen::Matrix3d R_prev_cur_B = Eigen::Matrix3d::Identity();
  std::int64_t t_last_imu_ns = -1;
  std::int64_t t_last_frame_ns = -1;
  const Eigen::Matrix3d R_B_C = config.camera.T_B_C.linear();
  for (std::int64_t t = 0; t <= kTrackStartNs + kTrackDurationNs;
       t += hq::sim::kScriptControlPeriodNs) {
    sim.set_command(hq::sim::scripted_command(sim, script, static_cast<double>(t) * 1e-9));
    sim.step_to(t);
    const std::size_t n_imu = sim.take_imu(imu.data(), imu.size());
    for (std::size_t i = 0; i < n_imu; ++i) {
      if (t_last_imu_ns >= 0) {
        const double dt_s = 1e-9 * static_cast<double>(imu[i].t_ns - t_last_imu_ns);
        R_prev_cur_B = R_prev_cur_B * hq::geometry::exp_so3(imu[i].omega_B_radps * dt_s);
      }
      t_last_imu_ns = imu[i].t_ns;
    }
    if (!sim.camera_due()) continue;
    const std::int64_t t_frame_ns = sim.camera_t_ns();
    const Eigen::Isometry3d T_N_C = sim.camera_T_N_C();
    sim.render_camera(gray, depth_m);
    hq::odometry::RotationPrior gyro;
    gyro.R_prev_cur = R_B_C.transpose() * R_prev_cur_B * R_B_C;
    const double sigma_rad =
        kGyroPriorSigmaRadps * 1e-9 * static_cast<double>(t_frame_ns - t_last_frame_ns);
    gyro.information = Eigen::Matrix3d::Identity() / (sigma_rad * sigma_rad);
    R_prev_cur_B.setIdentity();
    const bool have_gyro = flight.with_gyro && t_last_frame_ns >= 0;
    t_last_frame_ns = t_frame_ns;
    if (t_frame_ns < kTrackStartNs) continue;
    const auto result = odometry.track(t_frame_ns, gray, depth_m, have_gyro ? &gyro : nullptr);
    if (result.status == hq::odometry::TrackingStatus::kLost) ++run.lost;
    run.ground_truth.push_back({t_frame_ns, T_N_C});
    run.trajectory.push_back({t_frame_ns, result.T_O_C});
  }
  run.dropped_frames = sim.dropped_frames();
  run.collided = sim.collided();
  return run;
}

class OdometryOnSimulatedCircle : public ::testing::TestWithParam<Case> {};

TEST_P(OdometryOnSimulatedCircle, RpeAndAteStayWithinMeasuredBounds) {
  const Case& c = GetParam();
  const auto start = std::chrono::steady_clock::now();
  const SimRun run = fly_and_track(c);
  const double elapsed_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(run.dropped_frames, 0);
  EXPECT_FALSE(run.collided);
  EXPECT_EQ(run.lost, 0);
  const auto rpe = hq::evaluation::relative_pose_error(run.ground_truth, run.trajectory, 1.0);
  const auto ate = hq::evaluation::absolute_trajectory_error(run.ground_truth, run.trajectory);
  EXPECT_FALSE(rpe.delta_clipped);
  const Bounds& b = c.bounds;
  fmt::print(
      "room circle {}, {} frames, {:.1f} s: RPE {:.5f} m/s (measured {:.5f}, bound {:.5f}), {:.4f} "
      "deg/s ({:.4f}, {:.4f}), ATE {:.5f} m ({:.5f}, {:.5f}), {} lost\n",
      c.name, run.trajectory.size(), elapsed_s, rpe.trans_mps.rmse, b.measured_rpe_trans_mps,
      b.max_rpe_trans_mps, rpe.rot_degps.rmse, b.measured_rpe_rot_degps, b.max_rpe_rot_degps,
      ate.trans_m.rmse, b.measured_ate_m, b.max_ate_m, run.lost);
  EXPECT_LT(rpe.trans_mps.rmse, b.max_rpe_trans_mps);
  EXPECT_LT(rpe.rot_degps.rmse, b.max_rpe_rot_degps);
  EXPECT_LT(ate.trans_m.rmse, b.max_ate_m);
}

std::string case_name(const ::testing::TestParamInfo<Case>& info) { return info.param.name; }

// Measured with seed 7 over 241 frames (3 s to 11 s); 0.00113 m/s, 0.0287 deg/s, ATE 0.00075 m
// before the keyframe points seen moving were left out of its later alignments; 0.00076 m/s,
// 0.0223 deg/s, 0.00055 m when they were judged by their residual alone, which also left out
// the sharp edges (the marker field's) that the explore flight needs (docs/odometry.md).
constexpr Bounds kKeyframeBounds{0.00103, 0.0013, 0.0278, 0.035, 0.00081, 0.001};
INSTANTIATE_TEST_SUITE_P(ReferenceModes, OdometryOnSimulatedCircle,
                         // Frame to frame: 0.02397 m/s, 0.9234 deg/s, ATE 0.01639 m before
                         // the robust weights' median scale and the moving pixels left out of
                         // new references, which cost this low-texture circle 15 % and gain
                         // the real fr1/xyz as much (0.0237 -> 0.0195 m/s, docs/odometry.md).
                         ::testing::Values(Case{"frame_to_frame",
                                                hq::odometry::ReferenceMode::kFrameToFrame,
                                                true,
                                                {0.02745, 0.034, 1.0342, 1.29, 0.03085, 0.0386}},
                                           Case{"frame_to_keyframe_no_prediction",
                                                hq::odometry::ReferenceMode::kFrameToKeyframe,
                                                false, kKeyframeBounds}),
                         case_name);

// Frame-to-keyframe with its defaults: DenseOdometry ignores the constant-velocity guess in
// this mode, which once diverged here (RPE 69 m/s, 61.6 deg/s, ATE 8.6 m, 5 lost frames).
INSTANTIATE_TEST_SUITE_P(KeyframeDefaults, OdometryOnSimulatedCircle,
                         ::testing::Values(Case{"frame_to_keyframe",
                                                hq::odometry::ReferenceMode::kFrameToKeyframe, true,
                                                kKeyframeBounds}),
                         case_name);

// With DVO-SLAM's depth residual (Kerl IROS 2013) beside the intensity one; measured with
// seed 7 over the same 241 frames: it cuts the frame-to-frame drift 3x (0.02397 -> 0.00838
// m/s) and the keyframe drift 2x (0.00113 -> 0.00051 m/s).
INSTANTIATE_TEST_SUITE_P(DepthTerm, OdometryOnSimulatedCircle,
                         ::testing::Values(Case{"frame_to_frame_depth",
                                                hq::odometry::ReferenceMode::kFrameToFrame,
                                                true,
                                                {0.00838, 0.0105, 0.3516, 0.44, 0.00751, 0.0094},
                                                true},
                                           Case{
                                               "frame_to_keyframe_depth",
                                               hq::odometry::ReferenceMode::kFrameToKeyframe,
                                               true,
                                               {0.00051, 0.00064, 0.0124, 0.0155, 0.00039, 0.00049},
                                               true}),
                         case_name);

// A hover facing a plain wall and the floor (the textureless world's start corner, heading
// -129 deg; the campaign's depth-term runs that collided began there): the two planes say
// nothing of the motion along their common line, the camera's x. Without remapped steps the
// coarsest level's first step, taken before the robust scales are known, moved the pose 2-4 cm
// along that line per frame while the odometry claimed 0.3 mm (docs/odometry.md, "Depth-term
// options").
TEST(OdometryFacingAPlainWallAndTheFloor, RemappedStepsKeepAHoverStill) {
  const Case c{"plain_wall_hover", hq::odometry::ReferenceMode::kFrameToKeyframe, true, {}, true};
  const auto rpe_mps = [&](double ratio) {
    Flight flight;
    flight.world = "onboard/sim/worlds/structure_notexture.yaml";
    flight.start_yaw_deg = -129.0;
    flight.script = hq::sim::FlightScript::Kind::kHover;
    flight.depth_jacobian_from_normals = true;
    flight.degenerate_step_ratio = ratio;
    const SimRun run = fly_and_track(c, flight);
    EXPECT_FALSE(run.collided);
    const auto rpe = hq::evaluation::relative_pose_error(run.ground_truth, run.trajectory, 1.0);
    fmt::print(
        "plain wall and floor, hover, degenerate_step_ratio {:.3f}: RPE {:.4f} m/s, {} lost\n",
        ratio, rpe.trans_mps.rmse, run.lost);
    return rpe.trans_mps.rmse;
  };
  const double free_steps = rpe_mps(0.0);
  const double remapped = rpe_mps(0.01);
  // Measured (seed 7, 241 frames, 320x240): free 0.1508 m/s, remapped 0.0037.
  EXPECT_GT(free_steps, 0.03);  // the scene still shows what the remapping is for
  EXPECT_LT(remapped, 0.0046);
}

struct WithAndWithoutPeople {
  hq::evaluation::RpeResult alone, people;
};

// The circle flown in the room alone and again with people.yaml's two people walking through
// the camera's view, frame to keyframe; with_gyro as Flight's.
WithAndWithoutPeople fly_with_and_without_people(bool with_gyro, int moving_mark_radius_px = 1) {
  const Case c{"frame_to_keyframe", hq::odometry::ReferenceMode::kFrameToKeyframe, true, {}};
  Flight alone;
  alone.with_gyro = with_gyro;
  alone.moving_mark_radius_px = moving_mark_radius_px;
  Flight with_people = alone;
  with_people.world = "onboard/sim/worlds/people.yaml";
  const SimRun a = fly_and_track(c, alone);
  const SimRun p = fly_and_track(c, with_people);
  EXPECT_FALSE(p.collided);
  EXPECT_EQ(a.lost, 0);
  EXPECT_EQ(p.lost, 0);
  WithAndWithoutPeople out{hq::evaluation::relative_pose_error(a.ground_truth, a.trajectory, 1.0),
                           hq::evaluation::relative_pose_error(p.ground_truth, p.trajectory, 1.0)};
  fmt::print(
      "room circle {}, marks of radius {}: alone RPE {:.5f} m/s {:.4f} deg/s; with people: {:.5f} "
      "m/s {:.4f} deg/s ({:.2f}x, {:.2f}x)\n",
      with_gyro ? "with the gyro" : "odometry alone", moving_mark_radius_px,
      out.alone.trans_mps.rmse, out.alone.rot_degps.rmse, out.people.trans_mps.rmse,
      out.people.rot_degps.rmse, out.people.trans_mps.rmse / out.alone.trans_mps.rmse,
      out.people.rot_degps.rmse / out.alone.rot_degps.rmse);
  return out;
}

// The near person fills up to half the image at 0.7-1.5 m. Odometry alone (no gyro), measured
// (seed 7, 241 frames): alone 0.00103 m/s 0.0278 deg/s; with people 0.00228 m/s 0.0553 deg/s
// (2.2x and 2.0x; the goal is 1.2x). Before: 0.686 m/s, 7.36 deg/s (Kerl's fixed-point scale
// of the robust weights), 0.119 with the median scale, 0.0292 with the depth consistency check
// (at 0.1) too, 0.00664 with moving pixels left out of new keyframes, the rest from leaving the
// keyframe points seen moving out of its later alignments, and aligning again without them
// when they were many (docs/odometry.md, "People in view").
TEST(OdometryWithPeopleWalkingThroughTheView, RpeStaysNearTheSameCircleWithoutThem) {
  const WithAndWithoutPeople rpe = fly_with_and_without_people(false);
  EXPECT_LT(rpe.people.trans_mps.rmse, 0.0029);
  EXPECT_LT(rpe.people.rot_degps.rmse, 0.07);
  EXPECT_LT(rpe.alone.trans_mps.rmse, 0.0013);
}

// The same with the gyro's rotation between frames as the prior, as the vehicle flies. Measured
// (seed 7, 241 frames): alone 0.00078 m/s 0.0211 deg/s; with people 0.00135 m/s 0.0263 deg/s
// (1.7x and 1.2x; the goal is 1.2x; before the keyframe points seen moving were left out:
// 0.00078 / 0.00409 m/s, 0.0198 / 0.0410 deg/s, 5.2x). The first frames aligned to a new
// keyframe that holds the near person are aligned again without the points they saw move; what
// is left is the person's low-contrast pixels, within 4 sigmas (docs/odometry.md).
TEST(OdometryWithPeopleWalkingThroughTheView, WithTheGyroRpeStaysNearTheSameCircleWithoutThem) {
  const WithAndWithoutPeople rpe = fly_with_and_without_people(true);
  EXPECT_LT(rpe.alone.trans_mps.rmse, 0.00098);
  EXPECT_LT(rpe.alone.rot_degps.rmse, 0.027);
  EXPECT_LT(rpe.people.trans_mps.rmse, 0.0017);
  EXPECT_LT(rpe.people.rot_degps.rmse, 0.033);
}

// The same with odometry.moving_mark_radius_px 5, the setting for flights among people: the
// keyframe's points seen moving leave with the pixels around them. Measured (seed 7): alone
// 0.00080 m/s 0.0210 deg/s; with people 0.00098 m/s 0.0244 deg/s (1.2x, 1.2x); over seeds 1-5
// 1.3x and 1.4x against 1.8x and 1.5x with the default (docs/odometry.md, "People in view").
TEST(OdometryWithPeopleWalkingThroughTheView,
     WiderMarksAmongPeopleBringTheRpeNearerTheCircleWithout) {
  const WithAndWithoutPeople rpe = fly_with_and_without_people(true, 5);
  EXPECT_LT(rpe.alone.trans_mps.rmse, 0.0010);
  EXPECT_LT(rpe.people.trans_mps.rmse, 0.00123);
  EXPECT_LT(rpe.people.rot_degps.rmse, 0.0305);
}

}  // namespace
