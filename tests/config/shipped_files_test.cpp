// Every YAML file the repository ships loads with the loader that reads it, so a stricter
// loader cannot leave a shipped file behind: camera and vehicle files, the onboard, haptics and
// ground configs, the simulator's config and worlds, and the scripted flights.

#include "hq/closed_loop/operator_script.hpp"
#include "hq/config/camera_info.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/haptics/haptics_config.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/world.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace hq {
namespace {

std::vector<std::string> yaml_files_in(const std::string& folder) {
  std::vector<std::string> files;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    if (entry.path().extension() == ".yaml") files.push_back(entry.path().string());
  }
  return files;
}

// Loads each file of `folder` with `load`; returns how many it loaded.
int load_each(const std::string& folder, const std::function<void(const std::string&)>& load) {
  int loaded = 0;
  for (const std::string& path : yaml_files_in(folder)) {
    EXPECT_NO_THROW(load(path)) << path;
    ++loaded;
  }
  return loaded;
}

TEST(ShippedFiles, CalibrationFilesLoad) {
  int cameras = 0;
  for (const std::string& path : yaml_files_in("calib")) {
    if (path.find("vehicle_") != std::string::npos) {
      EXPECT_NO_THROW(load_vehicle_config(path)) << path;
    } else {
      EXPECT_NO_THROW(config::load_camera_info(path)) << path;
      ++cameras;
    }
  }
  EXPECT_EQ(cameras, 5) << "kinect_v1, xtion_pro_live, tum_fr1, tum_fr2, tum_fr3";
}

TEST(ShippedFiles, OnboardHapticsAndGroundConfigsLoad) {
  EXPECT_NO_THROW(pipeline::load_onboard_config("config/onboard.yaml"));
  EXPECT_NO_THROW(haptics::load_haptics_config("config/haptics.yaml"));
  EXPECT_EQ(load_each("ground/config",
                      [](const std::string& path) { haptics::load_haptics_config(path); }),
            2);
}

TEST(ShippedFiles, SimulatorConfigWorldsAndFlightsLoad) {
  EXPECT_NO_THROW(sim::load_sim_config("onboard/sim/config/sim.yaml"));
  EXPECT_EQ(load_each("onboard/sim/worlds", [](const std::string& path) { sim::load_world(path); }),
            6);
  EXPECT_EQ(load_each("onboard/closed_loop/flights",
                      [](const std::string& path) { closed_loop::load_operator_script(path); }),
            3);
}

}  // namespace
}  // namespace hq
