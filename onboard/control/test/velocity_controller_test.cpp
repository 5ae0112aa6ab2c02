#include "hq/control/velocity_controller.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"

#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace hq::control {
namespace {

using testing::HasSubstr;

constexpr std::int64_t kStepNs = 5'000'000;  // 200 Hz control
constexpr double kDt = 5e-3;
constexpr double kDeg = M_PI / 180.0;

VehicleConfig test_vehicle() {
  VehicleConfig vehicle;
  vehicle.mass_kg = 1.0;
  vehicle.max_tilt_rad = 30.0 * kDeg;
  vehicle.min_thrust_n = 2.0;
  vehicle.max_thrust_n = 20.0;
  return vehicle;
}

// Point mass whose attitude follows the setpoint instantly: the thrust -T z_Q, rotated into H
// by R_HQ = Ry(pitch) Rx(roll), plus gravity (NED).
struct PointMass {
  double mass_kg = 1.0;
  Eigen::Vector3d v_mps = Eigen::Vector3d::Zero();
  void step(const AttitudeSetpoint& sp, double dt_s) {
    const Eigen::Matrix3d R_HQ = (Eigen::AngleAxisd(sp.pitch_rad, Eigen::Vector3d::UnitY()) *
                                  Eigen::AngleAxisd(sp.roll_rad, Eigen::Vector3d::UnitX()))
                                     .toRotationMatrix();
    const Eigen::Vector3d a =
        R_HQ * Eigen::Vector3d(0, 0, -sp.thrust_n) / mass_kg + Eigen::Vector3d(0, 0, kGravityMps2);
    v_mps += a * dt_s;
  }
};

struct StepResponse {
  double peak = 0.0;
  double final_error = 0.0;
  double settle_s = 0.0;  // last time |v - target| exceeded 2 % of the step
};

StepResponse step_response(VelocityController& controller, const Eigen::Vector3d& target, int axis,
                           double duration_s) {
  PointMass plant;
  StepResponse response;
  const int steps = static_cast<int>(duration_s / kDt);
  for (int k = 0; k < steps; ++k) {
    const ControlOutput out = controller.update(k * kStepNs, target, 0.0, plant.v_mps);
    plant.step(out.setpoint, kDt);
    const double v = plant.v_mps[axis];
    response.peak = std::max(response.peak, v / target[axis]);
    if (std::abs(v - target[axis]) > 0.02 * std::abs(target[axis])) response.settle_s = k * kDt;
  }
  response.final_error = std::abs(plant.v_mps[axis] - target[axis]);
  return response;
}

TEST(VelocityController, HoverGivesWeightAndNoTilt) {
  VelocityController controller(VelocityControllerConfig{}, test_vehicle());
  for (int k = 0; k < 10; ++k) {
    const ControlOutput out =
        controller.update(k * kStepNs, Eigen::Vector3d::Zero(), 0.0, Eigen::Vector3d::Zero());
    EXPECT_DOUBLE_EQ(out.setpoint.thrust_n, 1.0 * kGravityMps2);
    EXPECT_DOUBLE_EQ(out.setpoint.roll_rad, 0.0);
    EXPECT_DOUBLE_EQ(out.setpoint.pitch_rad, 0.0);
    EXPECT_FALSE(out.safe_hover);
  }
}

TEST(VelocityController, SignsFollowNed) {
  VelocityController controller(VelocityControllerConfig{}, test_vehicle());
  // Forward (+x): nose down (pitch < 0). Right (+y): roll right (> 0). Climb (v_z < 0): more
  // thrust.
  const ControlOutput out =
      controller.update(0, Eigen::Vector3d(1.0, 1.0, -1.0), 0.0, Eigen::Vector3d::Zero());
  EXPECT_LT(out.setpoint.pitch_rad, 0.0);
  EXPECT_GT(out.setpoint.roll_rad, 0.0);
  EXPECT_GT(out.setpoint.thrust_n, kGravityMps2);
}

TEST(VelocityController, StepInDesiredVelocityConvergesWithBoundedOvershoot) {
  // GIVEN the point mass at rest WHEN 1 m/s forward is commanded THEN it settles.
  VelocityController horizontal(VelocityControllerConfig{}, test_vehicle());
  const StepResponse x = step_response(horizontal, Eigen::Vector3d(1.0, 0.0, 0.0), 0, 10.0);
  // Measured with the default gains: peak 1.132 (13 % overshoot), 2 % settling 3.99 s.
  EXPECT_LT(x.peak, 1.16) << x.peak;
  EXPECT_LT(x.settle_s, 4.5) << x.settle_s;
  EXPECT_LT(x.final_error, 0.005);

  VelocityController vertical(VelocityControllerConfig{}, test_vehicle());
  const StepResponse z = step_response(vertical, Eigen::Vector3d(0.0, 0.0, -0.5), 2, 10.0);
  // Measured: peak 1.117 (12 % overshoot), settling 3.3 s.
  EXPECT_LT(z.peak, 1.15) << z.peak;
  EXPECT_LT(z.settle_s, 3.8) << z.settle_s;
  EXPECT_LT(z.final_error, 0.005);
}

TEST(VelocityController, LongSaturationDoesNotWindUp) {
  // Only conditional integration may stop windup here: the integral clamp is out of the way.
  VelocityControllerConfig config;
  config.max_integral_m = 1e3;
  VelocityController controller(config, test_vehicle());
  const Eigen::Vector3d target(3.0, 0.0, 0.0);
  // GIVEN the vehicle held in place (against a wall) for 10 s while 3 m/s is commanded.
  std::int64_t t_ns = 0;
  for (int k = 0; k < 2000; ++k, t_ns += kStepNs) {
    const ControlOutput out = controller.update(t_ns, target, 0.0, Eigen::Vector3d::Zero());
    ASSERT_TRUE(out.tilt_saturated);
    ASSERT_LE(std::hypot(out.setpoint.roll_rad, out.setpoint.pitch_rad), 30.0 * kDeg + 1e-9);
  }
  EXPECT_LT(std::abs(controller.integral_m().x()), 1e-9);
  // WHEN released THEN it behaves like a fresh step: bounded overshoot, settles.
  PointMass plant;
  double peak = 0.0;
  double settle_s = 0.0;
  for (int k = 0; k < 2000; ++k, t_ns += kStepNs) {
    const ControlOutput out = controller.update(t_ns, target, 0.0, plant.v_mps);
    plant.step(out.setpoint, kDt);
    peak = std::max(peak, plant.v_mps.x());
    if (std::abs(plant.v_mps.x() - 3.0) > 0.06) settle_s = k * kDt;
  }
  // The same step from a fresh controller is the reference: measured peak 3.278 m/s and
  // settling 3.8 s for both. A wound-up integral (10 s x 3 m/s x ki 2 = 60 m/s^2) would keep
  // the tilt saturated long after passing 3 m/s.
  VelocityController fresh(config, test_vehicle());
  const StepResponse reference = step_response(fresh, target, 0, 10.0);
  EXPECT_LT(peak, 3.0 * reference.peak + 0.05) << peak;
  EXPECT_LT(settle_s, reference.settle_s + 0.5) << settle_s;
}

TEST(VelocityController, LimitsHoldForHugeCommands) {
  VelocityController controller(VelocityControllerConfig{}, test_vehicle());
  const ControlOutput up =
      controller.update(0, Eigen::Vector3d(50.0, -50.0, -50.0), 10.0, Eigen::Vector3d::Zero());
  EXPECT_LE(up.setpoint.thrust_n, 20.0 + 1e-9);
  EXPECT_TRUE(up.thrust_saturated);
  EXPECT_TRUE(up.tilt_saturated);
  const double tilt = std::acos(std::cos(up.setpoint.roll_rad) * std::cos(up.setpoint.pitch_rad));
  EXPECT_LE(tilt, 30.0 * kDeg + 1e-9);
  EXPECT_DOUBLE_EQ(up.setpoint.yaw_rate_radps, test_vehicle().max_yaw_rate_radps);
  const ControlOutput down =
      controller.update(kStepNs, Eigen::Vector3d(0.0, 0.0, 50.0), 0.0, Eigen::Vector3d::Zero());
  EXPECT_GE(down.setpoint.thrust_n, 2.0 - 1e-9);
}

TEST(VelocityController, NanEstimateGivesSafeHoverAndAFlag) {
  VelocityController controller(VelocityControllerConfig{}, test_vehicle());
  controller.update(0, Eigen::Vector3d(1.0, 0.0, 0.0), 0.0, Eigen::Vector3d::Zero());
  const ControlOutput out = controller.update(kStepNs, Eigen::Vector3d(1.0, 0.0, 0.0), 0.3,
                                              Eigen::Vector3d(std::nan(""), 0.0, 0.0));
  EXPECT_TRUE(out.safe_hover);
  EXPECT_THAT(out.reason, HasSubstr("non-finite"));
  EXPECT_DOUBLE_EQ(out.setpoint.thrust_n, kGravityMps2);
  EXPECT_EQ(out.setpoint.roll_rad, 0.0);
  EXPECT_EQ(out.setpoint.pitch_rad, 0.0);
  EXPECT_EQ(out.setpoint.yaw_rate_radps, 0.0);
  EXPECT_TRUE(controller.integral_m().allFinite());
}

TEST(VelocityController, NoEstimateGivesSafeHoverSayingSoAndKeepsTheIntegral) {
  VelocityController controller(VelocityControllerConfig{}, test_vehicle());
  for (int k = 0; k < 50; ++k) {
    controller.update(k * kStepNs, Eigen::Vector3d(0.3, 0.0, 0.0), 0.0, Eigen::Vector3d::Zero());
  }
  const Eigen::Vector3d integral_before = controller.integral_m();
  ASSERT_GT(integral_before.x(), 0.0);
  const ControlOutput out =
      controller.update(50 * kStepNs, Eigen::Vector3d(1.0, 0.0, 0.0), 0.3, std::nullopt);
  EXPECT_TRUE(out.safe_hover);
  EXPECT_STREQ(out.reason, "no velocity estimate: hover");
  EXPECT_DOUBLE_EQ(out.setpoint.thrust_n, kGravityMps2);
  EXPECT_EQ(out.setpoint.yaw_rate_radps, 0.0);
  EXPECT_EQ(controller.integral_m(), integral_before);
}

TEST(VehicleConfig, ShippedCorePaperVehicleLoads) {
  const VehicleConfig vehicle = load_vehicle_config("calib/vehicle_core_paper.yaml");
  EXPECT_DOUBLE_EQ(vehicle.mass_kg, 1.0);
  EXPECT_NEAR(vehicle.max_tilt_rad, 30.0 * kDeg, 1e-12);
  // The optical axis looks 45 deg right and 30 deg down in Q (NED: z down is positive).
  const Eigen::Vector3d axis = vehicle.camera.R_B_C().col(2);
  EXPECT_TRUE(
      axis.isApprox(Eigen::Vector3d(std::cos(30 * kDeg) * std::cos(45 * kDeg),
                                    std::cos(30 * kDeg) * std::sin(45 * kDeg), std::sin(30 * kDeg)),
                    1e-12));
  // Image "right" (optical x) stays horizontal with zero camera roll; "down" (y) points down-ish.
  EXPECT_NEAR(vehicle.camera.R_B_C().col(0).z(), 0.0, 1e-12);
  EXPECT_GT(vehicle.camera.R_B_C().col(1).z(), 0.0);
  EXPECT_NEAR(vehicle.camera.R_B_C().determinant(), 1.0, 1e-12);
  EXPECT_TRUE(vehicle.camera.p_B_C_m().isApprox(Eigen::Vector3d(0.10, 0.05, 0.03)));
}

// GIVEN a vehicle file written before the frame-letter rename (the mount keys spelt in words),
// WHEN read, THEN it gives the same mount as the file with T_B_C and p_B_C_m.
TEST(VehicleConfig, FileWithTheMountKeysOfBeforeTheRenameLoadsTheSameMount) {
  const std::string limits =
      "{mass_kg: 1.0, limits: {max_tilt_deg: 30, min_thrust_n: 2, max_thrust_n: 20, "
      "max_yaw_rate_degps: 90}, ";
  config::StrictMap before(
      YAML::Load(
          limits +
          "T_body_camera: {yaw_deg: 45, pitch_deg: -30, roll_deg: 0, "  // vocabulary: old spelling
          "p_body_camera_m: [0.1, 0.05, 0.03]}}"),                      // vocabulary: old spelling
      "old.yaml");
  config::StrictMap now(YAML::Load(limits + "T_B_C: {yaw_deg: 45, pitch_deg: -30, roll_deg: 0, "
                                            "p_B_C_m: [0.1, 0.05, 0.03]}}"),
                        "new.yaml");
  VehicleConfig old_vehicle;
  VehicleConfig new_vehicle;
  read_config(before, old_vehicle);
  read_config(now, new_vehicle);
  EXPECT_TRUE(old_vehicle.camera.R_B_C().isApprox(new_vehicle.camera.R_B_C(), 1e-15));
  EXPECT_TRUE(old_vehicle.camera.p_B_C_m().isApprox(Eigen::Vector3d(0.1, 0.05, 0.03)));
  EXPECT_GT((old_vehicle.camera.R_B_C() - Eigen::Matrix3d::Identity()).norm(), 0.5);
}

TEST(VehicleConfig, BadValueIsRejectedNamingTheKey) {
  const YAML::Node node = YAML::Load(
      "{mass_kg: 1.0, limits: {max_tilt_deg: 95, min_thrust_n: 2, max_thrust_n: 20, "
      "max_yaw_rate_degps: 90}, T_B_C: {yaw_deg: 45, pitch_deg: -30, roll_deg: 0, "
      "p_B_C_m: [0.1, 0, 0]}}");
  config::StrictMap root(node, "calib/vehicle_core_paper.yaml");
  VehicleConfig vehicle;
  try {
    read_config(root, vehicle);
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(),
                HasSubstr("calib/vehicle_core_paper.yaml: limits.max_tilt_deg = 95, expected in"));
  }
  config::StrictMap missing(YAML::Load("{mass_kg: 1.0}"), "v.yaml");
  EXPECT_THROW(read_config(missing, vehicle), InputError);
}

// The mount is checked once, where the file is read: a camera looking straight down has no
// heading for eq. 9, and the file says so instead of a component failing later.
TEST(VehicleConfig, VerticalCameraIsRejectedWhereTheFileIsRead) {
  const YAML::Node node = YAML::Load(
      "{mass_kg: 1.0, limits: {max_tilt_deg: 30, min_thrust_n: 2, max_thrust_n: 20, "
      "max_yaw_rate_degps: 90}, T_B_C: {yaw_deg: 0, pitch_deg: -90, roll_deg: 0, "
      "p_B_C_m: [0.1, 0, 0]}}");
  config::StrictMap root(node, "calib/down.yaml");
  VehicleConfig vehicle;
  try {
    read_config(root, vehicle);
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("calib/down.yaml: T_B_C.pitch_deg"));
    EXPECT_THAT(e.what(), HasSubstr("within 3 deg of vertical"));
  }
}

TEST(VelocityControllerConfig, BadValueIsRejectedNamingTheKey) {
  config::StrictMap section(YAML::Load("{kp_xy_per_s: -2}"), "config/onboard.yaml", "control");
  VelocityControllerConfig config;
  try {
    read_config(section, config);
    FAIL() << "expected hq::InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("config/onboard.yaml: control.kp_xy_per_s = -2"));
  }
}

TEST(VelocityControllerConfig, ShippedOnboardYamlSectionLoads) {
  const YAML::Node root = config::load_yaml_file("config/onboard.yaml");
  config::StrictMap section(root["control"], "config/onboard.yaml", "control");
  VelocityControllerConfig config;
  EXPECT_NO_THROW(read_config(section, config));
}

// All-zero PID gains never track a command: the proportional gains must be positive, the
// integral and derivative ones may be zero.
TEST(VelocityControllerConfig, ZeroProportionalGainIsRejected) {
  const auto error_of = [](const char* yaml) -> std::string {
    config::StrictMap section(YAML::Load(yaml), "config/onboard.yaml", "control");
    VelocityControllerConfig config;
    try {
      read_config(section, config);
    } catch (const InputError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_THAT(error_of("{kp_xy_per_s: 0, ki_xy_per_s2: 0, kd_xy: 0, kp_z_per_s: 0}"),
              HasSubstr("config/onboard.yaml: control.kp_xy_per_s = 0, expected > 0"));
  EXPECT_THAT(error_of("{kp_z_per_s: 0}"),
              HasSubstr("config/onboard.yaml: control.kp_z_per_s = 0, expected > 0"));
  EXPECT_EQ(error_of("{kp_xy_per_s: 1, ki_xy_per_s2: 0, kd_xy: 0, ki_z_per_s2: 0, kd_z: 0}"),
            "no error");
}

}  // namespace
}  // namespace hq::control
