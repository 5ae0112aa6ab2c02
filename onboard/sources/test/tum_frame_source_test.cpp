#include "hq/sources/tum_frame_source.hpp"

#include "hq/recording/data_dir.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace hq::sources {
namespace {

using ::testing::HasSubstr;

TEST(TumFrameSource, DeliversUndistortedGrayAndMetricDepthFromTheBundledSequence) {
  const auto data = recording::find_data_dir();
  if (!data) GTEST_SKIP() << "no real data: " << recording::data_dir_search_description();
  const std::string dir = *data + "/tum/rgbd_dataset_freiburg1_360";
  TumFrameSource source(dir, config::load_camera_info("calib/tum_fr1.yaml"));
  RgbdFrame frame;
  int count = 0;
  std::int64_t last_t_ns = 0;
  double sequence_max_m = 0.0;
  while (source.next(frame) == FrameStatus::kFrame) {
    EXPECT_EQ(frame.gray.type(), CV_8UC1);
    EXPECT_EQ(frame.depth_m.type(), CV_32FC1);
    EXPECT_GT(frame.t_ns, last_t_ns);
    last_t_ns = frame.t_ns;
    double min_m = 0.0, max_m = 0.0;
    cv::minMaxLoc(frame.depth_m, &min_m, &max_m);
    EXPECT_GT(max_m, 1.0);
    EXPECT_LT(max_m, 3.5);
    sequence_max_m = std::max(sequence_max_m, max_m);
    ++count;
  }
  EXPECT_EQ(count, 5);
  // SOURCES.md: z from 0.69 to 3.20 m at 5000 units per metre over the five frames.
  EXPECT_NEAR(sequence_max_m, 3.2, 0.1);
  EXPECT_EQ(source.next(frame), FrameStatus::kEndOfStream);
}

TEST(TumFrameSource, CameraOfAnotherSizeIsRejected) {
  const auto data = recording::find_data_dir();
  if (!data) GTEST_SKIP() << "no real data: " << recording::data_dir_search_description();
  config::CameraInfo small = config::load_camera_info("calib/tum_fr1.yaml");
  small.width = 320;
  small.height = 240;
  small.cx /= 2;
  small.cy /= 2;
  try {
    TumFrameSource source(*data + "/tum/rgbd_dataset_freiburg1_360", small);
    FAIL() << "accepted a 320x240 camera for 640x480 images";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("images are 640x480 but the camera file says 320x240"));
  }
}

}  // namespace
}  // namespace hq::sources
