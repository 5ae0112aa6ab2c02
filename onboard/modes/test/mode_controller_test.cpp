#include "hq/modes/mode_controller.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"

#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>

namespace hq::modes {
namespace {

using testing::HasSubstr;

constexpr std::int64_t kStepNs = 5'000'000;  // 200 Hz
constexpr double kDt = 5e-3;

control::VehicleConfig test_vehicle() { return control::VehicleConfig{}; }

// Point mass whose attitude follows the setpoint instantly (NED, H frame).
struct PointMass {
  Eigen::Vector3d v_mps = Eigen::Vector3d::Zero();
  void step(const control::AttitudeSetpoint& sp) {
    const Eigen::Matrix3d R_HQ = (Eigen::AngleAxisd(sp.pitch_rad, Eigen::Vector3d::UnitY()) *
                                  Eigen::AngleAxisd(sp.roll_rad, Eigen::Vector3d::UnitX()))
                                     .toRotationMatrix();
    v_mps += (R_HQ * Eigen::Vector3d(0, 0, -sp.thrust_n) / test_vehicle().mass_kg +
              Eigen::Vector3d(0, 0, control::kGravityMps2)) *
             kDt;
  }
};

struct FixedProvider : VelocityProvider {
  ModeCommand command;
  ModeCommand desired(std::int64_t) override { return command; }
};

double setpoint_change(const control::AttitudeSetpoint& a, const control::AttitudeSetpoint& b) {
  // Thrust in g-normalised units against angles in rad: both O(1) for a 1 kg vehicle.
  return std::max({std::abs(a.thrust_n - b.thrust_n) / control::kGravityMps2,
                   std::abs(a.roll_rad - b.roll_rad), std::abs(a.pitch_rad - b.pitch_rad)});
}

struct SwitchFigures {
  double at_switch = 0.0;     // setpoint change across the switch instant
  double after_switch = 0.0;  // largest per-step change in the 3 s after it
};

// Teleop at 1 m/s forward, settled, then a switch to land.
SwitchFigures teleop_to_land(double max_switch_accel_mps2) {
  ModesConfig config;
  config.max_switch_accel_mps2 = max_switch_accel_mps2;
  ModeController modes(config, control::VelocityControllerConfig{}, test_vehicle());
  EXPECT_TRUE(modes.request_mode(Mode::kTeleop).accepted);
  PointMass plant;
  std::int64_t t_ns = 0;
  control::AttitudeSetpoint previous;
  for (int k = 0; k < 2000; ++k, t_ns += kStepNs) {
    modes.set_operator_command({t_ns, Eigen::Vector3d(1.0, 0.0, 0.0), 0.0});
    const ModeOutput out = modes.step(t_ns, plant.v_mps, Eigen::Vector3d::Zero());
    plant.step(out.control.setpoint);
    previous = out.control.setpoint;
  }
  EXPECT_NEAR(plant.v_mps.x(), 1.0, 0.01);
  EXPECT_TRUE(modes.request_mode(Mode::kLand).accepted);
  SwitchFigures figures;
  for (int k = 0; k < 600; ++k, t_ns += kStepNs) {
    const ModeOutput out = modes.step(t_ns, plant.v_mps, Eigen::Vector3d::Zero());
    plant.step(out.control.setpoint);
    const double change = setpoint_change(out.control.setpoint, previous);
    if (k == 0) {
      figures.at_switch = change;
    } else {
      figures.after_switch = std::max(figures.after_switch, change);
    }
    previous = out.control.setpoint;
  }
  return figures;
}

TEST(ModeController, SwitchingIsBumpless) {
  const SwitchFigures ramped = teleop_to_land(ModesConfig{}.max_switch_accel_mps2);
  // THEN the switch instant changes the setpoint no more than any normal step of the ramp
  // (measured 0.00147 at the switch vs 0.00146 after, hence the 1 % margin; the ramp step is
  // about kp 3 x 1 m/s^2 x 5 ms / g = 0.0015).
  EXPECT_LE(ramped.at_switch, ramped.after_switch * 1.01 + 1e-9);
  EXPECT_LT(ramped.at_switch, 0.005);
  // Without the ramp the same switch steps the setpoint by 0.335 (measured).
  const SwitchFigures unramped = teleop_to_land(1e6 / kDt);
  EXPECT_GT(unramped.at_switch, 50.0 * ramped.at_switch);
}

TEST(ModeController, MarkerAndExploreNeedAProvider) {
  ModeController modes(ModesConfig{}, control::VelocityControllerConfig{}, test_vehicle());
  const ModeSwitch refused = modes.request_mode(Mode::kMarker);
  EXPECT_FALSE(refused.accepted);
  EXPECT_THAT(refused.reason, HasSubstr("marker"));
  EXPECT_THAT(modes.request_mode(Mode::kExplore).reason, HasSubstr("explore mode has no provider"));
  EXPECT_EQ(modes.mode(), Mode::kHover);

  FixedProvider provider;
  provider.command.valid = true;
  provider.command.v_horizontal_mps = Eigen::Vector3d(0.2, 0.0, 0.0);
  ASSERT_TRUE(modes.register_provider(Mode::kExplore, &provider));
  EXPECT_FALSE(modes.register_provider(Mode::kLand, &provider));
  EXPECT_TRUE(modes.request_mode(Mode::kExplore).accepted);
  ModeOutput out;
  for (int k = 0; k < 100; ++k)
    out = modes.step(k * kStepNs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  EXPECT_FALSE(out.ramping);
  EXPECT_TRUE(out.v_star_des_horizontal_mps.isApprox(Eigen::Vector3d(0.2, 0.0, 0.0)));
  // A provider with no command: hover.
  provider.command.valid = false;
  for (int k = 100; k < 200; ++k)
    out = modes.step(k * kStepNs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  EXPECT_TRUE(out.provider_failed);
  EXPECT_TRUE(out.v_star_des_horizontal_mps.isZero());
}

TEST(ModeController, StaleTeleopCommandFallsBackToHover) {
  ModeController modes(ModesConfig{}, control::VelocityControllerConfig{}, test_vehicle());
  modes.request_mode(Mode::kTeleop);
  ModeOutput out;
  // GIVEN fresh commands for 1 s (the switch ramp reaches 0.5 m/s after 0.5 s).
  for (int k = 0; k <= 200; ++k) {
    modes.set_operator_command({k * kStepNs, Eigen::Vector3d(0.5, 0.0, 0.0), 0.2});
    out = modes.step(k * kStepNs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  }
  EXPECT_NEAR(out.v_star_des_horizontal_mps.x(), 0.5, 1e-12);
  // WHEN the operator goes silent: still obeyed while younger than the 0.5 s timeout ...
  for (int k = 201; k < 290; ++k) {
    out = modes.step(k * kStepNs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  }
  EXPECT_FALSE(out.teleop_timed_out);
  EXPECT_NEAR(out.v_star_des_horizontal_mps.x(), 0.5, 1e-12);
  // ... THEN hover (zero velocity and yaw rate, reached through the ramp).
  for (int k = 290; k < 700; ++k) {
    out = modes.step(k * kStepNs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  }
  EXPECT_TRUE(out.teleop_timed_out);
  EXPECT_TRUE(out.v_star_des_horizontal_mps.isZero());
  EXPECT_EQ(out.yaw_rate_des_radps, 0.0);
}

TEST(ModeController, LandDescendsAtTheConfiguredSpeed) {
  ModesConfig config;
  config.land_speed_mps = 0.4;
  ModeController modes(config, control::VelocityControllerConfig{}, test_vehicle());
  modes.request_mode(Mode::kLand);
  PointMass plant;
  for (int k = 0; k < 2000; ++k)
    plant.step(modes.step(k * kStepNs, plant.v_mps, Eigen::Vector3d::Zero()).control.setpoint);
  EXPECT_NEAR(plant.v_mps.z(), 0.4, 0.01);  // NED: descending is +z
}

TEST(ModeController, ObstacleTermIsAddedInEveryMode) {
  const Eigen::Vector3d v_obs(-0.3, 0.1, -0.05);
  FixedProvider provider;
  provider.command.valid = true;
  provider.command.v_horizontal_mps = Eigen::Vector3d(0.1, 0.1, 0.0);
  for (const Mode mode :
       {Mode::kTeleop, Mode::kHover, Mode::kLand, Mode::kMarker, Mode::kExplore}) {
    ModeController modes(ModesConfig{}, control::VelocityControllerConfig{}, test_vehicle());
    modes.register_provider(Mode::kMarker, &provider);
    modes.register_provider(Mode::kExplore, &provider);
    ASSERT_TRUE(modes.request_mode(mode).accepted);
    ModeOutput out;
    for (int k = 0; k < 300; ++k) {
      modes.set_operator_command({k * kStepNs, Eigen::Vector3d(0.2, 0.0, 0.0), 0.0});
      out = modes.step(k * kStepNs, Eigen::Vector3d::Zero(), v_obs);
    }
    EXPECT_TRUE(out.v_des_horizontal_mps.isApprox(out.v_star_des_horizontal_mps + v_obs))
        << to_string(mode);
  }
}

TEST(ModesConfig, BadValueIsRejectedNamingTheKey) {
  config::StrictMap section(YAML::Load("{land_speed_mps: 0}"), "config/onboard.yaml", "modes");
  ModesConfig config;
  try {
    read_config(section, config);
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("config/onboard.yaml: modes.land_speed_mps = 0, expected > 0"));
  }
}

TEST(ModesConfig, ShippedOnboardYamlSectionLoads) {
  const YAML::Node root = config::load_yaml_file("config/onboard.yaml");
  config::StrictMap section(root["modes"], "config/onboard.yaml", "modes");
  ModesConfig config;
  EXPECT_NO_THROW(read_config(section, config));
}

}  // namespace
}  // namespace hq::modes
