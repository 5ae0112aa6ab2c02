#include "hq/recording/tum_sequence.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/recording/data_dir.hpp"
#include "hq/testing/input_error.hpp"

#include "temp_dir.hpp"
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <random>

namespace hq::recording {
namespace {

using test::TempDir;
using ::testing::HasSubstr;

using hq::testing::input_error_message;

// Distinct, reproducible content per frame so that a load of the wrong file shows.
cv::Mat make_bgr(int frame, cv::Size size) {
  cv::Mat bgr(size, CV_8UC3);
  for (int v = 0; v < size.height; ++v) {
    for (int u = 0; u < size.width; ++u) {
      bgr.at<cv::Vec3b>(v, u) = cv::Vec3b(static_cast<uchar>(u + frame), static_cast<uchar>(v),
                                          static_cast<uchar>(frame * 40));
    }
  }
  return bgr;
}

cv::Mat make_depth(int frame, cv::Size size) {
  cv::Mat depth(size, CV_16UC1);
  for (int v = 0; v < size.height; ++v) {
    for (int u = 0; u < size.width; ++u) {
      // Every 7th pixel has no data (0), the rest 0.2..~3 m at 5000 units per metre.
      depth.at<std::uint16_t>(v, u) =
          (u + v) % 7 == 0 ? 0 : static_cast<std::uint16_t>(1000 + 100 * frame + 37 * u + 11 * v);
    }
  }
  return depth;
}

// A small TUM layout with `frames` frames at 30 Hz, depth 3 ms after colour.
struct Fixture {
  explicit Fixture(int frames, cv::Size size = cv::Size(8, 6)) {
    std::string rgb_list = "# color images\n# file: 'test.bag'\n# timestamp filename\n";
    std::string depth_list = "# depth maps\n# file: 'test.bag'\n# timestamp filename\n";
    std::filesystem::create_directories(dir.path() + "/rgb");
    std::filesystem::create_directories(dir.path() + "/depth");
    for (int i = 0; i < frames; ++i) {
      char rgb_name[64];
      char depth_name[64];
      hq::format_into(rgb_name, "{:.6f}", 100.0 + i / 30.0);
      hq::format_into(depth_name, "{:.6f}", 100.003 + i / 30.0);
      rgb_paths.push_back("rgb/" + std::string(rgb_name) + ".png");
      depth_paths.push_back("depth/" + std::string(depth_name) + ".png");
      rgb_list += std::string(rgb_name) + " " + rgb_paths.back() + "\n";
      depth_list += std::string(depth_name) + " " + depth_paths.back() + "\n";
      cv::imwrite(dir.path() + "/" + rgb_paths.back(), make_bgr(i, size));
      cv::imwrite(dir.path() + "/" + depth_paths.back(), make_depth(i, size));
    }
    dir.write("rgb.txt", rgb_list);
    dir.write("depth.txt", depth_list);
  }
  std::string file(const std::string& relative) const { return dir.path() + "/" + relative; }

  TempDir dir;
  std::vector<std::string> rgb_paths;
  std::vector<std::string> depth_paths;
};

bool equal(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0.0;
}

TEST(TumSequence, AssociatesFramesAndLoadsIntoReusedBuffers) {
  const Fixture fixture(3);
  const TumSequence sequence(fixture.dir.path());
  ASSERT_EQ(sequence.size(), 3u);
  EXPECT_EQ(sequence.directory(), fixture.dir.path());
  EXPECT_EQ(sequence.image_size(), cv::Size(8, 6));
  EXPECT_FALSE(sequence.has_ground_truth());
  EXPECT_FALSE(sequence.has_accelerometer());
  EXPECT_EQ(sequence.frame(1).t_ns, seconds_to_ns(100.033333));
  EXPECT_EQ(sequence.frame(1).depth_t_ns, seconds_to_ns(100.036333));
  EXPECT_EQ(sequence.frame(1).depth_path, fixture.file(fixture.depth_paths[1]));

  cv::Mat bgr;
  cv::Mat depth_u16;
  sequence.load(0, bgr, depth_u16);
  EXPECT_TRUE(equal(bgr, make_bgr(0, cv::Size(8, 6))));
  EXPECT_TRUE(equal(depth_u16, make_depth(0, cv::Size(8, 6))));
  const uchar* bgr_data = bgr.data;
  const uchar* depth_data = depth_u16.data;
  sequence.load(2, bgr, depth_u16);
  EXPECT_TRUE(equal(bgr, make_bgr(2, cv::Size(8, 6))));
  EXPECT_TRUE(equal(depth_u16, make_depth(2, cv::Size(8, 6))));
  EXPECT_EQ(bgr.data, bgr_data);
  EXPECT_EQ(depth_u16.data, depth_data);
}

TEST(TumSequence, ReadsOptionalGroundTruthAndAccelerometer) {
  const Fixture fixture(2);
  fixture.dir.write("groundtruth.txt", "# gt\n100.0 1 2 3 0 0 0 1\n100.01 1 2 3 0 0 0 1\n");
  fixture.dir.write("accelerometer.txt", "100.0 0 -9.81 0\n");
  const TumSequence sequence(fixture.dir.path());
  ASSERT_TRUE(sequence.has_ground_truth());
  EXPECT_EQ(sequence.ground_truth().size(), 2u);
  ASSERT_TRUE(sequence.has_accelerometer());
  EXPECT_EQ(sequence.accelerometer().size(), 1u);
}

TEST(TumSequence, MissingDirectoryOrListNamed) {
  TempDir dir;
  EXPECT_THAT(input_error_message([&] { TumSequence(dir.path() + "/absent"); }),
              HasSubstr("absent: TUM sequence directory not found"));
  EXPECT_THAT(input_error_message([&] { TumSequence{dir.path()}; }),
              HasSubstr("rgb.txt: cannot open"));
  dir.write("rgb.txt", "1.0 rgb/a.png\n");
  EXPECT_THAT(input_error_message([&] { TumSequence{dir.path()}; }),
              HasSubstr("depth.txt: cannot open"));
}

TEST(TumSequence, MalformedGroundTruthNamesFileAndLine) {
  const Fixture fixture(2);
  fixture.dir.write("groundtruth.txt", "# gt\n100.0 1 2 3 0 0 0 1\n100.01 1 2 3 0 0 0\n");
  EXPECT_THAT(input_error_message([&] { TumSequence{fixture.dir.path()}; }),
              HasSubstr("groundtruth.txt:3: expected \"timestamp tx ty tz qx qy qz qw\""));
}

TEST(TumSequence, NoAssociatedPairRejected) {
  TempDir dir;
  dir.write("rgb.txt", "1.0 rgb/a.png\n");
  dir.write("depth.txt", "2.0 depth/a.png\n");
  EXPECT_THAT(input_error_message([&] { TumSequence{dir.path()}; }),
              HasSubstr("no colour/depth pair within"));
}

TEST(TumSequence, EightBitDepthRejectedNamingFile) {
  const Fixture fixture(2);
  cv::Mat depth_8u(6, 8, CV_8UC1, cv::Scalar(200));
  cv::imwrite(fixture.file(fixture.depth_paths[1]), depth_8u);
  const TumSequence sequence(fixture.dir.path());
  cv::Mat bgr;
  cv::Mat depth_u16;
  const std::string message = input_error_message([&] { sequence.load(1, bgr, depth_u16); });
  EXPECT_THAT(message,
              HasSubstr(fixture.depth_paths[1] + ": depth image is 8-bit unsigned "
                                                 "1-channel, expected 16-bit single-channel"));
}

TEST(TumSequence, EightBitDepthInFrameZeroRejectedAtConstruction) {
  const Fixture fixture(1);
  cv::imwrite(fixture.file(fixture.depth_paths[0]), cv::Mat(6, 8, CV_8UC1, cv::Scalar(7)));
  EXPECT_THAT(input_error_message([&] { TumSequence{fixture.dir.path()}; }),
              HasSubstr(fixture.depth_paths[0] + ": depth image is 8-bit"));
}

TEST(TumSequence, CorruptPngRejectedNamingFile) {
  const Fixture fixture(2);
  std::mt19937 rng(42);
  std::string garbage(4096, '\0');
  for (char& c : garbage) c = static_cast<char>(rng() & 0xff);
  fixture.dir.write(fixture.rgb_paths[1], garbage);
  const TumSequence sequence(fixture.dir.path());
  cv::Mat bgr;
  cv::Mat depth_u16;
  EXPECT_THAT(input_error_message([&] { sequence.load(1, bgr, depth_u16); }),
              HasSubstr(fixture.rgb_paths[1] + ": cannot decode image"));
}

TEST(TumSequence, TruncatedPngRejectedNamingFile) {
  const Fixture fixture(2, cv::Size(64, 48));
  const std::string path = fixture.file(fixture.depth_paths[1]);
  std::filesystem::resize_file(path, std::filesystem::file_size(path) / 2);
  const TumSequence sequence(fixture.dir.path());
  cv::Mat bgr;
  cv::Mat depth_u16;
  EXPECT_THAT(input_error_message([&] { sequence.load(1, bgr, depth_u16); }),
              HasSubstr(fixture.depth_paths[1] + ": cannot decode image"));
}

TEST(TumSequence, MissingPngRejectedNamingFile) {
  const Fixture fixture(2);
  std::filesystem::remove(fixture.file(fixture.rgb_paths[1]));
  const TumSequence sequence(fixture.dir.path());
  cv::Mat bgr;
  cv::Mat depth_u16;
  EXPECT_THAT(input_error_message([&] { sequence.load(1, bgr, depth_u16); }),
              HasSubstr(fixture.rgb_paths[1] + ": image file not found"));
}

TEST(TumSequence, DepthSizeDifferentFromColourRejected) {
  const Fixture fixture(2);
  cv::imwrite(fixture.file(fixture.depth_paths[1]), make_depth(1, cv::Size(4, 6)));
  const TumSequence sequence(fixture.dir.path());
  cv::Mat bgr;
  cv::Mat depth_u16;
  const std::string message = input_error_message([&] { sequence.load(1, bgr, depth_u16); });
  EXPECT_THAT(message, HasSubstr(fixture.depth_paths[1] + ": depth image is 4x6"));
  EXPECT_THAT(message, HasSubstr("is 8x6; expected equal sizes"));
}

TEST(TumSequence, FrameSizeDifferentFromFrameZeroRejected) {
  const Fixture fixture(2);
  cv::imwrite(fixture.file(fixture.rgb_paths[1]), make_bgr(1, cv::Size(10, 6)));
  cv::imwrite(fixture.file(fixture.depth_paths[1]), make_depth(1, cv::Size(10, 6)));
  const TumSequence sequence(fixture.dir.path());
  cv::Mat bgr;
  cv::Mat depth_u16;
  EXPECT_THAT(input_error_message([&] { sequence.load(1, bgr, depth_u16); }),
              HasSubstr(fixture.rgb_paths[1] + ": image is 10x6, expected 8x6 like frame 0"));
}

TEST(TumSequence, GreyscaleColourImageRejected) {
  const Fixture fixture(2);
  cv::imwrite(fixture.file(fixture.rgb_paths[1]), cv::Mat(6, 8, CV_8UC1, cv::Scalar(9)));
  const TumSequence sequence(fixture.dir.path());
  cv::Mat bgr;
  cv::Mat depth_u16;
  EXPECT_THAT(input_error_message([&] { sequence.load(1, bgr, depth_u16); }),
              HasSubstr(fixture.rgb_paths[1] + ": colour image is 8-bit unsigned 1-channel"));
}

TEST(DepthToMetres, ScalesUnitsAndKeepsZeroAsNoData) {
  cv::Mat depth_u16 = (cv::Mat_<std::uint16_t>(1, 4) << 0, 5000, 1234, 65535);
  cv::Mat depth_m;
  depth_to_metres(depth_u16, 5000.0, depth_m);
  ASSERT_EQ(depth_m.type(), CV_32FC1);
  ASSERT_EQ(depth_m.size(), depth_u16.size());
  EXPECT_EQ(depth_m.at<float>(0, 0), 0.0f);
  EXPECT_FLOAT_EQ(depth_m.at<float>(0, 1), 1.0f);
  EXPECT_FLOAT_EQ(depth_m.at<float>(0, 2), 0.2468f);
  EXPECT_FLOAT_EQ(depth_m.at<float>(0, 3), 13.107f);

  const float* data = depth_m.ptr<float>();
  depth_to_metres(depth_u16, 1000.0, depth_m);
  EXPECT_EQ(depth_m.ptr<float>(), data);
  EXPECT_FLOAT_EQ(depth_m.at<float>(0, 2), 1.234f);
}

TEST(DepthToMetres, RejectsWrongTypeAndScale) {
  cv::Mat depth_m;
  EXPECT_THAT(input_error_message(
                  [&] { depth_to_metres(cv::Mat(2, 2, CV_8UC1, cv::Scalar(1)), 5000, depth_m); }),
              HasSubstr("depth image is 8-bit unsigned 1-channel, expected 16-bit"));
  EXPECT_THAT(input_error_message(
                  [&] { depth_to_metres(cv::Mat(2, 2, CV_16UC1, cv::Scalar(1)), 0.0, depth_m); }),
              HasSubstr("units_per_m = 0.000000, expected finite and > 0"));
}

// Real data: the 5 bundled frames of fr1_360 (see shared/data/SOURCES.md).
TEST(TumSequenceRealData, Freiburg1_360HasFiveFramesWithGroundTruth) {
  const std::optional<std::string> data_dir = find_data_dir();
  if (!data_dir) GTEST_SKIP() << "no data directory; searched " << data_dir_search_description();
  const std::string dir = *data_dir + "/tum/rgbd_dataset_freiburg1_360";
  if (!std::filesystem::is_directory(dir)) GTEST_SKIP() << "absent: " << dir;

  const TumSequence sequence(dir);
  ASSERT_EQ(sequence.size(), 5u);
  EXPECT_EQ(sequence.image_size(), cv::Size(640, 480));
  EXPECT_EQ(sequence.frame(0).t_ns, seconds_to_ns(1305031790.645155));
  EXPECT_EQ(sequence.frame(0).depth_t_ns, seconds_to_ns(1305031790.640468));
  EXPECT_EQ(sequence.frame(4).t_ns, seconds_to_ns(1305031790.913129));
  // Every listed depth frame pairs with the colour frame of the same rank; the largest gap is
  // 7.7 ms (frame 2: 781.258 vs 773.548 ms), within the 20 ms tolerance.
  const std::vector<TumListEntry> depth = read_tum_list(dir + "/depth.txt");
  ASSERT_EQ(depth.size(), 5u);
  std::int64_t max_gap_ns = 0;
  for (std::size_t i = 0; i < sequence.size(); ++i) {
    EXPECT_EQ(sequence.frame(i).depth_t_ns, seconds_to_ns(depth[i].t_s)) << i;
    EXPECT_EQ(sequence.frame(i).depth_path, dir + "/" + depth[i].relative_path) << i;
    max_gap_ns =
        std::max(max_gap_ns, std::abs(sequence.frame(i).t_ns - sequence.frame(i).depth_t_ns));
  }
  EXPECT_NEAR(static_cast<double>(max_gap_ns), 7'710'000.0, 1000.0);
  ASSERT_TRUE(sequence.has_ground_truth());
  EXPECT_EQ(sequence.ground_truth().size(), 228u);
  EXPECT_LT(sequence.ground_truth().front().t_ns, sequence.frame(0).t_ns);
  EXPECT_GT(sequence.ground_truth().back().t_ns, sequence.frame(4).t_ns);
  EXPECT_FALSE(sequence.has_accelerometer());

  cv::Mat bgr;
  cv::Mat depth_u16;
  cv::Mat depth_m;
  sequence.load(2, bgr, depth_u16);
  EXPECT_EQ(bgr.type(), CV_8UC3);
  EXPECT_EQ(depth_u16.type(), CV_16UC1);
  EXPECT_EQ(bgr.size(), cv::Size(640, 480));
  depth_to_metres(depth_u16, 5000.0, depth_m);
  // SOURCES.md: about 81 % valid pixels, z from 0.69 to 3.20 m over the 5 frames.
  const double valid_ratio =
      static_cast<double>(cv::countNonZero(depth_m)) / static_cast<double>(depth_m.total());
  EXPECT_GT(valid_ratio, 0.6);
  double min_m = 0.0;
  double max_m = 0.0;
  cv::minMaxLoc(depth_m, &min_m, &max_m, nullptr, nullptr, depth_m > 0.0f);
  EXPECT_GT(min_m, 0.5);
  EXPECT_LT(max_m, 4.0);
}

}  // namespace
}  // namespace hq::recording
