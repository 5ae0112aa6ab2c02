// SitlFrameSource over a frame channel written in this process: intrinsics from the header,
// non-blocking next() with its reasons, gray and colour channels, truth, no allocation.
#include "hq/sources/sitl_frame_source.hpp"

#include "hq/frame_channel/frame_channel.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <unistd.h>

namespace {

using hq::frame_channel::ChannelGeometry;
using hq::frame_channel::FrameChannelWriter;
using hq::frame_channel::SitlTruth;
using hq::sources::FrameStatus;
using hq::sources::RgbdFrame;
using hq::sources::SitlFrameSource;
using ::testing::HasSubstr;

std::string unique_name(const std::string& what) {
  return "test-source-" + what + "-" + std::to_string(getpid());
}

ChannelGeometry geometry(int channels) {
  ChannelGeometry g;
  g.width = 32;
  g.height = 24;
  g.channels = channels;
  g.fx = 27.7;
  g.fy = 27.7;
  g.cx = 15.5;
  g.cy = 11.5;
  return g;
}

TEST(SitlFrameSource, ColourChannelGivesBgrGrayDepthStampTruthAndTheHeaderIntrinsics) {
  const std::string name = unique_name("colour");
  FrameChannelWriter writer(name, geometry(3));
  SitlFrameSource source(name);
  EXPECT_EQ(source.camera().fx, 27.7);
  EXPECT_EQ(source.camera().cy, 11.5);
  EXPECT_EQ(source.camera().width, 32);
  EXPECT_THAT(source.describe(), HasSubstr("sitl:/hq-" + name + " (32x24 BGR-D"));
  writer.set_time_origin(1'000'000);
  EXPECT_EQ(source.fc_time_origin_ns(), 1'000'000);

  RgbdFrame frame;
  EXPECT_EQ(source.next(frame), FrameStatus::kNoFrame);
  EXPECT_EQ(source.error(), "no new frame");
  EXPECT_FALSE(source.truth().has_value());

  const cv::Mat bgr(24, 32, CV_8UC3, cv::Scalar(10, 100, 200));
  const cv::Mat depth(24, 32, CV_32FC1, cv::Scalar(2.5));
  SitlTruth truth;
  truth.v_H_mps = {0.3, 0.0, -0.1};
  truth.on_ground = false;
  ASSERT_TRUE(writer.publish(5'000'000'000, bgr, depth, &truth));
  ASSERT_EQ(source.next(frame), FrameStatus::kFrame);
  EXPECT_EQ(frame.t_ns, 5'000'000'000);
  EXPECT_EQ(frame.bgr.type(), CV_8UC3);
  EXPECT_EQ(frame.bgr.at<cv::Vec3b>(3, 4), cv::Vec3b(10, 100, 200));
  ASSERT_EQ(frame.gray.type(), CV_8UC1);
  EXPECT_NEAR(frame.gray.at<std::uint8_t>(3, 4), 0.114 * 10 + 0.587 * 100 + 0.299 * 200, 1.0);
  EXPECT_EQ(frame.depth_m.at<float>(23, 31), 2.5f);
  ASSERT_TRUE(source.truth().has_value());
  EXPECT_EQ(source.truth()->v_H_mps[0], 0.3);
  EXPECT_FALSE(source.truth()->on_ground);

  EXPECT_EQ(source.next(frame), FrameStatus::kNoFrame) << "non-blocking, nothing new";
  EXPECT_EQ(source.error(), "no new frame");
}

TEST(SitlFrameSource, GrayChannelFillsGrayAndDepthAndNextAllocatesNothing) {
  const std::string name = unique_name("gray");
  FrameChannelWriter writer(name, geometry(1));
  SitlFrameSource source(name);
  const cv::Mat gray(24, 32, CV_8UC1, cv::Scalar(77));
  const cv::Mat depth(24, 32, CV_32FC1, cv::Scalar(1.0));
  RgbdFrame frame;
  writer.publish(1, gray, depth, nullptr);
  ASSERT_EQ(source.next(frame), FrameStatus::kFrame);
  EXPECT_TRUE(frame.bgr.empty());
  EXPECT_EQ(frame.gray.at<std::uint8_t>(0, 0), 77);
  EXPECT_FALSE(source.truth().has_value()) << "this frame carried no truth";
  const long before = hq::testing::allocation_count();
  for (int i = 2; i < 50; ++i) {
    writer.publish(i, gray, depth, nullptr);
    ASSERT_EQ(source.next(frame), FrameStatus::kFrame);
    ASSERT_EQ(source.next(frame), FrameStatus::kNoFrame);
  }
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
}

TEST(SitlFrameSource, AClosedWriterReadsAsGone) {
  const std::string name = unique_name("gone");
  auto writer = std::make_unique<FrameChannelWriter>(name, geometry(1));
  SitlFrameSource source(name);
  writer.reset();
  RgbdFrame frame;
  EXPECT_EQ(source.next(frame), FrameStatus::kNoFrame);
  EXPECT_EQ(source.error(), "SITL writer gone");
}

TEST(SitlFrameSource, AMissingChannelOrOneWithoutIntrinsicsIsAnInputError) {
  const std::string name = unique_name("none");
  EXPECT_THAT(hq::testing::input_error_message([&] { SitlFrameSource s(name); }),
              HasSubstr("frame channel /hq-" + name + ": no such shared-memory object"));
  FrameChannelWriter writer(name, 32, 24, 1);
  EXPECT_THAT(hq::testing::input_error_message([&] { SitlFrameSource s(name); }),
              HasSubstr("carries no intrinsics"));
}

}  // namespace
