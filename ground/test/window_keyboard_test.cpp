#include "hq/ground/window_keyboard.hpp"

#include "hq/console/console_window.hpp"
#include "hq/console/flight_keys.hpp"
#include "hq/haptics/teleop_mapping.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <SDL2/SDL_scancode.h>

namespace hq::ground {
namespace {

using ::testing::HasSubstr;

constexpr std::int64_t kMs = 1'000'000;

// The command eq. 6-10 gives for the keys held once the effector has settled.
haptics::MappedCommand settled_command(std::uint32_t held) {
  console::FlightKeys keys;
  keys.set_window_open(true);
  const haptics::KeyboardConfig config;
  WindowKeyboardDevice device(config, keys);
  keys.press(held);
  haptics::DeviceSample sample;
  for (int i = 0; i <= 500; ++i) EXPECT_TRUE(device.read(i * kMs, sample));
  const haptics::TeleopMapping mapping(
      haptics::MappingConfig{},
      Eigen::Matrix3d(
          // Camera looking forward along body x (optical z forward, x right, y down): alpha = 0.
          (Eigen::Matrix3d() << 0, 0, 1, 1, 0, 0, 0, 1, 0).finished()));
  return mapping.map(sample.p_D_m);
}

TEST(WindowKeyboard, ScancodesByPositionGiveTheFlyingKeys) {
  EXPECT_EQ(console::flight_key_for_scancode(SDL_SCANCODE_W), console::kKeyForward);
  EXPECT_EQ(console::flight_key_for_scancode(SDL_SCANCODE_UP), console::kKeyForward);
  EXPECT_EQ(console::flight_key_for_scancode(SDL_SCANCODE_DOWN), console::kKeyBack);
  EXPECT_EQ(console::flight_key_for_scancode(SDL_SCANCODE_A), console::kKeyYawLeft);
  EXPECT_EQ(console::flight_key_for_scancode(SDL_SCANCODE_Q), console::kKeyYawLeft);
  EXPECT_EQ(console::flight_key_for_scancode(SDL_SCANCODE_E), console::kKeyYawRight);
  EXPECT_EQ(console::flight_key_for_scancode(SDL_SCANCODE_RIGHT), console::kKeyYawRight);
  EXPECT_EQ(console::flight_key_for_scancode(SDL_SCANCODE_PAGEUP), console::kKeyClimb);
  EXPECT_EQ(console::flight_key_for_scancode(SDL_SCANCODE_PAGEDOWN), console::kKeyDescend);
  // Mode shortcuts do not fly.
  EXPECT_EQ(console::flight_key_for_scancode(SDL_SCANCODE_T), 0u);
  EXPECT_EQ(console::flight_key_for_scancode(SDL_SCANCODE_X), 0u);
}

TEST(WindowKeyboard, KeysGiveTheIntendedCommandThroughTheMapping) {
  const haptics::MappedCommand forward = settled_command(console::kKeyForward);
  ASSERT_TRUE(forward.valid);
  EXPECT_GT(forward.command.v_H_mps.x(), 0.1);
  EXPECT_NEAR(forward.command.v_H_mps.z(), 0.0, 1e-12);
  EXPECT_NEAR(forward.command.yaw_rate_radps, 0.0, 1e-12);
  EXPECT_LT(settled_command(console::kKeyBack).command.v_H_mps.x(), -0.1);
  // NED: a climb is v_z < 0, a yaw to the right is a positive rate.
  EXPECT_LT(settled_command(console::kKeyClimb).command.v_H_mps.z(), -0.1);
  EXPECT_GT(settled_command(console::kKeyDescend).command.v_H_mps.z(), 0.1);
  EXPECT_GT(settled_command(console::kKeyYawRight).command.yaw_rate_radps, 0.1);
  EXPECT_LT(settled_command(console::kKeyYawLeft).command.yaw_rate_radps, -0.1);
  // Opposite keys cancel.
  const haptics::MappedCommand both = settled_command(console::kKeyForward | console::kKeyBack);
  EXPECT_NEAR(both.command.v_H_mps.norm(), 0.0, 1e-12);
}

TEST(WindowKeyboard, DisplacementRampsToRangeAndBackOnRelease) {
  console::FlightKeys keys;
  keys.set_window_open(true);
  haptics::KeyboardConfig config;
  config.range_m = 0.04;
  WindowKeyboardDevice device(config, keys);
  haptics::DeviceSample sample;
  ASSERT_TRUE(device.read(0, sample));
  keys.press(console::kKeyForward);
  ASSERT_TRUE(device.read(50 * kMs, sample));  // a quarter of the slew time
  EXPECT_NEAR(sample.p_D_m.x(), 0.25 * config.range_m, 1e-9);
  ASSERT_TRUE(device.read(1000 * kMs, sample));
  EXPECT_NEAR(sample.p_D_m.x(), config.range_m, 1e-12);
  EXPECT_EQ(key_target_D_m(keys.held(), config), Eigen::Vector3d(config.range_m, 0, 0));
  keys.release(console::kKeyForward);
  ASSERT_TRUE(device.read(1100 * kMs, sample));
  EXPECT_NEAR(sample.p_D_m.x(), 0.5 * config.range_m, 1e-9);
  ASSERT_TRUE(device.read(2000 * kMs, sample));
  EXPECT_NEAR(sample.p_D_m.norm(), 0.0, 1e-12);
}

TEST(WindowKeyboard, FocusLossReleasesAndAClosedWindowIsDeviceLoss) {
  console::FlightKeys keys;
  const haptics::KeyboardConfig config;
  WindowKeyboardDevice device(config, keys);
  haptics::DeviceSample sample;
  EXPECT_FALSE(device.read(0, sample));  // window not open yet
  EXPECT_FALSE(device.connected());
  keys.set_window_open(true);
  keys.press(console::kKeyForward | console::kKeyClimb);
  EXPECT_TRUE(device.read(1000 * kMs, sample));
  EXPECT_TRUE(device.read(2000 * kMs, sample));
  EXPECT_GT(sample.p_D_m.x(), 0.0);
  keys.release_all();
  EXPECT_EQ(keys.held(), 0u);
  keys.press(console::kKeyForward);
  keys.set_window_open(false);
  EXPECT_EQ(keys.held(), 0u);
  EXPECT_FALSE(device.read(3000 * kMs, sample));
  EXPECT_FALSE(device.connected());
  EXPECT_EQ(sample.p_D_m, Eigen::Vector3d::Zero());
  EXPECT_THAT(device.status(), HasSubstr("closed"));
}

TEST(WindowKeyboard, ReadAllocatesNothing) {
  console::FlightKeys keys;
  keys.set_window_open(true);
  WindowKeyboardDevice device(haptics::KeyboardConfig{}, keys);
  haptics::DeviceSample sample;
  device.read(0, sample);
  const auto before = hq::testing::allocation_count();
  for (int i = 1; i < 1000; ++i) {
    if (i % 100 == 0) keys.press(console::kKeyYawLeft);
    if (i % 100 == 50) keys.release(console::kKeyYawLeft);
    device.read(i * kMs, sample);
  }
  EXPECT_EQ(hq::testing::allocation_count(), before);
}

TEST(WindowKeyboard, NonPositiveRangeIsAnInputError) {
  console::FlightKeys keys;
  haptics::KeyboardConfig config;
  config.range_m = 0.0;
  EXPECT_THAT(hq::testing::input_error_message([&] { WindowKeyboardDevice d(config, keys); }),
              HasSubstr("keyboard.range_m = 0"));
}

}  // namespace
}  // namespace hq::ground
