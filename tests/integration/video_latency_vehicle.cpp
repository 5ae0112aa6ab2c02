// hq-video-latency-vehicle: a stand-in vehicle for measuring the video latency of hq-ground's
// console without the simulator: the real LinkBridge (JPEG encode, states, heartbeats with their
// echo) publishing a synthetic 640x480 camera at 30 Hz whose frames are stamped at "exposure",
// before the image is drawn and encoded, on a clock 3 s ahead of the ground's. Not run by ctest.
//   hq-video-latency-vehicle --seconds 15 --insecure [--link-impair delay_ms=100] &
//   xvfb-run hq-ground --device sim --duration-s 12 --insecure --state-json out.json
// (or --security-dir KEYS on both, with keys made by hq-keys)

#include "hq/base/tool_main.hpp"
#include "hq/link/config.hpp"
#include "hq/link_bridge/link_bridge.hpp"

#include <CLI/CLI.hpp>
#include <opencv2/imgproc.hpp>

#include <cerrno>
#include <cstdio>
#include <ctime>
#include <fmt/format.h>
#include <vector>

namespace {

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

void sleep_until(std::int64_t t_ns) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(t_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(t_ns % 1'000'000'000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

int run(int argc, char** argv) {
  CLI::App app{"a stand-in vehicle streaming a synthetic camera for the video latency"};
  double seconds = 15.0;
  hq::link::LinkOverrides overrides;
  app.add_option("--seconds", seconds, "how long to stream")->check(CLI::Range(1.0, 3600.0));
  hq::link::add_link_options(app, overrides);
  CLI11_PARSE(app, argc, argv);
  hq::link::LinkConfig link;
  hq::link::apply_overrides(overrides, link);
  hq::link_bridge::BridgeOptions options;
  options.camera_rate_hz = 30.0;
  hq::link_bridge::LinkBridge bridge(link, hq::link_bridge::FailsafeConfig{}, options);
  constexpr std::int64_t kVehicleAheadNs = 3'000'000'000;
  cv::Mat image(480, 640, CV_8UC3);
  std::vector<hq::pipeline::ModeRequest> requests;
  const std::int64_t start_ns = monotonic_ns();
  std::int64_t next_frame_ns = start_ns;
  int frames = 0;
  for (std::int64_t step_ns = start_ns;
       step_ns < start_ns + static_cast<std::int64_t>(seconds * 1e9); step_ns += 5'000'000) {
    sleep_until(step_ns);
    const std::int64_t t_ns = monotonic_ns() + kVehicleAheadNs;
    requests.clear();
    bridge.poll(t_ns, requests);
    if (step_ns >= next_frame_ns) {
      next_frame_ns += 33'333'333;
      // Exposure now; drawing stands for readout, then the bridge encodes and publishes.
      const int shift = (frames * 7) % 640;
      for (int y = 0; y < image.rows; ++y) {
        auto* row = image.ptr<cv::Vec3b>(y);
        for (int x = 0; x < image.cols; ++x) {
          row[x] = cv::Vec3b(static_cast<uchar>((x + shift) & 255), static_cast<uchar>(y & 255),
                             static_cast<uchar>(((x ^ y) + shift) & 255));
        }
      }
      cv::putText(image, std::to_string(frames), {20, 60}, cv::FONT_HERSHEY_SIMPLEX, 2.0,
                  {255, 255, 255}, 3);
      frames += bridge.publish_camera(t_ns, image) ? 1 : 0;
      hq::pipeline::ChainOutput out;
      out.t_ns = t_ns;
      bridge.publish_state(out);
    }
  }
  fmt::print("hq-video-latency-vehicle: {} frames published\n", frames);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return hq::run_tool("hq-video-latency-vehicle", argc, argv, run);
}
