// The marker stage's config and the providers' per-step contract (no allocation).

#include "hq/marker_modes/marker_providers.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"

#include "scenario.hpp"
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

namespace hq::marker_modes {
namespace {

std::string write_config(const std::string& name, const std::string& text) {
  const std::string path =
      (std::filesystem::temp_directory_path() / ("hq_marker_modes_" + name + ".yaml")).string();
  std::ofstream(path) << text;
  return path;
}

TEST(MarkerModesConfig, DefaultConfigKeepsTheStageOff) {
  const pipeline::OnboardConfig config = pipeline::load_onboard_config("config/onboard.yaml");
  EXPECT_FALSE(config.markers.enabled);
  EXPECT_EQ(config.markers.marker_mode.target_id, 12);
}

TEST(MarkerModesConfig, OutOfRangeAndUnknownKeysNameTheKey) {
  const std::string bad_range =
      write_config("range", "markers: {enabled: true, detect_every_frames: 0}\n");
  const std::string message =
      ::hq::testing::input_error_message([&] { (void)pipeline::load_onboard_config(bad_range); });
  EXPECT_NE(message.find("detect_every_frames"), std::string::npos) << message;
  EXPECT_NE(message.find(bad_range), std::string::npos) << message;

  const std::string unknown =
      write_config("unknown", "markers: {explore: {height_m: 1.0, heigth_m: 2.0}}\n");
  const std::string unknown_message =
      ::hq::testing::input_error_message([&] { (void)pipeline::load_onboard_config(unknown); });
  EXPECT_NE(unknown_message.find("heigth_m"), std::string::npos) << unknown_message;

  const std::string nan_gain =
      write_config("nan", "markers: {marker_mode: {kp_position_per_s: .nan}}\n");
  const std::string nan_message =
      ::hq::testing::input_error_message([&] { (void)pipeline::load_onboard_config(nan_gain); });
  EXPECT_NE(nan_message.find("kp_position_per_s"), std::string::npos) << nan_message;
}

// The mode's own marker age limit was shadowed by the filter's: one limit, the old key refused
// with where the limit is now.
TEST(MarkerModesConfig, TheShadowedMarkerAgeKeyIsRefusedNamingTheOneLimit) {
  const std::string old_key =
      write_config("age", "markers: {marker_mode: {target_id: 3, max_marker_age_s: 10.0}}\n");
  const std::string message =
      ::hq::testing::input_error_message([&] { (void)pipeline::load_onboard_config(old_key); });
  EXPECT_NE(message.find(old_key), std::string::npos) << message;
  EXPECT_NE(message.find("markers.marker_mode.max_marker_age_s: removed"), std::string::npos)
      << message;
  EXPECT_NE(message.find("markers.navigation.position_max_age_s"), std::string::npos) << message;
}

TEST(MarkerProviders, StepAllocatesNothingOnceAnchored) {
  test::Flight f = test::make_flight("onboard/closed_loop/flights/marker_hover.yaml", 3);
  f.loop->run_until(8.0);
  ASSERT_TRUE(f.stage().navigation().pose_usable(f.loop->simulator().t_ns()));
  const std::int64_t t_ns = f.loop->simulator().t_ns();
  MarkerModeProvider& marker = f.stage().marker_mode();
  ExploreProvider& explore = f.stage().explore();
  (void)explore.desired(t_ns);
  const long before = ::hq::testing::allocation_count();
  const modes::ModeCommand hold = marker.desired(t_ns + 1'000'000);
  const modes::ModeCommand exploring = explore.desired(t_ns + 2'000'000);
  EXPECT_EQ(::hq::testing::allocation_count() - before, 0);
  EXPECT_TRUE(hold.valid) << hold.reason;
  EXPECT_TRUE(exploring.valid) << exploring.reason;
}

}  // namespace
}  // namespace hq::marker_modes
