// OnboardChain on rendered frames: a finite setpoint, nothing allocated after frame 1, safe
// hover without depth or camera, and config errors that name the key.
#include "hq/pipeline/onboard_chain.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/geometry/lie.hpp"
#include "hq/odometry/rendered_plane.hpp"
#include "hq/testing/allocation_counter.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <optional>
#include <string>

namespace hq::pipeline {
namespace {

using ::testing::HasSubstr;

const geometry::PinholeCamera kCamera{260.0, 260.0, 159.5, 119.5, 320, 240};
constexpr double kPlaneZ = 2.0;
constexpr std::int64_t kFramePeriodNs = 33'333'333;  // 30 Hz
constexpr std::int64_t kImuPeriodNs = 5'000'000;     // 200 Hz
constexpr double kSpeedMps = 0.3;                    // along the camera's x axis

/// Each call advances 1 ms, so every stage of one on_frame() lasts exactly 1 ms.
class FakeClock final : public Clock {
 public:
  std::int64_t now_ns() const override { return t_ns_ += 1'000'000; }

 private:
  mutable std::int64_t t_ns_ = 0;
};

Eigen::Isometry3d camera_pose_at(std::int64_t t_ns) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(kSpeedMps * hq::to_seconds(t_ns), 0.0, 0.0);
  return T;
}

/// A level body at rest as far as the IMU can tell: no rotation, specific force -g along z.
void feed_imu(OnboardChain& chain, std::int64_t from_ns, std::int64_t to_ns) {
  for (std::int64_t t = from_ns; t <= to_ns; t += kImuPeriodNs) {
    if (t <= 0) continue;
    chain.on_imu(t, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 0.0, -9.80665));
  }
}

bool setpoint_finite(const ChainOutput& out) {
  const control::AttitudeSetpoint& s = out.mode.control.setpoint;
  return std::isfinite(s.thrust_n) && std::isfinite(s.roll_rad) && std::isfinite(s.pitch_rad) &&
         std::isfinite(s.yaw_rate_radps) && out.mode.v_des_H_mps.allFinite() &&
         out.estimate.v_H_mps.allFinite() && out.obstacles.v_obs_H_mps.allFinite();
}

/// modes.start_landed is true by default (motors idle until a climb request); the tests of
/// the flying chain start airborne.
OnboardConfig airborne_config() {
  OnboardConfig config;
  config.modes.start_landed = false;
  // The rendered plane moves the camera while the IMU stays at rest: no thrust ever shows in
  // the accelerometer, so a hover thrust learnt from it would be nonsense (the gain runs to its
  // bound). Learning is flown in tests/closed_loop, on the simulator's physics.
  config.hover_thrust.enabled = false;
  return config;
}

/// Feeds the level at-rest IMU over (from_ns, to_ns] and ticks the chain at to_ns.
std::optional<ChainOutput> tick_after_imu(OnboardChain& chain, std::int64_t from_ns,
                                          std::int64_t to_ns) {
  feed_imu(chain, from_ns + kImuPeriodNs, to_ns);
  return chain.on_tick(to_ns);
}

class ChainOnRenderedPlane : public ::testing::Test {
 protected:
  explicit ChainOnRenderedPlane(const OnboardConfig& config = airborne_config())
      : chain_(config, VehicleConfig{}, kCamera, &clock_) {}

  /// Frame k at t = k * period; IMU up to its stamp first, as the apps do.
  ChainOutput frame(int k, bool valid_depth = true) {
    const std::int64_t t_ns = (k + 1) * kFramePeriodNs;
    feed_imu(chain_, t_ns - kFramePeriodNs + kImuPeriodNs, t_ns);
    odometry::test::render_textured_plane(kCamera, camera_pose_at(t_ns), kPlaneZ, gray_, depth_);
    if (!valid_depth) depth_.setTo(0.0f);
    return chain_.on_frame(t_ns, gray_, depth_);
  }

  FakeClock clock_;
  OnboardChain chain_;
  cv::Mat gray_, depth_;
};

TEST_F(ChainOnRenderedPlane, GivesFiniteSetpointAndAllocatesNothingAfterFrameOne) {
  // GIVEN a camera gliding at 0.3 m/s over a textured plane, WHEN the chain runs 20 frames,
  // THEN every setpoint is finite, the estimate becomes ok after the warm-up, eq. 1 matches the
  // motion, and frames 2.. allocate nothing (rendering is done before counting).
  ChainOutput out = frame(0);
  EXPECT_TRUE(setpoint_finite(out));
  EXPECT_TRUE(out.safe_hover) << "no velocity on a first frame";
  long allocations = 0;
  int ok = 0;
  for (int k = 1; k < 20; ++k) {
    const std::int64_t t_ns = (k + 1) * kFramePeriodNs;
    feed_imu(chain_, t_ns - kFramePeriodNs + kImuPeriodNs, t_ns - 1);
    odometry::test::render_textured_plane(kCamera, camera_pose_at(t_ns), kPlaneZ, gray_, depth_);
    const long before = testing::allocation_count();
    chain_.on_imu(t_ns, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 0.0, -9.80665));
    out = chain_.on_frame(t_ns, gray_, depth_);
    allocations += testing::allocation_count() - before;
    EXPECT_TRUE(setpoint_finite(out)) << "frame " << k;
    if (out.estimate.ok()) {
      ++ok;
      EXPECT_FALSE(out.safe_hover) << "frame " << k;
      EXPECT_FALSE(out.degraded) << "frame " << k;
      EXPECT_NEAR(out.estimate.v_C_raw_mps.x(), kSpeedMps, 0.03) << "frame " << k;
      EXPECT_NEAR(out.estimate.v_C_raw_mps.y(), 0.0, 0.03) << "frame " << k;
      EXPECT_NEAR(out.estimate.v_C_raw_mps.z(), 0.0, 0.03) << "frame " << k;
    }
  }
  EXPECT_EQ(allocations, 0);
  // Warm-up 0.2 s is 6 frames at 30 Hz, so at least 12 of the 19 must be ok.
  EXPECT_GE(ok, 12);
  // The fake clock ticks 1 ms per reading: five stages of 1 ms each.
  EXPECT_EQ(out.durations.odometry_ns, 1'000'000);
  EXPECT_EQ(out.durations.control_ns, 1'000'000);
  EXPECT_EQ(out.durations.memory_ns, 1'000'000);
  EXPECT_EQ(out.durations.total_ns, 5'000'000);
}

TEST_F(ChainOnRenderedPlane, AllInvalidDepthCoastsOnTheImuThenSafeHover) {
  // GIVEN a tracking chain, WHEN depth goes all-invalid, THEN the estimate coasts on the IMU
  // (kInertial, degraded, the velocity loop still closed) for the coast's horizon after the
  // last ok estimate (inertial_coast_s, shortened because a few frames have checked little of
  // the accelerometer), and only after that is the setpoint the level m g safe hover.
  // Nothing is NaN and the lost path allocates nothing.
  std::int64_t t_last_ok_ns = -1;
  for (int k = 0; k < 12; ++k) {
    if (frame(k).estimate.ok()) t_last_ok_ns = (k + 1) * kFramePeriodNs;
  }
  // The odometry takes depth from its reference (a keyframe), so depthless frames still track
  // on it until a new reference is due, which has no depth; from then on nothing can.
  int first_lost = 12;
  const int max_keyframe_age = chain_.config().odometry.max_keyframe_age;
  for (; first_lost <= 12 + max_keyframe_age; ++first_lost) {
    const ChainOutput depthless = frame(first_lost, false);
    EXPECT_TRUE(setpoint_finite(depthless));
    if (depthless.tracking != odometry::TrackingStatus::kOk) break;
    if (depthless.estimate.ok()) t_last_ok_ns = (first_lost + 1) * kFramePeriodNs;
  }
  ASSERT_LE(first_lost, 12 + max_keyframe_age) << "the odometry never stopped tracking";
  ASSERT_GT(t_last_ok_ns, 0);
  const double coast_s = chain_.estimator().coast_horizon_s();
  // (at most inertial_coast_s: the fused filter has learnt the rendered plane's unseen
  // acceleration well enough over these frames to reach it)
  EXPECT_GT(coast_s, 0.9);
  EXPECT_LE(coast_s, chain_.config().estimator.inertial_coast_s);
  long allocations = 0;
  int coasting = 0;
  int hovering = 0;
  for (int k = first_lost + 1; k < first_lost + 1 + static_cast<int>((coast_s + 0.5) * 30.0); ++k) {
    const std::int64_t t_ns = (k + 1) * kFramePeriodNs;
    feed_imu(chain_, t_ns - kFramePeriodNs + kImuPeriodNs, t_ns);
    depth_.setTo(0.0f);
    const long before = testing::allocation_count();
    const ChainOutput out = chain_.on_frame(t_ns, gray_, depth_);
    allocations += testing::allocation_count() - before;
    const double since_ok_s = hq::to_seconds(t_ns - t_last_ok_ns);
    EXPECT_EQ(out.tracking, odometry::TrackingStatus::kLost) << "frame " << k;
    EXPECT_FALSE(out.estimate.ok()) << "frame " << k;
    EXPECT_STRNE(out.estimate.reason, "");
    EXPECT_TRUE(out.degraded) << "frame " << k;
    EXPECT_TRUE(setpoint_finite(out)) << "frame " << k;
    if (since_ok_s <= coast_s) {
      EXPECT_EQ(out.estimate.status, estimator::EstimateStatus::kInertial) << "frame " << k;
      EXPECT_FALSE(out.safe_hover) << "frame " << k;
      EXPECT_TRUE(out.estimate.v_H_mps.allFinite());
      ++coasting;
    } else {
      EXPECT_EQ(out.estimate.status, estimator::EstimateStatus::kUnavailable) << "frame " << k;
      EXPECT_TRUE(out.safe_hover) << "frame " << k;
      EXPECT_STRNE(out.safe_hover_reason, "");
      EXPECT_DOUBLE_EQ(out.mode.control.setpoint.thrust_n, 1.0 * control::kGravityMps2);
      EXPECT_EQ(out.mode.control.setpoint.roll_rad, 0.0);
      EXPECT_EQ(out.mode.control.setpoint.pitch_rad, 0.0);
      EXPECT_EQ(out.mode.control.setpoint.yaw_rate_radps, 0.0);
      ++hovering;
    }
  }
  EXPECT_GE(coasting, static_cast<int>(coast_s * 30.0) - 2);
  EXPECT_GE(hovering, 10);
  EXPECT_EQ(allocations, 0) << "the lost path allocates nothing either";
}

TEST_F(ChainOnRenderedPlane, CameraSilenceCoastsOnTheImuThenCommandsSafeHover) {
  ChainOutput last;
  for (int k = 0; k < 12; ++k) last = frame(k);
  const std::int64_t t_last_ns = 12 * kFramePeriodNs;
  ASSERT_TRUE(last.estimate.ok()) << last.estimate.reason;
  // Within the 0.3 s timeout the last frame's setpoint stands.
  EXPECT_FALSE(tick_after_imu(chain_, t_last_ns, t_last_ns + 200'000'000).has_value());
  // After it, with the IMU still running: the inertial coast (degraded), not yet the hover.
  feed_imu(chain_, t_last_ns + 200'000'000 + kImuPeriodNs, t_last_ns + 400'000'000);
  const long before = testing::allocation_count();
  const auto coasting = chain_.on_tick(t_last_ns + 400'000'000);
  EXPECT_EQ(testing::allocation_count() - before, 0);
  ASSERT_TRUE(coasting.has_value());
  EXPECT_TRUE(coasting->camera_timed_out);
  EXPECT_TRUE(coasting->degraded);
  EXPECT_EQ(coasting->estimate.status, estimator::EstimateStatus::kInertial);
  EXPECT_STREQ(coasting->estimate.reason, "camera timed out");
  EXPECT_FALSE(coasting->safe_hover);
  EXPECT_TRUE(setpoint_finite(*coasting));
  // THEN once estimator.inertial_coast_s has passed since the last ok estimate: safe hover.
  const std::int64_t t_expired_ns =
      t_last_ns +
      static_cast<std::int64_t>((chain_.config().estimator.inertial_coast_s + 0.1) * 1e9);
  const auto out = tick_after_imu(chain_, t_last_ns + 400'000'000, t_expired_ns);
  ASSERT_TRUE(out.has_value());
  EXPECT_TRUE(out->camera_timed_out);
  EXPECT_TRUE(out->degraded);
  EXPECT_EQ(out->estimate.status, estimator::EstimateStatus::kUnavailable);
  EXPECT_TRUE(out->safe_hover);
  EXPECT_THAT(out->safe_hover_reason, HasSubstr("camera timed out"));
  EXPECT_TRUE(setpoint_finite(*out));
  EXPECT_DOUBLE_EQ(out->mode.control.setpoint.thrust_n, 1.0 * control::kGravityMps2);
  EXPECT_EQ(out->mode.control.setpoint.roll_rad, 0.0);
}

class LandedChainOnRenderedPlane : public ChainOnRenderedPlane {
 protected:
  LandedChainOnRenderedPlane() : ChainOnRenderedPlane(OnboardConfig{}) {}
};

TEST_F(LandedChainOnRenderedPlane, StartsLandedWithMotorsIdleAndTakesOffOnAClimbCommand) {
  ASSERT_TRUE(OnboardConfig{}.modes.start_landed);
  // GIVEN the default configuration: on the ground. Frames (even the first, with no velocity)
  // give thrust 0, no safe hover (nothing to hold in the air), the mode controller landed.
  for (int k = 0; k < 10; ++k) {
    const ChainOutput out = frame(k);
    EXPECT_TRUE(out.mode.landed) << "frame " << k;
    EXPECT_EQ(out.mode.control.setpoint.thrust_n, 0.0) << "frame " << k;
    EXPECT_FALSE(out.safe_hover) << "frame " << k;
    EXPECT_TRUE(setpoint_finite(out)) << "frame " << k;
  }
  // ... also in teleop with a horizontal command only.
  ASSERT_TRUE(chain_.request_mode(modes::Mode::kTeleop, modes::RequestOrigin::kOperator).accepted);
  chain_.set_operator_command({11 * kFramePeriodNs, Eigen::Vector3d(0.3, 0.0, 0.0), 0.0});
  ChainOutput out = frame(10);
  EXPECT_TRUE(out.mode.landed);
  EXPECT_EQ(out.mode.control.setpoint.thrust_n, 0.0);
  // WHEN the operator asks to climb at 0.5 m/s (NED -z)
  chain_.set_operator_command({12 * kFramePeriodNs, Eigen::Vector3d(0.0, 0.0, -0.5), 0.0});
  out = frame(11);
  // THEN the motors start: about m g (plus the climb term of the PID), not landed.
  EXPECT_FALSE(out.mode.landed);
  EXPECT_GT(out.mode.control.setpoint.thrust_n, 0.9 * control::kGravityMps2);
  EXPECT_LT(out.mode.control.setpoint.thrust_n, 1.5 * control::kGravityMps2);
  EXPECT_TRUE(setpoint_finite(out));
}

TEST_F(ChainOnRenderedPlane, OperatorCommandIsLimitedToTheSeenSpace) {
  // GIVEN the default camera (looking straight down at the plane 2 m below): it proves no
  // horizontal free space beyond a few cm around the vehicle.
  for (int k = 0; k < 12; ++k) frame(k);
  // WHEN the operator asks for 1 m/s sideways and a climb
  chain_.set_operator_command({12 * kFramePeriodNs, Eigen::Vector3d(0.0, 1.0, -0.2), 0.0});
  const ChainOutput out = frame(12);
  // THEN the horizontal part is cut to the creep speed (0), the climb passes, and the chain
  // says so with the per-bin limits.
  EXPECT_TRUE(out.command_limited);
  EXPECT_NEAR(out.v_cmd_flown_H_mps.head<2>().norm(), 0.0, 1e-9);
  EXPECT_DOUBLE_EQ(out.v_cmd_flown_H_mps.z(), -0.2);
  EXPECT_EQ(out.seen_space_bins, 72);
  EXPECT_TRUE(out.seen_space.updated);
  for (int b = 0; b < out.seen_space_bins; ++b) {
    EXPECT_EQ(out.seen_space_limits_mps[static_cast<std::size_t>(b)], 0.0f);
  }
  // The mode controller got the limited command: v*_des has no horizontal part.
  EXPECT_NEAR(out.mode.v_star_des_H_mps.head<2>().norm(), 0.0, 1e-9);
}

class UnlimitedChainOnRenderedPlane : public ChainOnRenderedPlane {
 protected:
  UnlimitedChainOnRenderedPlane() : ChainOnRenderedPlane(unlimited()) {}
  static OnboardConfig unlimited() {
    OnboardConfig config = airborne_config();
    config.seen_space.enabled = false;
    return config;
  }
};

TEST_F(UnlimitedChainOnRenderedPlane, DisabledLimiterPassesTheCommand) {
  for (int k = 0; k < 12; ++k) frame(k);
  chain_.set_operator_command({12 * kFramePeriodNs, Eigen::Vector3d(0.0, 1.0, -0.2), 0.0});
  const ChainOutput out = frame(12);
  EXPECT_FALSE(out.command_limited);
  EXPECT_DOUBLE_EQ(out.v_cmd_flown_H_mps.y(), 1.0);
}

TEST(OnboardChainCoast, OperatorsHorizontalCommandIsHeldOnTheCoastClimbIsFlown) {
  for (const bool hold : {true, false}) {
    // GIVEN a chain without the seen-space limit (nothing else cuts the command) that tracked,
    // then lost its odometry (depth all invalid): the inertial coast
    OnboardConfig config = airborne_config();
    config.seen_space.enabled = false;
    config.chain.hold_on_inertial_coast = hold;
    FakeClock clock;
    OnboardChain chain(config, VehicleConfig{}, kCamera, &clock);
    cv::Mat gray, depth;
    ChainOutput out;
    int k = 0;
    for (; k < 60; ++k) {
      const std::int64_t t_ns = (k + 1) * kFramePeriodNs;
      feed_imu(chain, t_ns - kFramePeriodNs + kImuPeriodNs, t_ns);
      odometry::test::render_textured_plane(kCamera, camera_pose_at(t_ns), kPlaneZ, gray, depth);
      if (k >= 12) depth.setTo(0.0f);
      out = chain.on_frame(t_ns, gray, depth);
      if (k >= 12 && out.estimate.status == estimator::EstimateStatus::kInertial) break;
    }
    ASSERT_EQ(out.estimate.status, estimator::EstimateStatus::kInertial) << "never coasted";
    // WHEN the operator asks for 1 m/s sideways and a climb
    ++k;
    const std::int64_t t_ns = (k + 1) * kFramePeriodNs;
    chain.set_operator_command({t_ns, Eigen::Vector3d(0.0, 1.0, -0.2), 0.0});
    feed_imu(chain, t_ns - kFramePeriodNs + kImuPeriodNs, t_ns);
    out = chain.on_frame(t_ns, gray, depth);
    ASSERT_EQ(out.estimate.status, estimator::EstimateStatus::kInertial);
    // THEN (hold_on_inertial_coast) the vehicle brakes to a hold and says the command is cut;
    // the climb is flown. Without the hold, the command is flown blind.
    EXPECT_EQ(out.command_limited, hold);
    EXPECT_DOUBLE_EQ(out.v_cmd_flown_H_mps.y(), hold ? 0.0 : 1.0);
    EXPECT_DOUBLE_EQ(out.v_cmd_flown_H_mps.z(), -0.2);
    if (hold) {
      EXPECT_NEAR(out.mode.v_star_des_H_mps.head<2>().norm(), 0.0, 1e-9);
    }
  }
}

TEST(OnboardChainDepthExposure, DepthTakenBeforeTheColourIsTurnedToItWithTheGyro) {
  // GIVEN a camera panning at 30 deg/s (a yaw) while gliding at 0.3 m/s over the plane, whose
  // depth maps lead their colour images by 3 and 8 ms in turn (Kinect v1 in TUM fr1_360:
  // 3.7-7.7 ms), the depth term on, and the gyro
  const Eigen::Vector3d omega_C_radps(0.0, 30.0 * M_PI / 180.0, 0.0);
  const auto pose_at = [&](std::int64_t t_ns) {
    Eigen::Isometry3d T = camera_pose_at(t_ns);
    T.linear() = geometry::exp_so3(omega_C_radps * hq::to_seconds(t_ns));
    return T;
  };
  const VehicleConfig vehicle;
  const Eigen::Vector3d omega_B_radps = vehicle.camera.R_B_C() * omega_C_radps;
  double rms_error_mps[2] = {0.0, 0.0};
  // (and a depth stamp 1 s off, a wrong stamp rather than a camera's gap, is not used)
  double wrong_stamp_rms_mps = 0.0;
  for (const int variant : {0, 1, 2}) {
    const bool with_depth_stamp = variant == 1;
    OnboardConfig config = airborne_config();
    config.odometry.use_depth_term = true;
    // eq. 1's velocity is what is measured here: without the depth stamp it is 0.15 m/s off,
    // which the estimator's IMU gate rightly refuses to fly on.
    config.estimator.velocity_gate_chi2 = 1e6;
    OnboardChain chain(config, vehicle, kCamera);
    cv::Mat gray, depth, unused_gray;
    double sum_sq = 0.0;
    int ok = 0;
    for (int k = 0; k < 16; ++k) {
      const std::int64_t t_ns = (k + 1) * kFramePeriodNs;
      for (std::int64_t t = t_ns - kFramePeriodNs + kImuPeriodNs; t <= t_ns; t += kImuPeriodNs) {
        chain.on_imu(t, omega_B_radps, Eigen::Vector3d(0.0, 0.0, -9.80665));
      }
      const std::int64_t depth_t_ns = t_ns - (k % 2 == 0 ? 3'000'000 : 8'000'000);
      odometry::test::render_textured_plane(kCamera, pose_at(t_ns), kPlaneZ, gray, unused_gray);
      odometry::test::render_textured_plane(kCamera, pose_at(depth_t_ns), kPlaneZ, unused_gray,
                                            depth);
      // WHEN the chain is told the depth's own stamp, and when it is not
      const ChainOutput out = with_depth_stamp ? chain.on_frame(t_ns, depth_t_ns, gray, depth)
                              : variant == 2
                                  ? chain.on_frame(t_ns, t_ns - 1'000'000'000, gray, depth)
                                  : chain.on_frame(t_ns, gray, depth);
      if (!out.estimate.ok()) continue;
      const Eigen::Vector3d v_C_true =
          pose_at(t_ns).linear().transpose() * Eigen::Vector3d(kSpeedMps, 0.0, 0.0);
      sum_sq += (out.estimate.v_C_raw_mps - v_C_true).squaredNorm();
      ++ok;
    }
    ASSERT_GE(ok, 8) << "variant " << variant;
    (variant == 2 ? wrong_stamp_rms_mps : rms_error_mps[variant]) = std::sqrt(sum_sq / ok);
  }
  fmt::print("camera velocity RMS error: {:.4f} m/s without the depth stamp, {:.4f} with\n",
             rms_error_mps[0], rms_error_mps[1]);
  // THEN with it, eq. 1's velocity is the motion's; without, each frame's 5 ms of pan between
  // the two leads (0.15 deg) shows in it
  EXPECT_LT(rms_error_mps[1], 0.01);
  EXPECT_GT(rms_error_mps[0], 10.0 * rms_error_mps[1]);
  EXPECT_DOUBLE_EQ(wrong_stamp_rms_mps, rms_error_mps[0]);
}

TEST(OnboardChainTimeout, SafeHoverWithoutEstimateLandsOnEvidenceOfTheFloorOnly) {
  // Airborne, no frame ever: the safe hover; after chain.safe_hover_land_s of it the chain
  // lands (blind descent) and refuses to go back to teleop while there is no estimate. The
  // descent ends landed (motors idle) only once the accelerometer has felt the floor: an
  // impact, then the floor carrying the vehicle; never from the estimate's loss alone (issue
  // 39: idled at 11.8 m).
  OnboardConfig config = airborne_config();
  config.chain.safe_hover_land_s = 2.0;
  OnboardChain chain(config, VehicleConfig{}, kCamera);
  chain.request_mode(modes::Mode::kTeleop, modes::RequestOrigin::kOperator);
  const std::int64_t tick_ns = 5'000'000;
  const std::int64_t t_impact_ns = 9'000'000'000;  // after the blind_descent_s of 3 s
  std::int64_t t_first_hover_ns = -1;
  std::int64_t t_land_ns = -1;
  std::int64_t t_landed_ns = -1;
  // Specific force (body FRD, level): the thrust over the mass in the air (the vehicle obeys
  // the setpoint), the floor's stop, then at rest on it; and the vertical speed it gives.
  const double mass_kg = VehicleConfig{}.mass_kg;
  double thrust_n = mass_kg * control::kGravityMps2;
  double v_down_mps = 0.0;
  double v_down_at_impact_mps = 0.0;
  for (std::int64_t t = tick_ns; t <= 12'000'000'000; t += tick_ns) {
    const double f_up = t < t_impact_ns    ? thrust_n / mass_kg
                        : t == t_impact_ns ? 40.0
                                           : control::kGravityMps2;
    if (t < t_impact_ns) v_down_mps += (control::kGravityMps2 - f_up) * 1e-9 * tick_ns;
    if (t == t_impact_ns) v_down_at_impact_mps = v_down_mps;
    chain.on_imu(t, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 0.0, -f_up));
    const auto out = chain.on_tick(t);
    if (!out) continue;
    thrust_n = out->mode.control.setpoint.thrust_n;
    if (out->safe_hover && t_first_hover_ns < 0) t_first_hover_ns = t;
    if (out->safe_hover_landing) t_land_ns = t;
    if (out->mode.landed && t_landed_ns < 0) {
      t_landed_ns = t;
      EXPECT_EQ(out->mode.control.setpoint.thrust_n, 0.0);
    }
    if (t_land_ns > 0 && t > t_land_ns && t_landed_ns < 0) {  // from the step after the request
      EXPECT_TRUE(out->mode.blind_descent);
      EXPECT_TRUE(out->mode.blind_descent_rate_held);  // on the IMU the chain feeds it
      EXPECT_EQ(out->mode.control.setpoint.roll_rad, 0.0);
    }
    if (t_land_ns > 0 && t == t_land_ns + 1'000'000'000) {
      // Descending blind: no going back to teleop while there is no estimate.
      const modes::ModeSwitch back =
          chain.request_mode(modes::Mode::kTeleop, modes::RequestOrigin::kOperator);
      EXPECT_FALSE(back.accepted);
      EXPECT_THAT(back.reason, HasSubstr("landing"));
    }
  }
  ASSERT_GT(t_first_hover_ns, 0);
  ASSERT_GT(t_land_ns, 0) << "the safe hover never escalated";
  EXPECT_NEAR(hq::to_seconds(t_land_ns - t_first_hover_ns), 2.0, 0.01);
  EXPECT_EQ(chain.mode(), modes::Mode::kLand);
  ASSERT_GT(t_landed_ns, 0) << "the blind descent never ended landed";
  EXPECT_GE(t_landed_ns, t_impact_ns) << "landed before the floor was felt";
  EXPECT_NEAR(hq::to_seconds(t_landed_ns - t_impact_ns), config.modes.touchdown_s, 0.02);
  // It sank at the blind descent's speed, not ever faster.
  EXPECT_NEAR(v_down_at_impact_mps, config.modes.blind_descent_speed_mps, 0.05);
}

TEST(OnboardChainTimeout, NoFrameEverAlsoTimesOut) {
  // Airborne, no frame ever and no IMU: nothing to coast on, the safe hover.
  OnboardChain airborne(airborne_config(), VehicleConfig{}, kCamera);
  EXPECT_FALSE(airborne.on_tick(1'000'000'000).has_value());
  const auto out = airborne.on_tick(1'400'000'000);
  ASSERT_TRUE(out.has_value());
  EXPECT_TRUE(out->camera_timed_out);
  EXPECT_TRUE(out->safe_hover);
  EXPECT_DOUBLE_EQ(out->mode.control.setpoint.thrust_n, 1.0 * control::kGravityMps2);
  // On the ground (the default) the same silence keeps the motors idle: no safe hover.
  OnboardChain landed(OnboardConfig{}, VehicleConfig{}, kCamera);
  EXPECT_FALSE(landed.on_tick(1'000'000'000).has_value());
  const auto on_ground = landed.on_tick(1'400'000'000);
  ASSERT_TRUE(on_ground.has_value());
  EXPECT_TRUE(on_ground->camera_timed_out);
  EXPECT_TRUE(on_ground->mode.landed);
  EXPECT_FALSE(on_ground->safe_hover);
  EXPECT_EQ(on_ground->mode.control.setpoint.thrust_n, 0.0);
}

TEST(OnboardChainModeRequests, OperatorsWaitTheDwellTheVehiclesOwnLandDoesNot) {
  // GIVEN an airborne chain that an operator put in teleop, stepped (on the safe hover) since
  OnboardChain chain(airborne_config(), VehicleConfig{}, kCamera);
  ASSERT_TRUE(chain.request_mode(modes::Mode::kTeleop, modes::RequestOrigin::kOperator).accepted);
  chain.on_tick(1'000'000'000);
  ASSERT_TRUE(chain.on_tick(1'400'000'000).has_value());
  // THEN an operator's change within modes.min_mode_dwell_s is refused, saying why
  const modes::ModeSwitch refused =
      chain.request_mode(ModeRequest{modes::Mode::kHover, std::nullopt});
  EXPECT_FALSE(refused.accepted);
  EXPECT_THAT(refused.reason, HasSubstr("minimum dwell in teleop 1.5 s, 1.4 s so far"));
  // ... AND the link failsafe's land, on the operator's path but the vehicle's own, is not
  const ModeRequest failsafe_land{modes::Mode::kLand, std::nullopt, false,
                                  modes::RequestOrigin::kVehicle};
  EXPECT_TRUE(chain.request_mode(failsafe_land).accepted);
  EXPECT_EQ(chain.mode(), modes::Mode::kLand);
}

std::string write_temp_yaml(const std::string& name, const std::string& text) {
  const std::string path =
      (std::filesystem::temp_directory_path() / ("hq_pipeline_test_" + name + ".yaml")).string();
  std::ofstream(path) << text;
  return path;
}

std::string load_error(const std::string& path) {
  try {
    load_onboard_config(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(LoadOnboardConfig, ReadsTheDefaultFileIntoEveryComponent) {
  const OnboardConfig config = load_onboard_config("config/onboard.yaml");
  EXPECT_TRUE(config.seen_space.enabled);
  EXPECT_EQ(config.seen_space.bins, 72);
  EXPECT_DOUBLE_EQ(config.chain.safe_hover_land_s, 5.0);
  // influence_distance_m is now the clearance to the vehicle's sphere (1.0 m in the file).
  EXPECT_DOUBLE_EQ(config.obstacles.influence_distance_m, 1.0);
  EXPECT_DOUBLE_EQ(config.obstacles.vehicle_radius_m, 0.35);
  EXPECT_DOUBLE_EQ(config.obstacles.max_repulsive_speed_mps, 1.5);
  EXPECT_DOUBLE_EQ(config.obstacles.support_influence_m, 0.3);
  EXPECT_DOUBLE_EQ(config.estimator.one_euro_position.beta, 2.0);
  EXPECT_DOUBLE_EQ(config.estimator.inertial_coast_s, 2.0);
  EXPECT_DOUBLE_EQ(config.estimator.velocity_gate_chi2, 16.27);
  EXPECT_EQ(config.estimator.velocity_output,
            estimator::VelocityEstimatorConfig::VelocityOutput::kFused);
  EXPECT_EQ(config.estimator.reacquire_frames, 2);
  EXPECT_DOUBLE_EQ(config.control.kp_xy_per_s, 3.0);
  EXPECT_DOUBLE_EQ(config.modes.teleop_timeout_s, 0.5);
  EXPECT_TRUE(config.modes.start_landed);
  EXPECT_DOUBLE_EQ(config.modes.blind_descent_thrust_ratio, 0.9);
  EXPECT_DOUBLE_EQ(config.chain.takeoff_height_m, 0.5);
}

TEST(LoadOnboardConfig, OdometryAndChainSectionsReachTheirComponents) {
  const std::string path = write_temp_yaml(
      "sections",
      "odometry: {pyramid_levels: 3, use_depth_term: true}\n"
      "chain: {camera_timeout_s: 0.7, gyro_rotation_prior: true, gyro_prior_sigma_radps: 0.02,"
      " hold_on_inertial_coast: false, depth_colour_max_offset_s: 0.03}\n");
  const OnboardConfig config = load_onboard_config(path);
  EXPECT_EQ(config.odometry.pyramid_levels, 3);
  EXPECT_TRUE(config.odometry.use_depth_term);
  EXPECT_DOUBLE_EQ(config.chain.camera_timeout_s, 0.7);
  EXPECT_TRUE(config.chain.gyro_rotation_prior);
  EXPECT_DOUBLE_EQ(config.chain.gyro_prior_sigma_radps, 0.02);
  EXPECT_FALSE(config.chain.hold_on_inertial_coast);
  EXPECT_DOUBLE_EQ(config.chain.depth_colour_max_offset_s, 0.03);
}

TEST(LoadOnboardConfig, ErrorsNameFileAndKey) {
  const std::string bad_range =
      write_temp_yaml("range", "obstacles: {influence_distance_m: -1.2}\n");
  EXPECT_THAT(load_error(bad_range), HasSubstr(bad_range + ": obstacles.influence_distance_m"));
  EXPECT_THAT(load_error(write_temp_yaml("section", "estimater: {warmup_s: 0.1}\n")),
              HasSubstr("estimater is not a known key"));
  EXPECT_THAT(load_error(write_temp_yaml("odometry", "odometry: {pyramid_levelz: 3}\n")),
              HasSubstr("odometry.pyramid_levelz"));
  EXPECT_THAT(load_error(write_temp_yaml("chain", "chain: {camera_timeout_s: 0}\n")),
              HasSubstr("chain.camera_timeout_s"));
  EXPECT_THAT(load_error(write_temp_yaml("takeoff", "chain: {takeoff_height_m: -0.5}\n")),
              HasSubstr("chain.takeoff_height_m = -0.5, expected in [0, 10]"));
  EXPECT_THAT(load_error(write_temp_yaml("gyro", "chain: {gyro_prior_sigma_radps: 0}\n")),
              HasSubstr("chain.gyro_prior_sigma_radps"));
  EXPECT_THAT(load_error(write_temp_yaml("lead", "chain: {depth_colour_max_offset_s: -0.01}\n")),
              HasSubstr("chain.depth_colour_max_offset_s = -0.01"));
  EXPECT_THAT(load_error(write_temp_yaml("nested", "estimator: {complementary: {k_q: 1}}\n")),
              HasSubstr("estimator.complementary.k_q"));
  EXPECT_THAT(load_error("no/such/onboard.yaml"), HasSubstr("no/such/onboard.yaml"));
}

}  // namespace
}  // namespace hq::pipeline
