#pragma once
// Shared by the haptics tests: the core paper's vehicle extrinsics and small helpers.

#include "hq/haptics/haptics_config.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <fstream>
#include <string>

namespace hq::haptics::test {

inline Eigen::Matrix3d core_paper_R_B_C() {
  return load_vehicle_config("calib/vehicle_core_paper.yaml").camera.R_B_C();
}

/// Writes `text` to a fresh file under /tmp and returns its path.
inline std::string write_temp_yaml(const std::string& name, const std::string& text) {
  std::string path = "/tmp/hq_haptics_test_" + name + ".yaml";
  std::ofstream(path) << text;
  return path;
}

inline constexpr std::int64_t kMsNs = 1'000'000;

}  // namespace hq::haptics::test
