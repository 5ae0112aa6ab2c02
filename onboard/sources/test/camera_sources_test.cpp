#include "hq/sources/camera_sources.hpp"

#include "hq/recording/data_dir.hpp"
#include "hq/recording/tum_sequence.hpp"
#include "hq/sources/tum_frame_source.hpp"
#include "hq/sources/tum_recorder.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace hq::sources {
namespace {

using ::testing::HasSubstr;
using testing::input_error_message;

std::string fresh_dir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / ("hq_sources_test_" + name);
  std::filesystem::remove_all(dir);
  return dir.string();
}

TEST(CameraSpec, SplitsKindAndAddressAtTheFirstColon) {
  for (const std::string& kind : available_camera_sources()) {
    const CameraSpec bare = parse_camera_spec(kind);
    EXPECT_EQ(bare.kind, kind);
    EXPECT_EQ(bare.address, "");
  }
#ifdef HQ_HAVE_OPENNI2
  const CameraSpec file = parse_camera_spec("openni2:/data/a:b.oni");
  EXPECT_EQ(file.kind, "openni2");
  EXPECT_EQ(file.address, "/data/a:b.oni");
#endif
#ifdef HQ_HAVE_FREENECT
  EXPECT_EQ(parse_camera_spec("freenect:2").address, "2");
#endif
}

TEST(CameraSpec, ListsExactlyTheKindsCompiledIn) {
  std::vector<std::string> expected;
#ifdef HQ_HAVE_OPENNI2
  expected.emplace_back("openni2");
#endif
#ifdef HQ_HAVE_FREENECT
  expected.emplace_back("freenect");
#endif
  EXPECT_EQ(available_camera_sources(), expected);
}

TEST(CameraSpec, UnknownKindIsRejectedWithTheSpec) {
  EXPECT_THAT(input_error_message([] { parse_camera_spec("realsense:0"); }),
              HasSubstr("--source realsense:0: unknown camera kind 'realsense', expected "
                        "openni2[:uri] or freenect[:index]"));
}

#ifdef HQ_HAVE_FREENECT
TEST(FreenectSource, NonNumericIndexIsRejected) {
  EXPECT_THAT(input_error_message([] { parse_camera_spec("freenect:-1"); }),
              HasSubstr("device index '-1', expected a non-negative integer"));
}

TEST(FreenectSource, AbsentKinectIsAClearErrorNamingTheIndex) {
  CameraSourceOptions options;
  options.camera_file = "calib/kinect_v1.yaml";
  // GIVEN no Kinect on this machine's USB (the real libfreenect, not fakenect).
  EXPECT_THAT(input_error_message([&] { open_camera_source("freenect:3", options); }),
              HasSubstr("freenect:3: no Kinect at index 3"));
}

TEST(FreenectSource, ModeTheKinectDoesNotOfferIsRejected) {
  CameraSourceOptions options;
  options.width = 320;
  options.height = 240;
  EXPECT_THAT(input_error_message([&] { open_camera_source("freenect", options); }),
              HasSubstr("freenect:0: mode 320x240@30 is not offered"));
}

TEST(FreenectSource, MissingCameraFileIsNamed) {
  CameraSourceOptions options;
  options.camera_file = "calib/no_such_camera.yaml";
  EXPECT_THAT(input_error_message([&] { open_camera_source("freenect", options); }),
              HasSubstr("calib/no_such_camera.yaml"));
}
#endif

#ifdef HQ_HAVE_OPENNI2
TEST(Openni2Source, AbsentDeviceIsAClearErrorNamingTheUri) {
  const std::string uri = "1d27/0601@3/7";  // an Xtion's USB vendor/product@bus/address form
  EXPECT_THAT(input_error_message([&] { open_camera_source("openni2:" + uri, {}); }),
              HasSubstr("openni2:1d27/0601@3/7: cannot open"));
  EXPECT_THAT(input_error_message([&] { open_camera_source("openni2", {}); }),
              HasSubstr("openni2:<any device>: cannot open (DeviceOpen using default: no "
                        "devices found); OpenNI2 devices connected: none"));
}

TEST(Openni2Source, MissingOniFileIsNamed) {
  EXPECT_THAT(input_error_message([] { open_camera_source("openni2:/no/such/file.oni", {}); }),
              HasSubstr("openni2:/no/such/file.oni: cannot read the .oni file"));
}

TEST(Openni2Source, CorruptOniFileIsAClearError) {
  const std::string dir = fresh_dir("corrupt_oni");
  std::filesystem::create_directories(dir);
  const std::string path = dir + "/corrupt.oni";
  std::ofstream(path) << "not an OpenNI recording\n";
  EXPECT_THAT(input_error_message([&] { open_camera_source("openni2:" + path, {}); }),
              HasSubstr("openni2:" + path + ": cannot open (DeviceOpen: Couldn't open device"));
}

TEST(Openni2Source, OutOfRangeOptionsAreNamed) {
  CameraSourceOptions options;
  options.fps = 0;
  EXPECT_THAT(input_error_message([&] { open_camera_source("openni2", options); }),
              HasSubstr("--source openni2: fps = 0, expected 1..240"));
}
#endif

TEST(TumRecorder, RecordingReadsBackAsTheSameTumSequence) {
  const auto data = recording::find_data_dir();
  if (!data) GTEST_SKIP() << "no real data: " << recording::data_dir_search_description();
  // GIVEN the bundled frames, undistorted by the TUM source, WHEN recorded and read back
  TumFrameSource source(*data + "/tum/rgbd_dataset_freiburg1_360",
                        config::load_camera_info("calib/tum_fr1.yaml"));
  const std::string dir = fresh_dir("recorder");
  TumRecorder recorder(dir, source.camera(), "test");
  std::vector<RgbdFrame> written;
  RgbdFrame frame;
  while (source.next(frame) == FrameStatus::kFrame) {
    recorder.write_frame(frame);
    recorder.write_accel({frame.t_ns, Eigen::Vector3d(0.1, -9.8, 0.2)});
    written.push_back({frame.t_ns, frame.bgr.clone(), frame.gray.clone(), frame.depth_m.clone(),
                       frame.depth_t_ns});
  }
  recorder.close();
  // THEN the TUM reader sees the same frames, stamps (the depth's own, 3.7-7.7 ms before the
  // colour's in fr1_360) to the microsecond, depth to 1/5000 m.
  recording::TumSequence sequence(dir);
  ASSERT_EQ(sequence.size(), written.size());
  ASSERT_EQ(sequence.accelerometer().size(), written.size());
  EXPECT_NEAR(sequence.accelerometer()[0].accel_mps2.y(), -9.8, 1e-6);
  cv::Mat bgr, depth_u16, depth_m;
  for (std::size_t i = 0; i < written.size(); ++i) {
    EXPECT_NEAR(static_cast<double>(sequence.frame(i).t_ns - written[i].t_ns), 0.0, 500.0);
    EXPECT_GT(written[i].t_ns - written[i].depth_t_ns, 3'000'000) << "frame " << i;
    EXPECT_NEAR(static_cast<double>(sequence.frame(i).depth_t_ns - written[i].depth_t_ns), 0.0,
                500.0);
    sequence.load(i, bgr, depth_u16);
    EXPECT_EQ(cv::norm(bgr, written[i].bgr, cv::NORM_INF), 0.0);
    recording::depth_to_metres(depth_u16, 5000.0, depth_m);
    EXPECT_LE(cv::norm(depth_m, written[i].depth_m, cv::NORM_INF), 0.5 / 5000.0 + 1e-6);
  }
  const config::CameraInfo info = config::load_camera_info(dir + "/camera.yaml");
  EXPECT_DOUBLE_EQ(info.fx, source.camera().fx);
  EXPECT_FALSE(info.has_distortion());
  EXPECT_THAT(input_error_message([&] { TumRecorder again(dir, source.camera(), "test"); }),
              HasSubstr("rgb.txt: exists already"));
}

TEST(TumRecorder, OptionsAddGroundTruthAndGyroLabelTheListsAndMayReplaceARecording) {
  // GIVEN a recorder with the simulator's options
  const std::string dir = fresh_dir("recorder_options");
  geometry::PinholeCamera camera;
  camera.width = 16;
  camera.height = 12;
  camera.fx = camera.fy = 20.0;
  camera.cx = 7.5;
  camera.cy = 5.5;
  TumRecordingOptions options;
  options.description = "unit";
  options.ground_truth = true;
  options.gyro = true;
  options.gyro_note = " (rad/s)";
  options.camera_comment = "# mount\n";
  for (int run = 0; run < 2; ++run) {
    // WHEN one frame, its pose and an IMU sample are written, twice into the same folder
    if (run == 1) {
      EXPECT_THAT(input_error_message([&] { TumRecorder refused(dir, camera, "unit"); }),
                  HasSubstr("rgb.txt: exists already"));
      options.replace_existing = true;
    }
    TumRecorder recorder(dir, camera, options);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(1.0, 2.0, 3.0);
    recorder.write_frame(1'500'000'000, cv::Mat(12, 16, CV_8UC3, cv::Scalar(1, 2, 3)),
                         cv::Mat(12, 16, CV_32F, cv::Scalar(1.0f)));
    recorder.write_ground_truth(1'500'000'000, T);
    recorder.write_gyro(1'500'000'000, Eigen::Vector3d(0.1, 0.2, 0.3));
    recorder.close();
    EXPECT_EQ(recorder.frames(), 1u);
  }
  // THEN the lists hold one entry each (the second run replaced the first), labelled
  const auto lines = [](const std::string& path) {
    std::ifstream file(path);
    std::vector<std::string> out;
    for (std::string line; std::getline(file, line);) out.push_back(line);
    return out;
  };
  const std::vector<std::string> gt = lines(dir + "/groundtruth.txt");
  ASSERT_EQ(gt.size(), 4u);
  EXPECT_EQ(gt[1], "# file: 'unit'");
  EXPECT_EQ(gt[3], "1.500000 1.000000 2.000000 3.000000 0.000000 0.000000 0.000000 1.000000");
  const std::vector<std::string> gyro = lines(dir + "/gyro.txt");
  ASSERT_EQ(gyro.size(), 4u);
  EXPECT_EQ(gyro[1], "# file: 'unit' (rad/s)");
  EXPECT_EQ(gyro[3], "1.500000 0.100000 0.200000 0.300000");
  EXPECT_EQ(lines(dir + "/rgb.txt").back(), "1.500000 rgb/1.500000.png");
  EXPECT_EQ(lines(dir + "/camera.yaml").back(), "# mount");
  EXPECT_DOUBLE_EQ(config::load_camera_info(dir + "/camera.yaml").cx, 7.5);
}

TEST(CalibFiles, NominalCameraFilesLoadAt640x480) {
  for (const char* path : {"calib/kinect_v1.yaml", "calib/xtion_pro_live.yaml"}) {
    const config::CameraInfo info = config::load_camera_info(path);
    EXPECT_EQ(info.width, 640) << path;
    EXPECT_EQ(info.height, 480) << path;
    EXPECT_FALSE(info.has_distortion()) << path;
  }
  EXPECT_DOUBLE_EQ(config::load_camera_info("calib/kinect_v1.yaml").fx, 525.0);
}

}  // namespace
}  // namespace hq::sources
