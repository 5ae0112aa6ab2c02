#include "hq/seen_space/seen_space_limiter.hpp"

#include "hq/config/strict_yaml.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"

#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <limits>

namespace hq::seen_space {
namespace {

using ::testing::HasSubstr;
constexpr double kRadius = 0.35;
constexpr std::int64_t kSecond = 1'000'000'000;

geometry::PinholeCamera test_camera() {
  geometry::PinholeCamera camera;  // 320x240, 58 deg horizontal field of view like the sim
  camera.width = 320;
  camera.height = 240;
  camera.fx = 160.0 / std::tan(29.0 * M_PI / 180.0);
  camera.fy = camera.fx;
  camera.cx = 159.5;
  camera.cy = 119.5;
  return camera;
}

/// A level, forward-looking camera at the body origin: optical z = body x, x = y, y = z.
Eigen::Matrix3d R_B_C() {
  Eigen::Matrix3d R;
  R.col(0) = Eigen::Vector3d::UnitY();
  R.col(1) = Eigen::Vector3d::UnitZ();
  R.col(2) = Eigen::Vector3d::UnitX();
  return R;
}

/// Camera pose for a body at p_W (W = NED-like, z down) with yaw psi (clockwise).
Eigen::Isometry3d camera_pose(double yaw_rad,
                              const Eigen::Vector3d& p_W = Eigen::Vector3d::Zero()) {
  Eigen::Isometry3d T_W_Q = Eigen::Isometry3d::Identity();
  T_W_Q.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T_W_Q.translation() = p_W;
  Eigen::Isometry3d T_Q_C = Eigen::Isometry3d::Identity();
  T_Q_C.linear() = R_B_C();
  return T_W_Q * T_Q_C;
}

/// A wall facing the camera at distance_m: constant depth.
cv::Mat wall(double distance_m) {
  return cv::Mat(240, 320, CV_32FC1, cv::Scalar(static_cast<float>(distance_m)));
}

class SeenSpaceTest : public ::testing::Test {
 protected:
  SeenSpaceTest() : limiter_(config_, test_camera(), R_B_C(), Eigen::Vector3d::Zero(), kRadius) {}
  SeenSpaceConfig config_;
  SeenSpaceLimiter limiter_;
  const Eigen::Matrix3d level_ = Eigen::Matrix3d::Identity();
};

TEST_F(SeenSpaceTest, BrakingModelStopsWithinTheFreeDistance) {
  for (double d : {0.6, 1.0, 2.0, 4.0}) {
    const double v = limiter_.max_speed_mps(d);
    const double stop_m = v * config_.reaction_s + v * v / (2.0 * config_.brake_accel_mps2);
    EXPECT_NEAR(stop_m, d - kRadius - config_.margin_m, 1e-9) << d;
  }
  EXPECT_EQ(limiter_.max_speed_mps(kRadius + config_.margin_m - 0.01), 0.0);
}

TEST_F(SeenSpaceTest, WallAheadLimitsForwardToTheBrakingSpeedAndUnseenBackToCreep) {
  const Eigen::Isometry3d T = camera_pose(0.0);
  const SeenSpaceUpdate u = limiter_.update(0, wall(2.0), &T, level_);
  ASSERT_TRUE(u.updated) << u.reason;
  EXPECT_GE(u.covered_bins, 10);  // 58 deg of 5 deg bins
  EXPECT_LE(u.covered_bins, 14);
  EXPECT_NEAR(limiter_.free_distance_m(limiter_.bin_of_heading_azimuth(0.01)), 2.0, 0.02);

  const LimitedCommand forward = limiter_.limit(Eigen::Vector3d(2.0, 0.0, 0.3));
  EXPECT_TRUE(forward.limited);
  EXPECT_FALSE(forward.unseen);
  EXPECT_NEAR(forward.v_H_mps.x(), limiter_.max_speed_mps(2.0), 0.05);
  EXPECT_LT(forward.v_H_mps.x(), 1.8);  // below the 2 m/s asked
  EXPECT_DOUBLE_EQ(forward.v_H_mps.z(), 0.3) << "vertical passes";

  const LimitedCommand slow = limiter_.limit(Eigen::Vector3d(0.3, 0.0, 0.0));
  EXPECT_FALSE(slow.limited);
  EXPECT_DOUBLE_EQ(slow.v_H_mps.x(), 0.3);

  const LimitedCommand back = limiter_.limit(Eigen::Vector3d(-1.0, 0.0, 0.0));
  EXPECT_TRUE(back.limited);
  EXPECT_TRUE(back.unseen);
  EXPECT_DOUBLE_EQ(back.v_H_mps.head<2>().norm(), config_.creep_speed_mps);

  // 45 deg off the camera axis, outside its +-29 deg: unseen.
  const LimitedCommand diagonal = limiter_.limit(Eigen::Vector3d(0.7, 0.7, 0.0));
  EXPECT_TRUE(diagonal.unseen);
  EXPECT_LT(diagonal.v_H_mps.head<2>().norm(), 1e-9);
}

TEST_F(SeenSpaceTest, AVehicleFasterThanItsCommandGetsALowerCommand) {
  const Eigen::Isometry3d T = camera_pose(0.0);
  limiter_.update(0, wall(2.0), &T, level_);
  const double plain = limiter_.limit(Eigen::Vector3d(2.0, 0.0, 0.0)).v_H_mps.x();
  const double slow =
      limiter_.limit(Eigen::Vector3d(2.0, 0.0, 0.0), Eigen::Vector3d(0.2, 0.0, 0.0)).v_H_mps.x();
  const double fast =
      limiter_.limit(Eigen::Vector3d(2.0, 0.0, 0.0), Eigen::Vector3d(1.8, 0.0, 0.0)).v_H_mps.x();
  EXPECT_GT(slow, fast);
  EXPECT_NEAR(fast,
              std::sqrt(2.0 * config_.brake_accel_mps2 *
                        (2.0 - kRadius - config_.margin_m - 1.8 * config_.reaction_s)),
              0.05);
  // Moving away from the wall: no reaction distance towards it.
  const double away =
      limiter_.limit(Eigen::Vector3d(2.0, 0.0, 0.0), Eigen::Vector3d(-0.5, 0.0, 0.0)).v_H_mps.x();
  EXPECT_GT(away, plain);
}

TEST_F(SeenSpaceTest, CreepSpeedIsConfigurable) {
  SeenSpaceConfig config = config_;
  config.creep_speed_mps = 0.15;
  SeenSpaceLimiter limiter(config, test_camera(), R_B_C(), Eigen::Vector3d::Zero(), kRadius);
  const Eigen::Isometry3d T = camera_pose(0.0);
  limiter.update(0, wall(2.0), &T, level_);
  const LimitedCommand back = limiter.limit(Eigen::Vector3d(-1.0, 0.0, 0.0));
  EXPECT_NEAR(back.v_H_mps.x(), -0.15, 1e-9);
}

TEST_F(SeenSpaceTest, ADirectionCoveredOnlyByMemoryUsesTheMemory) {
  const Eigen::Isometry3d T = camera_pose(0.0);
  limiter_.update(0, wall(3.0), &T, level_);
  // A remembered wall 1.5 m behind (W = body frame here), spanning +-40 deg.
  for (double y = -1.3; y <= 1.3; y += 0.05) {
    limiter_.add_remembered_point(Eigen::Vector3f(-1.5f, static_cast<float>(y), 0.0f), 0);
  }
  // Remembered points above the band (a ceiling) or beyond range do nothing.
  limiter_.add_remembered_point(Eigen::Vector3f(0.0f, 1.0f, -1.0f), 0);
  EXPECT_LT(limiter_.free_distance_m(limiter_.bin_of_heading_azimuth(M_PI)), 1.51);
  EXPECT_LT(limiter_.free_distance_m(limiter_.bin_of_heading_azimuth(M_PI / 2)), 0.0);

  const LimitedCommand back = limiter_.limit(Eigen::Vector3d(-2.0, 0.0, 0.0));
  EXPECT_TRUE(back.limited);
  EXPECT_FALSE(back.unseen);
  EXPECT_NEAR(-back.v_H_mps.x(), limiter_.max_speed_mps(1.5), 0.05);
  EXPECT_GT(-back.v_H_mps.x(), 0.3);
  // The memory is per frame: the next update without it is unseen behind again.
  limiter_.update(kSecond / 30, wall(3.0), &T, level_);
  EXPECT_TRUE(limiter_.limit(Eigen::Vector3d(-2.0, 0.0, 0.0)).unseen);
}

TEST_F(SeenSpaceTest, SeenSpaceAgesBackToNoData) {
  const Eigen::Isometry3d T = camera_pose(0.0);
  limiter_.update(0, wall(3.0), &T, level_);
  // Tracking lost: no pose, no new data; the bins are kept until max_age_s.
  limiter_.update(4 * kSecond, wall(3.0), nullptr, level_);
  EXPECT_FALSE(limiter_.limit(Eigen::Vector3d(1.0, 0.0, 0.0)).limited);
  limiter_.update(static_cast<std::int64_t>((config_.max_age_s + 0.1) * 1e9), wall(3.0), nullptr,
                  level_);
  const LimitedCommand aged = limiter_.limit(Eigen::Vector3d(1.0, 0.0, 0.0));
  EXPECT_TRUE(aged.unseen);
  EXPECT_EQ(aged.v_H_mps.x(), 0.0);
}

TEST_F(SeenSpaceTest, NanDepthIsNoData) {
  const Eigen::Isometry3d T = camera_pose(0.0);
  limiter_.update(0, wall(3.0), &T, level_);
  ASSERT_FALSE(limiter_.limit(Eigen::Vector3d(1.0, 0.0, 0.0)).limited);
  const cv::Mat nan(240, 320, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  const SeenSpaceUpdate u = limiter_.update(kSecond / 30, nan, &T, level_);
  EXPECT_EQ(u.covered_bins, 0);
  const LimitedCommand forward = limiter_.limit(Eigen::Vector3d(1.0, 0.0, 0.0));
  EXPECT_TRUE(forward.unseen);
  EXPECT_EQ(forward.v_H_mps.x(), 0.0);
  // A non-finite command is zero, not NaN.
  const LimitedCommand bad = limiter_.limit(Eigen::Vector3d(std::nan(""), 0.0, 0.0));
  EXPECT_TRUE(bad.v_H_mps.allFinite());
}

TEST_F(SeenSpaceTest, FloorBelowTheBandIsFreeSpaceNotAWall) {
  // The camera 1 m above a floor, pitched down 30 deg: it sees only floor.
  const Eigen::Isometry3d T = camera_pose(0.0);
  cv::Mat floor(240, 320, CV_32FC1, cv::Scalar(0.0f));
  const geometry::PinholeCamera cam = test_camera();
  const Eigen::Matrix3d R_pitch =
      Eigen::AngleAxisd(-30.0 * M_PI / 180.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Matrix3d R_HC = R_pitch * R_B_C();
  for (int v = 0; v < 240; ++v) {
    for (int u = 0; u < 320; ++u) {
      const Eigen::Vector3d ray =
          Eigen::Vector3d((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, 1.0);
      const double down = (R_HC * ray).z();
      if (down > 1e-3) floor.at<float>(v, u) = static_cast<float>(1.0 / down);  // depth = z_C
    }
  }
  limiter_.update(0, floor, &T, R_pitch);
  const double free_m = limiter_.free_distance_m(limiter_.bin_of_heading_azimuth(0.01));
  EXPECT_GT(free_m, 1.5);  // the top rows leave the 0.45 m band far away
  EXPECT_FALSE(limiter_.limit(Eigen::Vector3d(0.5, 0.0, 0.0)).limited);
}

TEST_F(SeenSpaceTest, YawTurnsTheBinsWithTheWorld) {
  limiter_.update(0, wall(2.0), &(static_cast<const Eigen::Isometry3d&>(camera_pose(0.0))), level_);
  // The vehicle yaws 90 deg right (no depth this frame): the wall is now on its left.
  const Eigen::Isometry3d T90 = camera_pose(M_PI / 2);
  limiter_.update(kSecond / 30, cv::Mat(), &T90, level_);
  EXPECT_NEAR(limiter_.yaw_rad(), M_PI / 2, 1e-9);
  const LimitedCommand left = limiter_.limit(Eigen::Vector3d(0.0, -2.0, 0.0));
  EXPECT_FALSE(left.unseen);
  EXPECT_NEAR(-left.v_H_mps.y(), limiter_.max_speed_mps(2.0), 0.05);
  EXPECT_TRUE(limiter_.limit(Eigen::Vector3d(1.0, 0.0, 0.0)).unseen) << "ahead is unseen now";
}

TEST_F(SeenSpaceTest, ATrackingLossForgetsKeptBinsAndOlderMemory) {
  const Eigen::Isometry3d T = camera_pose(0.0);
  limiter_.update(0, wall(3.0), &T, level_);
  limiter_.update(kSecond / 30, wall(3.0), nullptr, level_);  // lost
  // Back, turned 90 deg meanwhile (unknown to the limiter): nothing kept is trusted.
  const Eigen::Isometry3d T90 = camera_pose(M_PI / 2);
  limiter_.update(2 * kSecond / 30, cv::Mat(), &T90, level_);
  EXPECT_TRUE(limiter_.limit(Eigen::Vector3d(0.0, -1.0, 0.0)).unseen);
  // W -x is on the right of a body yawed 90 deg.
  limiter_.add_remembered_point(Eigen::Vector3f(-1.5f, 0.0f, 0.0f), 0);  // seen before the loss
  EXPECT_LT(limiter_.free_distance_m(limiter_.bin_of_heading_azimuth(M_PI / 2 + 0.01)), 0.0);
  limiter_.add_remembered_point(Eigen::Vector3f(-1.5f, 0.0f, 0.0f), 2 * kSecond / 30);
  EXPECT_NEAR(limiter_.free_distance_m(limiter_.bin_of_heading_azimuth(M_PI / 2 + 0.01)), 1.5,
              0.01);
}

TEST_F(SeenSpaceTest, TravelShrinksKeptBinsAndAJumpForgetsThem) {
  limiter_.update(0, wall(3.0), &(static_cast<const Eigen::Isometry3d&>(camera_pose(0.0))), level_);
  // Moved 0.25 m forward, depth missing this frame: the kept wall is at most 2.75 m away.
  const Eigen::Isometry3d T1 = camera_pose(0.0, Eigen::Vector3d(0.25, 0.0, 0.0));
  limiter_.update(kSecond / 30, cv::Mat(), &T1, level_);
  EXPECT_NEAR(limiter_.free_distance_m(limiter_.bin_of_heading_azimuth(0.01)), 2.75, 0.02);
  const Eigen::Isometry3d T2 = camera_pose(0.0, Eigen::Vector3d(1.0, 0.0, 0.0));
  limiter_.update(2 * kSecond / 30, cv::Mat(), &T2, level_);
  EXPECT_LT(limiter_.free_distance_m(limiter_.bin_of_heading_azimuth(0.01)), 0.0);
}

TEST_F(SeenSpaceTest, UpdateAndLimitAllocateNothing) {
  const Eigen::Isometry3d T = camera_pose(0.0);
  const cv::Mat depth = wall(2.0);
  limiter_.update(0, depth, &T, level_);
  std::array<float, kMaxBins> limits{};
  const long before = testing::allocation_count();
  for (int i = 1; i < 20; ++i) {
    const Eigen::Isometry3d Ti = camera_pose(0.01 * i, Eigen::Vector3d(0.01 * i, 0.0, 0.0));
    limiter_.update(i * kSecond / 30, depth, &Ti, level_);
    limiter_.add_remembered_point(Eigen::Vector3f(-1.0f, 0.0f, 0.0f), i * kSecond / 30);
    const LimitedCommand c = limiter_.limit(Eigen::Vector3d(1.0, 0.5, 0.0));
    EXPECT_TRUE(c.v_H_mps.allFinite());
    limiter_.heading_limits(limits);
  }
  EXPECT_EQ(testing::allocation_count() - before, 0);
  EXPECT_NEAR(
      limits[0],
      limiter_.max_speed_mps(limiter_.free_distance_m(limiter_.bin_of_heading_azimuth(0.02))), 0.5);
}

TEST(SeenSpaceConfigTest, ReadsStrictlyWithRanges) {
  SeenSpaceConfig config;
  config::StrictMap ok(YAML::Load("{enabled: true, bins: 36, creep_speed_mps: 0.1, margin_m: 0.3}"),
                       "config/onboard.yaml", "seen_space");
  read_config(ok, config);
  EXPECT_EQ(config.bins, 36);
  EXPECT_DOUBLE_EQ(config.creep_speed_mps, 0.1);
  const std::string message = testing::input_error_message([] {
    SeenSpaceConfig c;
    config::StrictMap bad(YAML::Load("{bins: 500}"), "config/onboard.yaml", "seen_space");
    read_config(bad, c);
  });
  EXPECT_THAT(message, HasSubstr("bins"));
  EXPECT_THAT(message, HasSubstr("500"));
  const std::string unknown = testing::input_error_message([] {
    SeenSpaceConfig c;
    config::StrictMap bad(YAML::Load("{creep_mps: 0.1}"), "config/onboard.yaml", "seen_space");
    read_config(bad, c);
  });
  EXPECT_THAT(unknown, HasSubstr("creep_mps"));
}

}  // namespace
}  // namespace hq::seen_space
