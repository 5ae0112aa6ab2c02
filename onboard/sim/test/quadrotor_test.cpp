#include "hq/sim/quadrotor.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace hq::sim {
namespace {

constexpr double kG = 9.81;
constexpr double kDt = 1e-3;

QuadrotorParams calm_params() {
  QuadrotorParams p;
  p.gust_sigma_mps = 0.0;
  return p;
}

TEST(QuadrotorTest, EulerAnglesRoundTripThroughRWorldBody) {
  for (double roll : {-0.4, 0.0, 0.3}) {
    for (double pitch : {-0.5, 0.1}) {
      for (double yaw : {-2.5, 0.0, 1.2}) {
        const Eigen::Vector3d e = euler_from_R_N_B(R_N_B_from_euler(roll, pitch, yaw));
        EXPECT_NEAR(e.x(), roll, 1e-12);
        EXPECT_NEAR(e.y(), pitch, 1e-12);
        EXPECT_NEAR(e.z(), yaw, 1e-12);
      }
    }
  }
  // Level, yaw 0: body NED x = world x (north), body z (down) = world -z.
  const Eigen::Matrix3d R = R_N_B_from_euler(0.0, 0.0, 0.0);
  EXPECT_TRUE(R.col(0).isApprox(Eigen::Vector3d::UnitX()));
  EXPECT_TRUE(R.col(2).isApprox(-Eigen::Vector3d::UnitZ()));
}

TEST(QuadrotorTest, HoverThrustKeepsAltitudeWithAttitudeController) {
  Quadrotor q(calm_params(), 1);
  q.reset(Eigen::Vector3d(0.0, 0.0, 1.0), 0.3);
  q.set_command({q.hover_thrust_n(), 0.0, 0.0, 0.0});
  for (int i = 0; i < 5000; ++i) q.step(kDt);
  EXPECT_NEAR(q.state().p_N_m.z(), 1.0, 0.01);
  EXPECT_LT(q.state().v_N_mps.norm(), 0.01);
  EXPECT_FALSE(q.state().on_ground);
}

TEST(QuadrotorTest, RollSetpointGivesLateralAccelerationGTanRoll) {
  QuadrotorParams p = calm_params();
  p.linear_drag_nspm = 0.0;
  Quadrotor q(p, 1);
  q.reset(Eigen::Vector3d(0.0, 0.0, 2.0), 0.0);
  const double roll = 0.2;
  q.set_command({q.hover_thrust_n() / std::cos(roll), roll, 0.0, 0.0});
  for (int i = 0; i < 1000; ++i) q.step(kDt);  // attitude settles (3 Hz loop)
  const Eigen::Vector3d v0 = q.state().v_N_mps;
  for (int i = 0; i < 500; ++i) q.step(kDt);
  const Eigen::Vector3d a = (q.state().v_N_mps - v0) / 0.5;
  EXPECT_NEAR(q.state().p_N_m.z(), 2.0, 0.05);
  // Right wing down (NED roll > 0) accelerates east = world -y (NWU).
  EXPECT_NEAR(a.y(), -kG * std::tan(roll), 0.03 * kG * std::tan(roll));
  EXPECT_NEAR(a.x(), 0.0, 0.02);
  EXPECT_NEAR(a.z(), 0.0, 0.05);
  EXPECT_NEAR(euler_from_R_N_B(q.state().q_N_B.toRotationMatrix()).x(), roll, 0.005);
}

TEST(QuadrotorTest, PitchNoseDownAcceleratesNorth) {
  QuadrotorParams p = calm_params();
  p.linear_drag_nspm = 0.0;
  Quadrotor q(p, 1);
  q.reset(Eigen::Vector3d(0.0, 0.0, 2.0), 0.0);
  q.set_command({q.hover_thrust_n() / std::cos(0.1), 0.0, -0.1, 0.0});
  for (int i = 0; i < 1000; ++i) q.step(kDt);
  EXPECT_GT(q.state().v_N_mps.x(), 0.3);
}

TEST(QuadrotorTest, YawRateCommandTurnsTheVehicle) {
  Quadrotor q(calm_params(), 1);
  q.reset(Eigen::Vector3d(0.0, 0.0, 1.0), 0.0);
  q.set_command({q.hover_thrust_n(), 0.0, 0.0, 0.5});
  for (int i = 0; i < 2000; ++i) q.step(kDt);
  const double yaw = euler_from_R_N_B(q.state().q_N_B.toRotationMatrix()).z();
  EXPECT_NEAR(yaw, 1.0, 0.1);  // 0.5 rad/s for 2 s, less the loop's lag
}

TEST(QuadrotorTest, RestsOnFloorWithoutThrustAndTakesOffWithMore) {
  Quadrotor q(calm_params(), 1);
  q.reset(Eigen::Vector3d(1.0, 2.0, 0.0), 0.0);
  for (int i = 0; i < 1000; ++i) q.step(kDt);
  EXPECT_TRUE(q.state().on_ground);
  EXPECT_DOUBLE_EQ(q.state().p_N_m.z(), q.params().rest_height_m);
  EXPECT_EQ(q.state().v_N_mps.norm(), 0.0);
  q.set_command({1.3 * q.hover_thrust_n(), 0.0, 0.0, 0.0});
  for (int i = 0; i < 1000; ++i) q.step(kDt);
  EXPECT_FALSE(q.state().on_ground);
  EXPECT_GT(q.state().p_N_m.z(), 0.5);
}

TEST(QuadrotorTest, FallingVehicleStopsAtTheFloor) {
  Quadrotor q(calm_params(), 1);
  q.reset(Eigen::Vector3d(0.0, 0.0, 1.5), 0.0);
  q.set_command({0.0, 0.0, 0.0, 0.0});
  for (int i = 0; i < 3000; ++i) q.step(kDt);
  EXPECT_TRUE(q.state().on_ground);
  EXPECT_GE(q.state().p_N_m.z(), q.params().rest_height_m - 1e-12);
}

TEST(QuadrotorTest, SameSeedGivesSameGustyFlight) {
  QuadrotorParams p;
  p.gust_sigma_mps = 0.5;
  Quadrotor a(p, 42);
  Quadrotor b(p, 42);
  Quadrotor c(p, 43);
  for (Quadrotor* q : {&a, &b, &c}) {
    q->reset(Eigen::Vector3d(0.0, 0.0, 1.0), 0.0);
    q->set_command({q->hover_thrust_n(), 0.0, 0.0, 0.0});
    for (int i = 0; i < 2000; ++i) q->step(kDt);
  }
  EXPECT_EQ(a.state().p_N_m, b.state().p_N_m);
  EXPECT_NE(a.state().p_N_m, c.state().p_N_m);
  EXPECT_GT(a.state().v_N_mps.head<2>().norm(), 1e-3);  // the gusts push it
}

}  // namespace
}  // namespace hq::sim
