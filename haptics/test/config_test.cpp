#include "hq/haptics/haptics_config.hpp"
#include "hq/testing/input_error.hpp"

#include "test_support.hpp"
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

namespace hq::haptics {
namespace {

using ::testing::HasSubstr;

TEST(HapticsConfig, ShippedFileLoadsWithASortedScript) {
  const HapticsConfig config = load_haptics_config("config/haptics.yaml");
  ASSERT_GE(config.sim.script.size(), 2u);
  for (std::size_t i = 1; i < config.sim.script.size(); ++i) {
    EXPECT_GT(config.sim.script[i].t_s, config.sim.script[i - 1].t_s);
  }
  EXPECT_GT(config.mapping.velocity_gain_mps_per_m, 0.0);
}

TEST(HapticsConfig, DegreesAreConvertedOnce) {
  const std::string path = test::write_temp_yaml("deg", "mapping: {max_yaw_rate_degps: 90.0}\n");
  EXPECT_NEAR(load_haptics_config(path).mapping.max_yaw_rate_radps, M_PI / 2.0, 1e-12);
}

TEST(HapticsConfig, UnknownKeyIsNamed) {
  const std::string path = test::write_temp_yaml("unknown", "mapping: {velocity_gain: 3.0}\n");
  const std::string message = testing::input_error_message([&] { load_haptics_config(path); });
  EXPECT_THAT(message, HasSubstr(path));
  EXPECT_THAT(message, HasSubstr("mapping.velocity_gain"));
}

TEST(HapticsConfig, OutOfRangeValueIsNamedWithValue) {
  const std::string path = test::write_temp_yaml("range", "feedback: {damping_ns_per_m: -2.0}\n");
  const std::string message = testing::input_error_message([&] { load_haptics_config(path); });
  EXPECT_THAT(message, HasSubstr("feedback.damping_ns_per_m"));
  EXPECT_THAT(message, HasSubstr("-2"));
}

TEST(HapticsConfig, UnsortedScriptNamesTheKeyframe) {
  const std::string path = test::write_temp_yaml(
      "unsorted",
      "sim:\n  script:\n    - {t_s: 0.0, p_m: [0, 0, 0]}\n    - {t_s: 1.0, p_m: [0, 0, 0]}\n"
      "    - {t_s: 0.5, p_m: [0, 0, 0]}\n");
  const std::string message = testing::input_error_message([&] { load_haptics_config(path); });
  EXPECT_THAT(message, HasSubstr("sim.script[2].t_s"));
  EXPECT_THAT(message, HasSubstr("sorted"));
}

TEST(HapticsConfig, ScriptPositionOutsideWorkspaceOrMalformedIsNamed) {
  const std::string far = test::write_temp_yaml(
      "far", "sim:\n  workspace_m: 0.05\n  script:\n    - {t_s: 0.0, p_m: [0.2, 0, 0]}\n");
  EXPECT_THAT(testing::input_error_message([&] { load_haptics_config(far); }),
              HasSubstr("sim.script[0].p_m[0] = 0.2"));
  const std::string short_list =
      test::write_temp_yaml("short", "sim:\n  script:\n    - {t_s: 0.0, p_m: [0, 0]}\n");
  EXPECT_THAT(testing::input_error_message([&] { load_haptics_config(short_list); }),
              HasSubstr("sim.script[0].p_m"));
  const std::string not_list = test::write_temp_yaml("notlist", "sim:\n  script: 3\n");
  EXPECT_THAT(testing::input_error_message([&] { load_haptics_config(not_list); }),
              HasSubstr("sim.script"));
}

TEST(HapticsConfig, MissingFileIsNamed) {
  EXPECT_THAT(testing::input_error_message([] { load_haptics_config("nope/haptics.yaml"); }),
              HasSubstr("nope/haptics.yaml"));
}

}  // namespace
}  // namespace hq::haptics
