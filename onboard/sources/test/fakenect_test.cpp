// The Kinect source through Debian's fakenect (libfreenect-bin), a libfreenect that replays a
// dump directory instead of talking USB: the real driver API, no hardware. Each test re-runs
// itself in a child process whose LD_LIBRARY_PATH puts fakenect first, because fakenect must
// replace libfreenect when the process starts and exit()s on a dump it cannot read.
#include "hq/base/format_into.hpp"
#include "hq/recording/data_dir.hpp"
#include "hq/recording/tum_sequence.hpp"
#include "hq/sources/camera_sources.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"
#include "hq/testing/loopback_dds.hpp"
#include "hq/testing/process.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <dlfcn.h>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace hq::sources {
namespace {

using ::testing::HasSubstr;
using testing::input_error_message;

// The inverse of the source's conversion (OpenKinect wiki, N. Burrus): raw = (1/z - b) / a.
constexpr double kRaw11A = -0.0030711016;
constexpr double kRaw11B = 3.3309495161;
constexpr std::uint32_t kTicksBeforeWrap = 3'000'000;  // 50 ms at 60 MHz: wraps after frame 0
constexpr double kTicksPerS = 60e6;
constexpr std::int16_t kAccelRaw[3] = {12, -819, 40};  // freenect counts, 819 per g
constexpr double kGravityMps2 = 9.80665;               // libfreenect's GRAVITY

bool running_on_fakenect() {
  void* symbol = dlsym(RTLD_DEFAULT, "freenect_init");
  Dl_info info{};
  return symbol != nullptr && dladdr(symbol, &info) != 0 && info.dli_fname != nullptr &&
         std::strstr(info.dli_fname, "/fakenect/") != nullptr;
}

/// True in the child on fakenect (run the test body); in the parent, runs this one test in a
/// child on fakenect, expects it to pass and returns false.
bool on_fakenect_or_rerun() {
  if (running_on_fakenect()) return true;
#ifndef HQ_FAKENECT_DIR
  ADD_FAILURE() << "built without fakenect (libfreenect-bin's fakenect/libfreenect.so)";
  return false;
#else
  const ::testing::TestInfo* test = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string filter =
      std::string("--gtest_filter=") + test->test_suite_name() + "." + test->name();
  std::fflush(stdout);
  const pid_t child = fork();
  if (child == 0) {
    const char* old = std::getenv("LD_LIBRARY_PATH");
    const std::string path = std::string(HQ_FAKENECT_DIR) + (old ? std::string(":") + old : "");
    setenv("LD_LIBRARY_PATH", path.c_str(), 1);
    char* argv[] = {const_cast<char*>("hq_sources_fakenect_test"),
                    const_cast<char*>(filter.c_str()), nullptr};
    execv("/proc/self/exe", argv);
    _exit(127);
  }
  int status = 0;
  waitpid(child, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0)
      << "the fakenect child failed (status " << status << "), see its output above";
  return false;
#endif
}

std::string fresh_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("hq_fakenect_" + name);
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

std::uint16_t metres_to_raw11(float z_m) {
  if (!(z_m > 0.0f)) return 2047;  // the Kinect's "no depth"
  const long raw = std::lround((1.0 / static_cast<double>(z_m) - kRaw11B) / kRaw11A);
  return static_cast<std::uint16_t>(std::clamp(raw, 0L, 2046L));
}

struct Dump {
  std::vector<std::uint32_t> colour_ticks;
  std::vector<cv::Mat> bgr, depth_m;
};

/// Writes the bundled TUM frames as fakenect-record would have recorded them: per frame an
/// accelerometer state, the depth (11-bit raw, host-endian uint16 after a P5 line) and the
/// colour (RGB after a P6 line), named <type>-<seconds>-<device ticks>.<ext> and listed in
/// INDEX.txt in replay order. passes > 1 records the frames that many times over, one frame
/// period apart, for a replay long enough to outlast DDS discovery.
Dump write_dump(const std::string& tum_dir, const std::string& dir, int passes = 1) {
  const recording::TumSequence sequence(tum_dir);
  Dump dump;
  std::ofstream index(dir + "/INDEX.txt");
  const std::int64_t t0_ns = sequence.frame(0).t_ns;
  const std::int64_t pass_ns =
      sequence.frame(sequence.size() - 1).t_ns - t0_ns + (sequence.frame(1).t_ns - t0_ns);
  cv::Mat bgr, depth_u16, depth_m, rgb;
  cv::Mat raw(480, 640, CV_16UC1);
  for (std::size_t k = 0; k < static_cast<std::size_t>(passes) * sequence.size(); ++k) {
    const std::size_t i = k % sequence.size();
    const std::int64_t offset_ns = static_cast<std::int64_t>(k / sequence.size()) * pass_ns;
    recording::RgbdFrameFiles files = sequence.frame(i);
    files.t_ns += offset_ns;
    files.depth_t_ns += offset_ns;
    sequence.load(i, bgr, depth_u16);
    recording::depth_to_metres(depth_u16, 5000.0, depth_m);
    const auto ticks_since_0 = static_cast<std::uint64_t>(
        std::llround(static_cast<double>(files.t_ns - t0_ns) * 1e-9 * kTicksPerS));
    const auto ticks = static_cast<std::uint32_t>((std::uint64_t{1} << 32) - kTicksBeforeWrap +
                                                  ticks_since_0);  // wraps modulo 2^32
    char name[96];
    hq::format_into(name, "a-{:f}-{}.dump", static_cast<double>(files.depth_t_ns) * 1e-9, ticks);
    const std::int16_t tilt[6] = {kAccelRaw[0], kAccelRaw[1], kAccelRaw[2], 0, 0, 0};
    std::ofstream(dir + "/" + name, std::ios::binary)
        .write(reinterpret_cast<const char*>(tilt), 12);  // sizeof(freenect_raw_tilt_state)
    index << name << '\n';
    for (int v = 0; v < raw.rows; ++v) {
      for (int u = 0; u < raw.cols; ++u) {
        raw.at<std::uint16_t>(v, u) = metres_to_raw11(depth_m.at<float>(v, u));
      }
    }
    hq::format_into(name, "d-{:f}-{}.pgm", static_cast<double>(files.depth_t_ns) * 1e-9, ticks);
    std::ofstream depth_file(dir + "/" + name, std::ios::binary);
    depth_file << "P5 640 480 65535\n";
    depth_file.write(reinterpret_cast<const char*>(raw.data), 640 * 480 * 2);
    index << name << '\n';
    cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
    hq::format_into(name, "r-{:f}-{}.ppm", static_cast<double>(files.t_ns) * 1e-9, ticks);
    std::ofstream colour_file(dir + "/" + name, std::ios::binary);
    colour_file << "P6 640 480 255\n";
    colour_file.write(reinterpret_cast<const char*>(rgb.data), 640 * 480 * 3);
    index << name << '\n';
    dump.colour_ticks.push_back(ticks);
    dump.bgr.push_back(bgr.clone());
    dump.depth_m.push_back(depth_m.clone());
  }
  return dump;
}

CameraSourceOptions kinect_options() {
  CameraSourceOptions options;
  options.camera_file = "calib/kinect_v1.yaml";
  return options;
}

TEST(Fakenect, ReplaysTumFramesWithDeviceStampsDepthAndAccelerometer) {
  if (!on_fakenect_or_rerun()) return;
  const auto data = recording::find_data_dir();
  if (!data) GTEST_SKIP() << "no real data: " << recording::data_dir_search_description();
  // GIVEN a fakenect dump of the 5 bundled fr1_360 frames whose device clock wraps after frame 0
  const std::string dir = fresh_dir("replay");
  const Dump dump = write_dump(*data + "/tum/rgbd_dataset_freiburg1_360", dir);
  setenv("FAKENECT_PATH", dir.c_str(), 1);
  // WHEN the Kinect source reads it through fakenect
  const auto source = open_camera_source("freenect:0", kinect_options());
  EXPECT_THAT(source->describe(), HasSubstr("fakenect replay"));
  RgbdFrame frame;
  std::vector<std::int64_t> t_ns;
  long allocations_after_first = 0;
  // OpenCV grows its worker pool lazily, on its own threads, and the counter is process-wide:
  // keep OpenCV on this thread so that what is counted is the source's own allocation.
  cv::setNumThreads(1);
  while (true) {
    const long before = hq::testing::allocation_count();
    const FrameStatus status = source->next(frame);
    if (status != FrameStatus::kFrame) {
      EXPECT_EQ(status, FrameStatus::kEndOfStream) << source->error();
      break;
    }
    if (!t_ns.empty()) allocations_after_first += hq::testing::allocation_count() - before;
    const std::size_t i = t_ns.size();
    t_ns.push_back(frame.t_ns);
    ASSERT_LT(i, dump.bgr.size()) << "more frames than the dump holds";
    // THEN sizes and types are the project's, colour is the recorded colour, ...
    ASSERT_EQ(frame.bgr.size(), cv::Size(640, 480));
    ASSERT_EQ(frame.depth_m.type(), CV_32FC1);
    ASSERT_EQ(frame.gray.type(), CV_8UC1);
    EXPECT_EQ(cv::norm(frame.bgr, dump.bgr[i], cv::NORM_INF), 0.0) << "frame " << i;
    // ... depth matches within half a disparity step, dz = |a| z^2 / 2, and holes stay holes.
    int mismatched = 0, valid = 0, expected_valid = 0;
    for (int v = 0; v < 480; ++v) {
      for (int u = 0; u < 640; ++u) {
        const float z = dump.depth_m[i].at<float>(v, u);
        const float z_out = frame.depth_m.at<float>(v, u);
        expected_valid += z > 0.0f;
        valid += z_out > 0.0f;
        const auto z_d = static_cast<double>(z);
        if (z > 0.0f &&
            static_cast<double>(std::abs(z_out - z)) > 0.5 * -kRaw11A * z_d * z_d * 1.01 + 1e-5) {
          ++mismatched;
        }
      }
    }
    EXPECT_EQ(mismatched, 0) << "frame " << i;
    EXPECT_EQ(valid, expected_valid) << "frame " << i;
    EXPECT_GT(valid, 640 * 480 / 2) << "frame " << i;
    ASSERT_TRUE(source->accelerometer().has_value());
    EXPECT_NEAR(source->accelerometer()->accel_mps2.x(), kAccelRaw[0] * kGravityMps2 / 819, 1e-9);
    EXPECT_NEAR(source->accelerometer()->accel_mps2.y(), -kGravityMps2, 1e-9);
    EXPECT_EQ(source->accelerometer()->t_ns, frame.t_ns);
  }
  // ... every frame arrives once, stamped by the unwrapped 60 MHz device clock.
  ASSERT_EQ(t_ns.size(), dump.colour_ticks.size());
  for (std::size_t i = 1; i < t_ns.size(); ++i) {
    const std::uint64_t elapsed_ticks =
        static_cast<std::uint32_t>(dump.colour_ticks[i] - dump.colour_ticks[0]);
    EXPECT_EQ(t_ns[i] - t_ns[0], static_cast<std::int64_t>(elapsed_ticks * 50 / 3)) << i;
  }
  EXPECT_LT(dump.colour_ticks[1], dump.colour_ticks[0]) << "the dump should wrap the clock";
  EXPECT_EQ(allocations_after_first, 0);
  EXPECT_THAT(source->error(), HasSubstr("end of the dump"));
  EXPECT_EQ(source->next(frame), FrameStatus::kEndOfStream);
}

TEST(Fakenect, MissingDumpIsAClearError) {
  if (!on_fakenect_or_rerun()) return;
  const std::string dir = fresh_dir("missing");
  setenv("FAKENECT_PATH", dir.c_str(), 1);
  EXPECT_THAT(input_error_message([] { open_camera_source("freenect", kinect_options()); }),
              HasSubstr(dir + "/INDEX.txt: cannot open the fakenect dump index"));
  unsetenv("FAKENECT_PATH");
  EXPECT_THAT(input_error_message([] { open_camera_source("freenect", kinect_options()); }),
              HasSubstr("fakenect: FAKENECT_PATH is not set"));
}

TEST(Fakenect, CorruptDumpIsAClearErrorNamingTheFile) {
  if (!on_fakenect_or_rerun()) return;
  const std::string dir = fresh_dir("corrupt");
  setenv("FAKENECT_PATH", dir.c_str(), 1);
  // A colour frame cut short, as when a recording is interrupted.
  const std::string name = "r-1305031790.645155-4291967296.ppm";
  std::ofstream(dir + "/" + name, std::ios::binary) << "P6 640 480 255\n" << std::string(1000, 'x');
  std::ofstream(dir + "/INDEX.txt") << name << '\n';
  EXPECT_THAT(input_error_message([] { open_camera_source("freenect", kinect_options()); }),
              HasSubstr(dir + "/" + name + ": expected a 'P6 ...' header line and 921600 bytes"));
  // An index line that names no frame, and one whose file is gone.
  std::ofstream(dir + "/INDEX.txt") << "hello.txt\n";
  EXPECT_THAT(input_error_message([] { open_camera_source("freenect", kinect_options()); }),
              HasSubstr("INDEX.txt:1: 'hello.txt', expected r-|d-|a-<seconds>-<ticks>.<ext>"));
  std::ofstream(dir + "/INDEX.txt") << name << '\n';
  std::filesystem::remove(dir + "/" + name);
  EXPECT_THAT(input_error_message([] { open_camera_source("freenect", kinect_options()); }),
              HasSubstr("INDEX.txt:1: " + dir + "/" + name + " is missing"));
}

}  // namespace
}  // namespace hq::sources

namespace hq::sources {
namespace {

/// hq-onboard's frames run through the chain plus those a newer one replaced while the chain
/// was busy (a live camera does not wait): every frame of the dump is one or the other.
int frames_taken_or_skipped(const std::string& output) {
  std::smatch taken;
  std::smatch skipped;
  if (!std::regex_search(output, taken, std::regex(R"(hq-onboard: ([0-9]+) frames from)")) ||
      !std::regex_search(output, skipped, std::regex(R"(camera frames skipped +([0-9]+))"))) {
    return -1;
  }
  return std::stoi(taken[1].str()) + std::stoi(skipped[1].str());
}

// The whole on-board chain on a "live" Kinect: hq-onboard --source freenect, with fakenect in
// place of libfreenect, runs every frame of the dump through odometry, estimator and control
// (or counts it skipped when the chain was busy).
TEST(Fakenect, HqOnboardRunsTheChainOnTheKinect) {
#if !defined(HQ_FAKENECT_DIR) || !defined(HQ_ONBOARD_EXE)
  GTEST_SKIP() << "built without fakenect or hq-onboard";
#else
  if (running_on_fakenect()) GTEST_SKIP() << "runs hq-onboard as its own process";
  const auto data = recording::find_data_dir();
  if (!data) GTEST_SKIP() << "no real data: " << recording::data_dir_search_description();
  const std::string dir = fresh_dir("onboard");
  (void)write_dump(*data + "/tum/rgbd_dataset_freiburg1_360", dir);
  const std::string command = std::string("LD_LIBRARY_PATH=") + HQ_FAKENECT_DIR +
                              " FAKENECT_PATH=" + dir + " " + HQ_ONBOARD_EXE +
                              " --source freenect --duration-s 20 2>&1";
  std::FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, pipe)) output += buffer;
  const int status = pclose(pipe);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << output;
  EXPECT_EQ(frames_taken_or_skipped(output), 5) << output;
  EXPECT_THAT(output, HasSubstr("fakenect replay"));
  EXPECT_THAT(output, HasSubstr("total"));  // the stage-timing table
#endif
}

// The same Kinect with --link: a ground station on a private domain receives the vehicle's
// states while hq-onboard runs the dump, the camera read on its own thread.
TEST(Fakenect, HqOnboardOnTheKinectReachesAGroundStationOverTheLink) {
#if !defined(HQ_FAKENECT_DIR) || !defined(HQ_ONBOARD_EXE) || !defined(HQ_GROUND_EXE)
  GTEST_SKIP() << "built without fakenect, hq-onboard or hq-ground";
#else
  if (running_on_fakenect()) GTEST_SKIP() << "runs hq-onboard as its own process";
  const auto data = recording::find_data_dir();
  if (!data) GTEST_SKIP() << "no real data: " << recording::data_dir_search_description();
  const std::string dir = fresh_dir("onboard_link");
  // The vehicle sends a state per frame and the state topic keeps no history: five frames
  // (0.13 s) could all go out before discovery under load, so the dump plays them six times.
  constexpr int kPasses = 6;
  (void)write_dump(*data + "/tum/rgbd_dataset_freiburg1_360", dir, kPasses);
  hq::testing::use_loopback_dds();
  const std::string domain = std::to_string(hq::testing::private_domain_id(101));
  hq::testing::Process ground({HQ_GROUND_EXE, "--device", "sim", "--headless", "--domain-id",
                               domain, "--insecure", "--duration-s", "6"},
                              dir + "/ground.out");
  ASSERT_TRUE(ground.started());
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const std::string command = std::string("LD_LIBRARY_PATH=") + HQ_FAKENECT_DIR +
                              " FAKENECT_PATH=" + dir + " " + HQ_ONBOARD_EXE +
                              " --source freenect --link --insecure --domain-id " + domain +
                              " --duration-s 3 2>&1";
  std::FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, pipe)) output += buffer;
  const int status = pclose(pipe);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << output;
  EXPECT_EQ(frames_taken_or_skipped(output), 5 * kPasses) << output;
  EXPECT_THAT(output, HasSubstr("link on domain " + domain));
  EXPECT_EQ(ground.wait_exit(20.0), 0);
  std::ifstream in(dir + "/ground.out");
  const std::string ground_out((std::istreambuf_iterator<char>(in)),
                               std::istreambuf_iterator<char>());
  // Each frame is a state; those sent before discovery completes are lost, so at least one of
  // the 30 reaches the station.
  const std::size_t at = ground_out.find("received");
  ASSERT_NE(at, std::string::npos) << ground_out;
  EXPECT_GE(std::atoi(ground_out.c_str() + ground_out.find_first_of("0123456789", at)), 1)
      << ground_out;
#endif
}

}  // namespace
}  // namespace hq::sources
