#include "hq/config/camera_info.hpp"

#include <gtest/gtest.h>

#include <filesystem>

namespace {

TEST(CalibFiles, EveryShippedCameraFileLoads) {
  int loaded = 0;
  for (const auto& entry : std::filesystem::directory_iterator("calib")) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("tum_", 0) != 0 || entry.path().extension() != ".yaml") continue;
    const hq::config::CameraInfo info = hq::config::load_camera_info(entry.path().string());
    EXPECT_EQ(info.width, 640) << name;
    EXPECT_GT(info.fx, 400.0) << name;
    ++loaded;
  }
  EXPECT_EQ(loaded, 3) << "expected tum_fr1, tum_fr2 and tum_fr3";
}

// The depth cameras the vehicle flies give millimetres; TUM's PNGs 5000 units per metre.
TEST(CalibFiles, EveryShippedCameraFileStatesItsDepthScale) {
  EXPECT_DOUBLE_EQ(hq::config::load_camera_info("calib/kinect_v1.yaml").depth_scale_units_per_m,
                   1000.0);
  EXPECT_DOUBLE_EQ(
      hq::config::load_camera_info("calib/xtion_pro_live.yaml").depth_scale_units_per_m, 1000.0);
  EXPECT_DOUBLE_EQ(hq::config::load_camera_info("calib/tum_fr2.yaml").depth_scale_units_per_m,
                   5000.0);
}

TEST(CalibFiles, Fr1MatchesTheTumCalibration) {
  const auto info = hq::config::load_camera_info("calib/tum_fr1.yaml");
  EXPECT_DOUBLE_EQ(info.fx, 517.3);
  EXPECT_DOUBLE_EQ(info.cy, 255.3);
  ASSERT_EQ(info.distortion.size(), 5u);
  EXPECT_DOUBLE_EQ(info.distortion[4], 1.1633);
  EXPECT_TRUE(info.has_distortion());
  EXPECT_FALSE(hq::config::load_camera_info("calib/tum_fr3.yaml").has_distortion());
}

}  // namespace
