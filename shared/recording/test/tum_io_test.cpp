#include "hq/recording/tum_io.hpp"

#include "hq/base/error.hpp"
#include "hq/testing/input_error.hpp"

#include "temp_dir.hpp"
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

namespace hq::recording {
namespace {

using test::TempDir;
using ::testing::HasSubstr;

using hq::testing::input_error_message;

TEST(SecondsToNs, RoundsToNearestNanosecondAtEpochMagnitude) {
  EXPECT_EQ(seconds_to_ns(0.25), 250'000'000);
  EXPECT_EQ(seconds_to_ns(-0.25), -250'000'000);
  EXPECT_EQ(seconds_to_ns(2.0), 2'000'000'000);
  // A double holds 1305031790.645155 only to +-119 ns; the conversion must add no more error
  // (a plain t_s * 1e9 would round to a multiple of 256 ns).
  const std::int64_t t_ns = seconds_to_ns(1305031790.645155);
  EXPECT_LE(std::abs(t_ns - 1'305'031'790'645'155'000), 120);
  EXPECT_NEAR(ns_to_seconds(1'305'031'790'645'155'000) - 1305031790.0, 0.645155, 3e-7);
  EXPECT_EQ(ns_to_seconds(-250'000'000), -0.25);
  for (const std::int64_t ns : {std::int64_t{0}, std::int64_t{1}, std::int64_t{123'456'789},
                                std::int64_t{1'305'031'790'000'000'001}}) {
    EXPECT_LE(std::abs(seconds_to_ns(ns_to_seconds(ns)) - ns), 120) << ns;
  }
}

TEST(ReadTumList, ParsesEntriesAndSkipsCommentsAndBlankLines) {
  TempDir dir;
  const std::string path = dir.write("rgb.txt",
                                     "# color images\n"
                                     "# timestamp filename\n"
                                     "\n"
                                     "1305031790.645155 rgb/1305031790.645155.png\n"
                                     "  1305031790.713097\trgb/1305031790.713097.png  \r\n");
  const std::vector<TumListEntry> entries = read_tum_list(path);
  ASSERT_EQ(entries.size(), 2u);
  EXPECT_DOUBLE_EQ(entries[0].t_s, 1305031790.645155);
  EXPECT_EQ(entries[0].relative_path, "rgb/1305031790.645155.png");
  EXPECT_DOUBLE_EQ(entries[1].t_s, 1305031790.713097);
  EXPECT_EQ(entries[1].relative_path, "rgb/1305031790.713097.png");
}

TEST(ReadTumList, MalformedLineNamesFileAndLine) {
  TempDir dir;
  const std::string path = dir.write("rgb.txt", "# c\n# c\n1.0 a.png\n2.0 b.png extra\n");
  const std::string message = input_error_message([&] { read_tum_list(path); });
  EXPECT_THAT(message, HasSubstr("rgb.txt:4: expected \"timestamp filename\""));
  EXPECT_THAT(message, HasSubstr("b.png extra"));
}

TEST(ReadTumList, NonNumericStampNamesFileAndLine) {
  TempDir dir;
  const std::string path = dir.write("depth.txt", "1.0 a.png\nabc b.png\n");
  EXPECT_THAT(input_error_message([&] { read_tum_list(path); }),
              HasSubstr("depth.txt:2: timestamp = \"abc\", expected a number"));
}

TEST(ReadTumList, NonFiniteStampRejected) {
  TempDir dir;
  const std::string path = dir.write("rgb.txt", "nan a.png\n");
  EXPECT_THAT(input_error_message([&] { read_tum_list(path); }),
              HasSubstr("rgb.txt:1: timestamp = nan, expected a finite number"));
}

TEST(ReadTumList, NonMonotonicStampNamesLine) {
  TempDir dir;
  const std::string path = dir.write("rgb.txt", "# c\n1.0 a.png\n2.0 b.png\n2.0 c.png\n");
  const std::string message = input_error_message([&] { read_tum_list(path); });
  EXPECT_THAT(message, HasSubstr("rgb.txt:4: timestamp 2.0 is not after the previous one"));
}

TEST(ReadTumList, MissingFileNamed) {
  TempDir dir;
  EXPECT_THAT(input_error_message([&] { read_tum_list(dir.path() + "/nope.txt"); }),
              HasSubstr("nope.txt: cannot open"));
}

TEST(ReadTumTrajectory, ParsesAndNormalisesQuaternion) {
  TempDir dir;
  // 90 degrees about z, printed with 4 decimals as TUM does (norm 0.99999).
  const std::string path = dir.write("groundtruth.txt",
                                     "# timestamp tx ty tz qx qy qz qw\n"
                                     "1305031789.6406 0.4365 -0.3888 1.6888 0 0 0.7071 0.7071\n"
                                     "1305031789.6505 1 2 3 0 0 0 1\n");
  const std::vector<StampedPose> poses = read_tum_trajectory(path);
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_EQ(poses[0].t_ns, seconds_to_ns(1305031789.6406));
  EXPECT_TRUE(poses[0].T_G_S.translation().isApprox(Eigen::Vector3d(0.4365, -0.3888, 1.6888)));
  const Eigen::Matrix3d R = poses[0].T_G_S.rotation();
  EXPECT_NEAR((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-12);
  // x axis maps to y under +90 degrees about z.
  EXPECT_TRUE((R * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
  EXPECT_TRUE(poses[1].T_G_S.linear().isIdentity(0.0));
}

TEST(ReadTumTrajectory, WrongFieldCountNamesLine) {
  TempDir dir;
  const std::string path = dir.write("traj.txt", "1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n");
  EXPECT_THAT(input_error_message([&] { read_tum_trajectory(path); }),
              HasSubstr("traj.txt:2: expected \"timestamp tx ty tz qx qy qz qw\" (8 fields), "
                        "got 7"));
}

TEST(ReadTumTrajectory, NonFiniteValueNamesLineAndField) {
  TempDir dir;
  const std::string path = dir.write("traj.txt", "# h\n1 0 0 0 0 0 0 1\n2 0 inf 0 0 0 0 1\n");
  EXPECT_THAT(input_error_message([&] { read_tum_trajectory(path); }),
              HasSubstr("traj.txt:3: ty = inf, expected a finite number"));
}

TEST(ReadTumTrajectory, ZeroQuaternionRejected) {
  TempDir dir;
  const std::string path = dir.write("traj.txt", "1 0 0 0 0 0 0 0\n");
  EXPECT_THAT(input_error_message([&] { read_tum_trajectory(path); }),
              HasSubstr("traj.txt:1: quaternion (qx qy qz qw) has norm 0, expected 1"));
}

TEST(ReadTumTrajectory, QuaternionFarFromUnitRejected) {
  TempDir dir;
  // Columns in the wrong order: positions where the quaternion should be.
  const std::string path = dir.write("traj.txt", "1 0 0 0 1 0.5 2 3\n");
  EXPECT_THAT(input_error_message([&] { read_tum_trajectory(path); }),
              HasSubstr("traj.txt:1: quaternion (qx qy qz qw) has norm"));
}

TEST(ReadTumTrajectory, NonMonotonicStampNamesLine) {
  TempDir dir;
  const std::string path = dir.write("traj.txt", "2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n");
  EXPECT_THAT(input_error_message([&] { read_tum_trajectory(path); }),
              HasSubstr("traj.txt:2: timestamp 1 is not after the previous one"));
}

TEST(WriteTumTrajectory, RoundTripsThroughReader) {
  TempDir dir;
  std::vector<StampedPose> poses;
  for (int i = 0; i < 5; ++i) {
    StampedPose pose{1'305'031'790'000'000'000 + i * 33'333'000, Eigen::Isometry3d::Identity()};
    pose.T_G_S.linear() =
        Eigen::AngleAxisd(0.3 * i + 0.1, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    pose.T_G_S.translation() = Eigen::Vector3d(0.123456789 * i, -1.5, 2.0 / 3.0);
    poses.push_back(pose);
  }
  const std::string path = dir.path() + "/est.txt";
  write_tum_trajectory(path, poses);
  const std::vector<StampedPose> read = read_tum_trajectory(path);
  ASSERT_EQ(read.size(), poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    // Stamps are written at TUM's microsecond resolution; these are whole microseconds.
    EXPECT_LE(std::abs(read[i].t_ns - poses[i].t_ns), 120) << i;
    EXPECT_TRUE(read[i].T_G_S.matrix().isApprox(poses[i].T_G_S.matrix(), 1e-8)) << i;
  }
}

TEST(WriteTumTrajectory, NonFinitePoseRejected) {
  TempDir dir;
  StampedPose pose{0, Eigen::Isometry3d::Identity()};
  pose.T_G_S.translation().x() = std::nan("");
  EXPECT_THAT(input_error_message([&] { write_tum_trajectory(dir.path() + "/e.txt", {pose}); }),
              HasSubstr("e.txt: pose 0 (t_ns 0) is not finite"));
}

TEST(ReadTumAccelerometer, ParsesSamplesAndNamesBadLine) {
  TempDir dir;
  const std::string good = dir.write("accelerometer.txt",
                                     "# accelerometer data\n"
                                     "1305031790.640000 -0.0794 -9.8211 0.1589\n"
                                     "1305031790.650000 -0.0813 -9.8102 0.1532\n");
  const std::vector<AccelSample> samples = read_tum_accelerometer(good);
  ASSERT_EQ(samples.size(), 2u);
  EXPECT_EQ(samples[1].t_ns, seconds_to_ns(1305031790.65));
  EXPECT_TRUE(samples[0].accel_mps2.isApprox(Eigen::Vector3d(-0.0794, -9.8211, 0.1589)));

  const std::string bad = dir.write("accel_bad.txt", "1 0 0 9.81\n2 0 9.81\n");
  EXPECT_THAT(input_error_message([&] { read_tum_accelerometer(bad); }),
              HasSubstr("accel_bad.txt:2: expected \"timestamp ax ay az\""));
}

TEST(AssociateRgbd, PairsWithinToleranceAndJoinsPaths) {
  const std::vector<TumListEntry> rgb = {
      {10.000, "rgb/a.png"}, {10.033, "rgb/b.png"}, {10.066, "/abs/c.png"}};
  const std::vector<TumListEntry> depth = {
      {9.995, "depth/a.png"}, {10.040, "depth/b.png"}, {10.075, "depth/c.png"}};
  const std::vector<RgbdFrameFiles> frames = associate_rgbd(rgb, depth, "/seq", 0.01);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].t_ns, seconds_to_ns(10.000));
  EXPECT_EQ(frames[0].depth_t_ns, seconds_to_ns(9.995));
  EXPECT_EQ(frames[0].rgb_path, "/seq/rgb/a.png");
  EXPECT_EQ(frames[0].depth_path, "/seq/depth/a.png");
  EXPECT_EQ(frames[1].depth_t_ns, seconds_to_ns(10.040));
  EXPECT_EQ(frames[2].rgb_path, "/abs/c.png");
  EXPECT_EQ(frames[2].depth_t_ns, seconds_to_ns(10.075));

  // A tighter tolerance drops the pairs 7 ms and 9 ms apart, keeps the 5 ms one.
  const std::vector<RgbdFrameFiles> tight = associate_rgbd(rgb, depth, "/seq", 0.006);
  ASSERT_EQ(tight.size(), 1u);
  EXPECT_EQ(tight[0].rgb_path, "/seq/rgb/a.png");
}

TEST(AssociateRgbd, GapsLeaveFramesUnpairedAndEachEntryIsUsedOnce) {
  // Depth 2 is missing (gap); rgb 10.030 and 10.036 both lie near depth 10.034: the closer one
  // (10.036, 2 ms) wins, the other stays unpaired although within tolerance.
  const std::vector<TumListEntry> rgb = {
      {10.000, "r0"}, {10.030, "r1"}, {10.036, "r2"}, {10.100, "r3"}, {10.133, "r4"}};
  const std::vector<TumListEntry> depth = {{10.001, "d0"}, {10.034, "d1"}, {10.135, "d4"}};
  const std::vector<RgbdFrameFiles> frames = associate_rgbd(rgb, depth, "", 0.02);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_EQ(frames[0].rgb_path, "r0");
  EXPECT_EQ(frames[0].depth_path, "d0");
  EXPECT_EQ(frames[1].rgb_path, "r2");
  EXPECT_EQ(frames[1].depth_path, "d1");
  EXPECT_EQ(frames[2].rgb_path, "r4");
  EXPECT_EQ(frames[2].depth_path, "d4");
}

TEST(AssociateRgbd, ToleranceBoundaryIsInclusive) {
  const std::vector<TumListEntry> rgb = {{1.0, "r"}};
  const std::vector<TumListEntry> depth = {{1.25, "d"}};
  EXPECT_EQ(associate_rgbd(rgb, depth, "", 0.25).size(), 1u);
  EXPECT_EQ(associate_rgbd(rgb, depth, "", 0.2499).size(), 0u);
}

}  // namespace
}  // namespace hq::recording
