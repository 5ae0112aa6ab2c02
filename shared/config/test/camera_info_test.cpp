#include "hq/config/camera_info.hpp"

#include "hq/base/error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

namespace hq::config {
namespace {

using ::testing::HasSubstr;

class CameraFile : public ::testing::Test {
 protected:
  std::string write(const std::string& text) {
    std::ofstream(path_) << text;
    return path_.string();
  }
  std::string error_of(const std::string& text) {
    try {
      load_camera_info(write(text));
    } catch (const InputError& e) {
      return e.what();
    }
    return "(no error)";
  }
  void TearDown() override { std::filesystem::remove(path_); }
  // One file per test case and process: ctest runs the cases of this fixture in parallel.
  std::filesystem::path path_ =
      std::filesystem::temp_directory_path() /
      ("hq_camera_test_" +
       std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
       std::to_string(getpid()) + ".yaml");
};

constexpr const char* kGood = R"(image_width: 640
image_height: 480
camera_matrix: {rows: 3, cols: 3, data: [500, 0, 320, 0, 501, 240, 0, 0, 1]}
distortion_model: plumb_bob
distortion_coefficients: {rows: 1, cols: 5, data: [0.1, -0.2, 0, 0, 0]}
depth_scale_units_per_m: 5000
)";

TEST_F(CameraFile, LoadsTheRosLayout) {
  const CameraInfo info = load_camera_info(write(kGood));
  EXPECT_EQ(info.width, 640);
  EXPECT_DOUBLE_EQ(info.fy, 501.0);
  EXPECT_DOUBLE_EQ(info.cx, 320.0);
  EXPECT_TRUE(info.has_distortion());
  EXPECT_DOUBLE_EQ(info.depth_scale_units_per_m, 5000.0);
}

TEST_F(CameraFile, WrongMatrixSizeNamesKeyAndCount) {
  std::string text = kGood;
  text.replace(text.find("0, 0, 1]"), 8, "0, 0]");
  EXPECT_THAT(error_of(text), HasSubstr("camera_matrix.data has 8 values, expected 9"));
}

TEST_F(CameraFile, MissingKeyAndBadValuesAreNamed) {
  std::string no_height = kGood;
  no_height.erase(no_height.find("image_height"), std::string("image_height: 480\n").size());
  EXPECT_THAT(error_of(no_height), HasSubstr("image_height is missing"));

  std::string negative_f = kGood;
  negative_f.replace(negative_f.find("[500"), 4, "[-500");
  EXPECT_THAT(error_of(negative_f), HasSubstr("fx and fy must be > 0"));

  std::string typo = std::string(kGood) + "focal: 3\n";
  EXPECT_THAT(error_of(typo), HasSubstr("focal is not a known key"));
}

TEST(Undistorter, IdentityWithoutDistortionAndStraightensWithIt) {
  CameraInfo info;
  info.width = 64;
  info.height = 48;
  info.fx = info.fy = 60.0;
  info.cx = 31.5;
  info.cy = 23.5;
  const cv::Mat image(48, 64, CV_8UC1, cv::Scalar(77));
  cv::Mat out;
  Undistorter none(info);
  EXPECT_TRUE(none.is_identity());
  none.apply_color(image, out);
  EXPECT_EQ(cv::countNonZero(out != image), 0);

  info.distortion = {0.3, 0.0, 0.0, 0.0, 0.0};
  Undistorter barrel(info);
  EXPECT_FALSE(barrel.is_identity());
  cv::Mat depth(48, 64, CV_32FC1, cv::Scalar(2.0f));
  cv::Mat depth_out;
  barrel.apply_depth(depth, depth_out);
  // Nearest-neighbour depth never invents values: every output is 2 m or 0 (outside).
  for (int v = 0; v < 48; ++v) {
    for (int u = 0; u < 64; ++u) {
      const float d = depth_out.at<float>(v, u);
      EXPECT_TRUE(d == 2.0f || d == 0.0f);
    }
  }
  EXPECT_EQ(depth_out.at<float>(24, 32), 2.0f);
}

// fx = 1e-300 passed as "> 0": focal lengths outside 10-10000 px have no physical sense.
TEST_F(CameraFile, FocalLengthOutsidePhysicalRangeIsNamed) {
  std::string tiny = kGood;
  tiny.replace(tiny.find("[500"), 4, "[1e-300");
  EXPECT_THAT(error_of(tiny), HasSubstr("camera_matrix: fx = 1e-300, expected in [10, 10000] px"));
  std::string huge = kGood;
  huge.replace(huge.find("501"), 3, "2e6");
  EXPECT_THAT(error_of(huge), HasSubstr("camera_matrix: fy = 2e+06, expected in [10, 10000] px"));
}

// kGood with the principal point at (cx, cy) and, if asked, without its depth scale.
std::string camera_text(const std::string& cx, const std::string& cy, bool with_depth_scale) {
  std::ostringstream text;
  text << "image_width: 640\nimage_height: 480\n"
       << "camera_matrix: {rows: 3, cols: 3, data: [500, 0, " << cx << ", 0, 501, " << cy
       << ", 0, 0, 1]}\n";
  if (with_depth_scale) text << "depth_scale_units_per_m: 5000\n";
  return text.str();
}

// A camera file without a depth scale read TUM's 5000 units per metre; OpenNI2 and libfreenect
// give millimetres (1000), so every depth was 5 times too small without a word.
TEST_F(CameraFile, MissingDepthScaleIsAnError) {
  EXPECT_NO_THROW(load_camera_info(write(camera_text("320", "240", true))));
  EXPECT_THAT(error_of(camera_text("320", "240", false)),
              HasSubstr(path_.string() + ": depth_scale_units_per_m is missing"));
}

// cx = 0 passed "inside the image": a principal point on the border is a missing value, not a
// lens.
TEST_F(CameraFile, PrincipalPointOnTheBorderIsRefused) {
  EXPECT_THAT(error_of(camera_text("0", "240", true)),
              HasSubstr(path_.string() + ": camera_matrix: principal point (0, 240), "
                                         "expected 0 < cx < 640 and 0 < cy < 480"));
  EXPECT_THAT(error_of(camera_text("320", "480", true)), HasSubstr("principal point (320, 480)"));
}

}  // namespace
}  // namespace hq::config
