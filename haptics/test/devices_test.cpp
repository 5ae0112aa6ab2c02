#include "hq/haptics/haptic_device.hpp"
#include "hq/testing/input_error.hpp"

#include "test_support.hpp"
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <deque>
#include <fcntl.h>
#include <string>
#include <unistd.h>

namespace hq::haptics {
namespace {

using ::testing::AnyOf;
using ::testing::HasSubstr;

SimulatedDeviceConfig push_script() {
  SimulatedDeviceConfig config;
  HandKeyframe rest;
  HandKeyframe pushed;
  pushed.t_s = 0.3;
  pushed.p_D_m = Eigen::Vector3d(0.03, -0.01, 0.02);
  pushed.buttons = 0b101;
  config.script = {rest, pushed};
  return config;
}

TEST(SimulatedDevice, SameTimesAndForcesReproduceBitForBit) {
  SimulatedDevice a(push_script());
  SimulatedDevice b(push_script());
  for (int k = 0; k < 800; ++k) {
    const std::int64_t t_ns = 123 * test::kMsNs + k * test::kMsNs;
    DeviceSample sample_a;
    DeviceSample sample_b;
    ASSERT_TRUE(a.read(t_ns, sample_a));
    ASSERT_TRUE(b.read(t_ns, sample_b));
    ASSERT_EQ(sample_a.p_D_m, sample_b.p_D_m) << "tick " << k;
    ASSERT_EQ(sample_a.buttons, sample_b.buttons);
    const Eigen::Vector3d F = -40.0 * sample_a.p_D_m;
    a.write_force(t_ns, F);
    b.write_force(t_ns, F);
  }
}

TEST(SimulatedDevice, EffectorFollowsTheHandAndReportsItsButtons) {
  const SimulatedDeviceConfig config = push_script();
  SimulatedDevice device(config);
  DeviceSample sample;
  for (int k = 0; k <= 2000; ++k) device.read(k * test::kMsNs, sample);
  // With no device force the grip spring settles the effector on the hand target.
  EXPECT_TRUE(sample.p_D_m.isApprox(config.script.back().p_D_m, 1e-3));
  EXPECT_EQ(sample.buttons, 0b101u);
  EXPECT_NEAR(device.v_D_mps().norm(), 0.0, 1e-3);
}

TEST(SimulatedDevice, DeviceForceDeflectsTheEffectorAgainstTheGrip) {
  const SimulatedDeviceConfig config = push_script();
  SimulatedDevice device(config);
  DeviceSample sample;
  const Eigen::Vector3d F(-2.0, 0.0, 0.0);
  for (int k = 0; k <= 2000; ++k) {
    device.read(k * test::kMsNs, sample);
    device.write_force(k * test::kMsNs, F);
  }
  // Static balance: F + k_hand (hand - p) = 0.
  const double expected_x = config.script.back().p_D_m.x() + F.x() / config.hand_stiffness_n_per_m;
  EXPECT_NEAR(sample.p_D_m.x(), expected_x, 1e-4);
}

TEST(SimulatedDevice, ScriptedLossReadsAsDisconnectedWithStatus) {
  SimulatedDeviceConfig config = push_script();
  HandKeyframe lost;
  lost.t_s = 0.5;
  lost.connected = false;
  config.script.push_back(lost);
  SimulatedDevice device(config);
  DeviceSample sample;
  EXPECT_TRUE(device.read(0, sample));
  EXPECT_TRUE(device.read(400 * test::kMsNs, sample));
  EXPECT_FALSE(device.read(600 * test::kMsNs, sample));
  EXPECT_FALSE(device.connected());
  EXPECT_EQ(sample.p_D_m, Eigen::Vector3d::Zero());
  EXPECT_THAT(device.status(), HasSubstr("lost"));
}

/// Keys queued by the test; "closes" when told to.
class ScriptedKeys final : public ByteSource {
 public:
  explicit ScriptedKeys(std::deque<std::string>* chunks) : chunks_(chunks) {}
  int read_available(char* buffer, int capacity) override {
    if (chunks_->empty()) return 0;
    if (chunks_->front() == "<closed>") return -1;
    std::string& chunk = chunks_->front();
    const int n = std::min(capacity, static_cast<int>(chunk.size()));
    chunk.copy(buffer, static_cast<std::size_t>(n));
    chunk.erase(0, static_cast<std::size_t>(n));
    if (chunk.empty()) chunks_->pop_front();
    return n;
  }

 private:
  std::deque<std::string>* chunks_;
};

TEST(KeyboardDevice, KeysMoveTheVirtualEffectorAlongDAxes) {
  std::deque<std::string> chunks;
  KeyboardConfig config;
  KeyboardDevice device(config, std::make_unique<ScriptedKeys>(&chunks));
  DeviceSample sample;
  chunks.push_back("www");
  ASSERT_TRUE(device.read(0, sample));
  EXPECT_TRUE(sample.p_D_m.isApprox(Eigen::Vector3d(3 * config.step_m, 0, 0)));
  chunks.push_back("sddf");
  device.read(0, sample);
  EXPECT_TRUE(
      sample.p_D_m.isApprox(Eigen::Vector3d(2 * config.step_m, 2 * config.step_m, config.step_m)));
  chunks.push_back("rra");
  device.read(0, sample);
  EXPECT_TRUE(
      sample.p_D_m.isApprox(Eigen::Vector3d(2 * config.step_m, config.step_m, -config.step_m)));
  chunks.push_back(" ");
  device.read(0, sample);
  EXPECT_EQ(sample.p_D_m, Eigen::Vector3d::Zero());
}

TEST(KeyboardDevice, ArrowEscapeSequencesSplitAcrossReadsWork) {
  std::deque<std::string> chunks;
  KeyboardConfig config;
  KeyboardDevice device(config, std::make_unique<ScriptedKeys>(&chunks));
  DeviceSample sample;
  chunks.push_back("\x1b[A\x1b");  // up, then half of right
  device.read(0, sample);
  chunks.push_back("[C\x1b[B\x1b[B");
  device.read(0, sample);
  EXPECT_TRUE(sample.p_D_m.isApprox(Eigen::Vector3d(-config.step_m, config.step_m, 0)));
}

TEST(KeyboardDevice, TravelIsClampedAndButtonsLastOneRead) {
  std::deque<std::string> chunks;
  KeyboardConfig config;
  config.range_m = 0.012;
  KeyboardDevice device(config, std::make_unique<ScriptedKeys>(&chunks));
  DeviceSample sample;
  chunks.push_back(std::string(100, 'w') + "13");
  device.read(0, sample);
  EXPECT_DOUBLE_EQ(sample.p_D_m.x(), config.range_m);
  EXPECT_EQ(sample.buttons, 0b101u);
  device.read(0, sample);
  EXPECT_EQ(sample.buttons, 0u);
}

TEST(KeyboardDevice, ClosedInputIsDeviceLoss) {
  std::deque<std::string> chunks{"ww", "<closed>"};
  KeyboardDevice device(KeyboardConfig{}, std::make_unique<ScriptedKeys>(&chunks));
  DeviceSample sample;
  EXPECT_TRUE(device.read(0, sample));
  EXPECT_FALSE(device.read(0, sample));
  EXPECT_FALSE(device.connected());
  EXPECT_EQ(sample.p_D_m, Eigen::Vector3d::Zero());
  EXPECT_THAT(device.status(), HasSubstr("closed"));
}

TEST(OpenDevice, UnknownKindIsNamedWithTheChoices) {
  const std::string message =
      testing::input_error_message([] { open_device("omega7", DeviceOptions{}); });
  EXPECT_THAT(message, HasSubstr("'omega7'"));
  EXPECT_THAT(message, HasSubstr("sim|keyboard|joystick|forcedim"));
}

TEST(OpenDevice, KeyboardWithoutATerminalSaysSo) {
  DeviceOptions options;
  options.terminal_fd = open("/dev/null", O_RDONLY);
  ASSERT_GE(options.terminal_fd, 0);
  const std::string message =
      testing::input_error_message([&] { open_device("keyboard", options); });
  close(options.terminal_fd);
  EXPECT_THAT(message, HasSubstr("not a terminal"));
}

TEST(OpenDevice, ForceDimensionWithoutItsSdkSaysWhy) {
#ifndef HQ_TEST_HAVE_FORCE_DIMENSION
  const std::string message =
      testing::input_error_message([] { open_device("forcedim", DeviceOptions{}); });
  EXPECT_THAT(message, HasSubstr("'forcedim'"));
  EXPECT_THAT(message, HasSubstr("Force Dimension SDK"));
#else
  GTEST_SKIP() << "built with the Force Dimension SDK";
#endif
}

TEST(OpenDevice, JoystickEitherOpensOrNamesTheProblem) {
  try {
    const auto device = open_device("joystick", DeviceOptions{});
    EXPECT_STREQ(device->name(), "joystick");
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), AnyOf(HasSubstr("joystick device"), HasSubstr("'joystick'")));
  }
}

TEST(OpenDevice, SimOpensWithTheConfiguredScript) {
  DeviceOptions options;
  options.config.sim = push_script();
  const auto device = open_device("sim", options);
  EXPECT_STREQ(device->name(), "sim");
  EXPECT_THAT(device->status(), HasSubstr("2 keyframes"));
}

}  // namespace
}  // namespace hq::haptics
