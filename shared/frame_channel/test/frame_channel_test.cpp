// The shared-memory frame channel: round trip, a fast writer never tearing a frame, missed frames,
// bad channels named in errors, a dead, closed and restarted writer, no allocation per frame.
#include "hq/frame_channel/frame_channel.hpp"

#include "hq/base/error.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <fcntl.h>
#include <fmt/format.h>
#include <string>
#include <sys/mman.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

using hq::frame_channel::ChannelGeometry;
using hq::frame_channel::FrameChannelReader;
using hq::frame_channel::FrameChannelWriter;
using hq::frame_channel::FrameInfo;
using hq::frame_channel::ReaderOptions;
using hq::frame_channel::SitlTruth;
using hq::testing::input_error_message;
using ::testing::HasSubstr;

/// A channel name no other test (or test process) uses.
std::string unique_name(const std::string& what) {
  return "test-" + what + "-" + std::to_string(getpid());
}

/// Fills image and depth with the frame's index, so a torn copy shows as mixed values.
void fill(cv::Mat& image, cv::Mat& depth_m, std::uint64_t index) {
  image.setTo(cv::Scalar::all(static_cast<double>(index & 0xFFu)));
  depth_m.setTo(cv::Scalar(static_cast<double>(index & 0xFFu)));
}

bool uniform(const cv::Mat& image, const cv::Mat& depth_m, std::uint64_t index) {
  const cv::Mat bytes = image.reshape(1);
  for (int r = 0; r < bytes.rows; ++r) {
    for (int c = 0; c < bytes.cols; ++c) {
      if (bytes.at<std::uint8_t>(r, c) != (index & 0xFFu)) return false;
    }
  }
  for (int r = 0; r < depth_m.rows; ++r) {
    for (int c = 0; c < depth_m.cols; ++c) {
      if (depth_m.at<float>(r, c) != static_cast<float>(index & 0xFFu)) return false;
    }
  }
  return true;
}

TEST(FrameChannel, RoundTripCarriesGeometryIntrinsicsStampImageDepthAndTruth) {
  const std::string name = unique_name("roundtrip");
  ChannelGeometry g;
  g.width = 8;
  g.height = 6;
  g.channels = 3;
  g.fx = 7.5;
  g.fy = 7.25;
  g.cx = 3.5;
  g.cy = 2.5;
  FrameChannelWriter writer(name, g);
  EXPECT_EQ(writer.name(), "/hq-" + name);

  FrameChannelReader reader(name);
  EXPECT_EQ(reader.geometry().width, 8);
  EXPECT_EQ(reader.geometry().height, 6);
  EXPECT_EQ(reader.geometry().channels, 3);
  EXPECT_EQ(reader.geometry().fx, 7.5);
  EXPECT_EQ(reader.geometry().cy, 2.5);
  EXPECT_EQ(reader.writer_pid(), getpid());
  EXPECT_TRUE(reader.writer_alive());
  EXPECT_EQ(reader.time_origin_ns(), 0) << "not set yet";
  writer.set_time_origin(42'000'000'000);
  EXPECT_EQ(reader.time_origin_ns(), 42'000'000'000);

  cv::Mat image(6, 8, CV_8UC3);
  cv::Mat depth(6, 8, CV_32FC1);
  cv::randu(image, 0, 255);
  cv::randu(depth, 0.5, 4.0);
  SitlTruth truth;
  truth.v_H_mps = {0.5, -0.25, 0.125};
  truth.p_W_m = {1.0, 2.0, 1.5};
  truth.on_ground = false;

  cv::Mat image_out, depth_out;
  FrameInfo info;
  EXPECT_FALSE(reader.take_latest(image_out, depth_out, info)) << "nothing published yet";
  ASSERT_TRUE(writer.publish(123'456'789, image, depth, &truth));
  ASSERT_TRUE(reader.take_latest(image_out, depth_out, info));
  EXPECT_EQ(info.index, 0u);
  EXPECT_EQ(info.t_ns, 123'456'789);
  ASSERT_TRUE(info.has_truth);
  EXPECT_EQ(info.truth.v_H_mps[1], -0.25);
  EXPECT_EQ(info.truth.p_W_m[2], 1.5);
  EXPECT_FALSE(info.truth.on_ground);
  EXPECT_EQ(cv::norm(image, image_out, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(depth, depth_out, cv::NORM_INF), 0.0);
  EXPECT_FALSE(reader.take_latest(image_out, depth_out, info)) << "taken already";

  ASSERT_TRUE(writer.publish(2, image, depth, nullptr));
  ASSERT_TRUE(reader.take_latest(image_out, depth_out, info));
  EXPECT_FALSE(info.has_truth);
}

TEST(FrameChannel, PublishRefusesAFrameOfTheWrongTypeOrSize) {
  FrameChannelWriter writer(unique_name("mismatch"), 8, 6, 1);
  cv::Mat depth(6, 8, CV_32FC1, cv::Scalar(1.0));
  EXPECT_FALSE(writer.publish(0, cv::Mat(6, 8, CV_8UC3), depth, nullptr));
  EXPECT_FALSE(writer.publish(0, cv::Mat(6, 9, CV_8UC1), depth, nullptr));
  EXPECT_FALSE(writer.publish(0, cv::Mat(6, 8, CV_8UC1), cv::Mat(6, 8, CV_16UC1), nullptr));
  EXPECT_TRUE(writer.publish(0, cv::Mat(6, 8, CV_8UC1), depth, nullptr));
  EXPECT_EQ(writer.published(), 1u);
}

TEST(FrameChannel, ReaderTakesTheNewestFrameAndCountsTheOnesItMissed) {
  const std::string name = unique_name("missed");
  FrameChannelWriter writer(name, 4, 4, 1);
  FrameChannelReader reader(name);
  cv::Mat image(4, 4, CV_8UC1), depth(4, 4, CV_32FC1), image_out, depth_out;
  FrameInfo info;
  for (std::uint64_t i = 0; i < 3; ++i) {
    fill(image, depth, i);
    writer.publish(static_cast<std::int64_t>(i), image, depth, nullptr);
  }
  ASSERT_TRUE(reader.take_latest(image_out, depth_out, info));
  EXPECT_EQ(info.index, 2u);
  EXPECT_EQ(reader.frames_missed(), 0u) << "frames before the first take are not missed";
  for (std::uint64_t i = 3; i < 10; ++i) {
    fill(image, depth, i);
    writer.publish(static_cast<std::int64_t>(i), image, depth, nullptr);
  }
  ASSERT_TRUE(reader.take_latest(image_out, depth_out, info));
  EXPECT_EQ(info.index, 9u);
  EXPECT_TRUE(uniform(image_out, depth_out, 9));
  EXPECT_EQ(reader.frames_missed(), 6u);
  EXPECT_EQ(reader.frames_taken(), 2u);
}

TEST(FrameChannel, AFastWriterThreadNeverHandsTheReaderATornFrame) {
  const std::string name = unique_name("torn");
  constexpr int kW = 64, kH = 48;
  FrameChannelWriter writer(name, kW, kH, 3);
  FrameChannelReader reader(name);
  // Frames filled beforehand, so the writer publishes as fast as it can copy and laps the
  // reader's ring often.
  std::vector<cv::Mat> images(256), depths(256);
  for (std::uint64_t i = 0; i < 256; ++i) {
    images[i].create(kH, kW, CV_8UC3);
    depths[i].create(kH, kW, CV_32FC1);
    fill(images[i], depths[i], i);
  }
  std::atomic<bool> done{false};
  constexpr std::uint64_t kFrames = 200'000;
  std::thread producer([&] {
    for (std::uint64_t i = 0; i < kFrames; ++i) {
      writer.publish(static_cast<std::int64_t>(i), images[i % 256], depths[i % 256], nullptr);
    }
    done.store(true);
  });
  cv::Mat image_out, depth_out;
  FrameInfo info;
  std::uint64_t taken = 0, torn = 0, first = 0, last = 0;
  bool out_of_order = false;
  while (!done.load()) {
    if (!reader.take_latest(image_out, depth_out, info)) continue;
    if (taken == 0) first = info.index;
    if (taken > 0 && info.index <= last) out_of_order = true;
    last = info.index;
    ++taken;
    if (!uniform(image_out, depth_out, info.index) ||
        info.t_ns != static_cast<std::int64_t>(info.index)) {
      ++torn;
    }
  }
  producer.join();
  EXPECT_GT(taken, 10u);
  EXPECT_EQ(torn, 0u);
  EXPECT_FALSE(out_of_order);
  EXPECT_EQ(reader.frames_taken() + reader.frames_missed(), last - first + 1)
      << "every index from the first take to the last is either taken or missed";
  fmt::print("torn-frame test: {} taken, {} missed, {} retried copies\n",
             static_cast<unsigned long long>(taken),
             static_cast<unsigned long long>(reader.frames_missed()),
             static_cast<unsigned long long>(reader.retries()));
}

TEST(FrameChannel, AMissingChannelIsAnInputErrorNamingIt) {
  const std::string name = unique_name("absent");
  const std::string message = input_error_message([&] { FrameChannelReader reader(name); });
  EXPECT_THAT(message, HasSubstr("/hq-" + name));
  EXPECT_THAT(message, HasSubstr("no such shared-memory object"));
}

TEST(FrameChannel, ABadNameIsAnInputError) {
  EXPECT_THAT(input_error_message([] { FrameChannelWriter w("a/b", 4, 4, 1); }),
              HasSubstr("frame channel name \"a/b\""));
  EXPECT_THAT(input_error_message([] { FrameChannelReader r(""); }),
              HasSubstr("expected 1..200 characters"));
}

TEST(FrameChannel, AReaderExpectingAnotherSizeIsAnInputError) {
  const std::string name = unique_name("size");
  FrameChannelWriter writer(name, 320, 240, 1);
  ReaderOptions options;
  options.expect_width = 640;
  options.expect_height = 480;
  const std::string message = input_error_message([&] { FrameChannelReader r(name, options); });
  EXPECT_THAT(message, HasSubstr("/hq-" + name));
  EXPECT_THAT(message, HasSubstr("frames are 320x240, expected 640x480"));
}

/// A shared-memory object with the given first two words (magic, version), 4 KiB long.
void make_raw_object(const std::string& shm, std::uint32_t magic, std::uint32_t version) {
  const int fd = shm_open(shm.c_str(), O_RDWR | O_CREAT | O_TRUNC, 0600);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(ftruncate(fd, 4096), 0);
  const std::uint32_t words[2] = {magic, version};
  ASSERT_EQ(write(fd, words, sizeof(words)), static_cast<ssize_t>(sizeof(words)));
  close(fd);
}

TEST(FrameChannel, AnObjectOfAnotherKindOrVersionIsAnInputError) {
  const std::string name = unique_name("kind");
  const std::string shm = "/hq-" + name;
  make_raw_object(shm, 0x12345678u, 1);
  EXPECT_THAT(input_error_message([&] { FrameChannelReader r(name); }),
              HasSubstr(shm + ": not a frame channel (bad magic)"));
  make_raw_object(shm, 0x43465148u, 99);
  EXPECT_THAT(input_error_message([&] { FrameChannelReader r(name); }),
              HasSubstr(shm + ": version 99, expected 1"));
  {
    // A writer replaces what no live writer owns.
    FrameChannelWriter writer(name, 4, 4, 1);
    FrameChannelReader reader(name);
    EXPECT_EQ(reader.geometry().width, 4);
  }
  EXPECT_LT(shm_open(shm.c_str(), O_RDONLY, 0), 0) << "the writer unlinks its channel";
}

TEST(FrameChannel, ASecondWriterOnTheSameNameIsRefused) {
  const std::string name = unique_name("second");
  FrameChannelWriter first(name, 4, 4, 1);
  const std::string message =
      input_error_message([&] { FrameChannelWriter second(name, 4, 4, 1); });
  EXPECT_THAT(message, HasSubstr("/hq-" + name + ": frame channel in use by a live writer (pid " +
                                 std::to_string(getpid())));
}

TEST(FrameChannel, AWriterWhoseHeartbeatStopsCountsAsGoneUntilItBeatsAgain) {
  const std::string name = unique_name("dead");
  FrameChannelWriter writer(name, 4, 4, 1);
  ReaderOptions options;
  options.dead_after_ns = 50'000'000;
  FrameChannelReader reader(name, options);
  cv::Mat image(4, 4, CV_8UC1, cv::Scalar(1)), depth(4, 4, CV_32FC1, cv::Scalar(1.0));
  cv::Mat image_out, depth_out;
  FrameInfo info;
  writer.publish(1, image, depth, nullptr);
  ASSERT_TRUE(reader.take_latest(image_out, depth_out, info));
  EXPECT_TRUE(reader.writer_alive());
  std::this_thread::sleep_for(std::chrono::milliseconds(120));
  EXPECT_FALSE(reader.take_latest(image_out, depth_out, info));
  EXPECT_FALSE(reader.writer_alive());
  writer.heartbeat();
  EXPECT_FALSE(reader.take_latest(image_out, depth_out, info));
  EXPECT_TRUE(reader.writer_alive());
}

TEST(FrameChannel, AClosedWriterIsGoneAtOnceAndARestartedOneIsFollowed) {
  const std::string name = unique_name("restart");
  ReaderOptions options;
  options.reopen_interval_ns = 0;
  cv::Mat image(4, 4, CV_8UC1), depth(4, 4, CV_32FC1), image_out, depth_out;
  FrameInfo info;
  auto writer = std::make_unique<FrameChannelWriter>(name, 4, 4, 1);
  FrameChannelReader reader(name, options);
  for (std::uint64_t i = 0; i < 5; ++i) {
    fill(image, depth, i);
    writer->publish(static_cast<std::int64_t>(i), image, depth, nullptr);
  }
  writer.reset();
  ASSERT_TRUE(reader.take_latest(image_out, depth_out, info)) << "published before closing";
  EXPECT_FALSE(reader.writer_alive());
  EXPECT_EQ(info.index, 4u);
  EXPECT_FALSE(reader.take_latest(image_out, depth_out, info));

  writer = std::make_unique<FrameChannelWriter>(name, 4, 4, 1);
  fill(image, depth, 7);
  writer->publish(70, image, depth, nullptr);
  ASSERT_TRUE(reader.take_latest(image_out, depth_out, info));
  EXPECT_TRUE(reader.writer_alive());
  EXPECT_EQ(reader.writer_restarts(), 1u);
  EXPECT_EQ(info.index, 0u) << "the new writer counts from 0";
  EXPECT_EQ(info.t_ns, 70);
  EXPECT_TRUE(uniform(image_out, depth_out, 7));
}

TEST(FrameChannel, PublishAndTakeAllocateNothingAfterTheFirstFrame) {
  const std::string name = unique_name("alloc");
  FrameChannelWriter writer(name, 640, 480, 3);
  FrameChannelReader reader(name);
  cv::Mat image(480, 640, CV_8UC3, cv::Scalar::all(3)), depth(480, 640, CV_32FC1);
  cv::Mat image_out, depth_out;
  FrameInfo info;
  SitlTruth truth;
  writer.publish(0, image, depth, &truth);
  ASSERT_TRUE(reader.take_latest(image_out, depth_out, info));
  const long before = hq::testing::allocation_count();
  int taken = 0;
  const auto start = std::chrono::steady_clock::now();
  constexpr int kFrames = 200;
  for (int i = 1; i <= kFrames; ++i) {
    writer.publish(i, image, depth, &truth);
    taken += reader.take_latest(image_out, depth_out, info) ? 1 : 0;
  }
  const double us_per_pair =
      std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count() /
      kFrames;
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
  EXPECT_EQ(taken, kFrames);
  fmt::print("640x480 BGR-D: publish + take_latest {:.0f} us per frame\n", us_per_pair);
}

}  // namespace
