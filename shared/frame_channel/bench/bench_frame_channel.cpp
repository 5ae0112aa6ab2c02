// hq-bench-frame-channel: publish and take_latest cost per frame at the SITL geometries, beside
// the floor of the same run (memcpy of the same bytes between two buffers), so the figures say
// what the channel adds to copying. Median and p90 over 300 frames; not run by ctest.
#include "hq/base/monotonic_clock.hpp"
#include "hq/base/program.hpp"
#include "hq/frame_channel/frame_channel.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fmt/format.h>
#include <optional>
#include <string>
#include <unistd.h>
#include <vector>

namespace {

using hq::monotonic_now_ns;

struct Figures {
  double median_us, p90_us;
};

Figures summarise(std::vector<double>& us) {
  std::sort(us.begin(), us.end());
  return {us[us.size() / 2], us[us.size() * 9 / 10]};
}

void bench(int width, int height, int channels) {
  constexpr int kFrames = 300;
  const std::string name = "bench-" + std::to_string(getpid());
  hq::frame_channel::FrameChannelWriter writer(name, width, height, channels);
  hq::frame_channel::FrameChannelReader reader(name);
  cv::Mat image(height, width, CV_8UC(channels), cv::Scalar::all(7));
  cv::Mat depth(height, width, CV_32FC1, cv::Scalar(1.5));
  cv::Mat image_out, depth_out;
  hq::frame_channel::FrameInfo info;
  hq::frame_channel::SitlTruth truth;
  std::vector<double> publish_us, take_us, floor_us;
  const std::size_t bytes = image.total() * image.elemSize() + depth.total() * depth.elemSize();
  std::vector<unsigned char> a(bytes, 1), b(bytes);
  for (int i = 0; i < kFrames; ++i) {
    const std::int64_t t0 = monotonic_now_ns();
    writer.publish(i, image, depth, &truth);
    const std::int64_t t1 = monotonic_now_ns();
    reader.take_latest(image_out, depth_out, info);
    const std::int64_t t2 = monotonic_now_ns();
    std::memcpy(b.data(), a.data(), bytes);
    const std::int64_t t3 = monotonic_now_ns();
    if (i == 0) continue;  // first take sizes the buffers
    publish_us.push_back(static_cast<double>(t1 - t0) * 1e-3);
    take_us.push_back(static_cast<double>(t2 - t1) * 1e-3);
    floor_us.push_back(static_cast<double>(t3 - t2) * 1e-3);
  }
  const Figures p = summarise(publish_us), t = summarise(take_us), f = summarise(floor_us);
  fmt::print(
      "{:4}x{:<4} {}-D {:7.2f} MB: publish {:6.0f} / {:6.0f} us, take_latest {:6.0f} / {:6.0f} us, "
      "memcpy floor {:6.0f} / {:6.0f} us (median / p90)\n",
      width, height, channels == 3 ? "BGR " : "gray", static_cast<double>(bytes) / 1e6, p.median_us,
      p.p90_us, t.median_us, t.p90_us, f.median_us, f.p90_us);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"hq-bench-frame-channel: the shared-memory frame channel's publish-to-read time"};
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  bench(320, 240, 1);
  bench(320, 240, 3);
  bench(640, 480, 1);
  bench(640, 480, 3);
  return 0;
}
