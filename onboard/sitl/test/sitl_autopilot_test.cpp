// SitlAutopilot, the PX4-like flight controller of hq-sim --sitl: arming and offboard rules,
// setpoint conversion, the offboard failsafes into LAND and the disarm on the ground, the
// messages it streams, the vision velocity it fuses as PX4 would and TIMESYNC.
#include "hq/sitl/sitl_autopilot.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fmt/format.h>
#include <limits>
#include <random>
#include <string>
#include <vector>

namespace {

namespace mav = hq::mavlink;
using hq::sim::TruthState;
using hq::sitl::SitlAutopilot;
using hq::sitl::SitlMode;
using ::testing::HasSubstr;

constexpr std::int64_t kMs = 1'000'000;

class Capture final : public hq::sitl::MessageSink {
 public:
  void send(const mav::Message& message) override { messages.push_back(message); }
  template <typename T>
  std::vector<T> all() const {
    std::vector<T> out;
    for (const mav::Message& m : messages) {
      if (const T* t = std::get_if<T>(&m)) out.push_back(*t);
    }
    return out;
  }
  std::string texts() const {
    std::string out;
    for (const mav::Statustext& s : all<mav::Statustext>()) {
      out.append(s.text.data(), strnlen(s.text.data(), s.text.size())).append("\n");
    }
    return out;
  }
  std::vector<mav::Message> messages;
};

mav::CommandLong command(std::uint16_t id, float p1, float p2 = 0, float p3 = 0) {
  mav::CommandLong c;
  c.command = id;
  c.param[0] = p1;
  c.param[1] = p2;
  c.param[2] = p3;
  c.target_system = 1;
  c.target_component = 1;
  return c;
}

mav::Heartbeat companion_heartbeat() {
  mav::Heartbeat h;
  h.type = mav::kMavTypeOnboardController;
  h.autopilot = mav::kMavAutopilotInvalid;
  return h;
}

mav::SetAttitudeTarget level_setpoint(float thrust) {
  mav::SetAttitudeTarget s;
  s.target_system = 1;
  s.thrust = thrust;
  s.type_mask = mav::kAttitudeTargetIgnoreBodyRollRate | mav::kAttitudeTargetIgnoreBodyPitchRate;
  return s;
}

TruthState airborne(double altitude_m, double v_up_mps = 0.0) {
  TruthState t;
  t.on_ground = false;
  t.T_N_B.translation().z() = altitude_m;
  t.v_N_mps.z() = v_up_mps;
  return t;
}

class SitlAutopilotTest : public ::testing::Test {
 protected:
  /// Heartbeat, a setpoint, OFFBOARD, ARM at t = 0..3 ms: flying our setpoints.
  void arm_offboard(const TruthState& truth) {
    ap_.on_message(0, 1, 191, companion_heartbeat(), truth, out_);
    ap_.on_message(1 * kMs, 1, 191, level_setpoint(0.3f), truth, out_);
    ap_.on_message(2 * kMs, 1, 191, command(mav::kMavCmdDoSetMode, 1, 6), truth, out_);
    ap_.on_message(3 * kMs, 1, 191, command(mav::kMavCmdComponentArmDisarm, 1), truth, out_);
    ASSERT_TRUE(ap_.armed());
    ASSERT_EQ(ap_.mode(), SitlMode::kOffboard);
  }
  hq::sim::QuadrotorParams params_;
  SitlAutopilot ap_{params_};
  Capture out_;
};

TEST_F(SitlAutopilotTest, MaxThrustIsFourRotorsAtFullSpeed) {
  EXPECT_NEAR(ap_.max_thrust_n(), 4.0 * 6.8e-6 * 1100.0 * 1100.0, 1e-9);
}

TEST_F(SitlAutopilotTest, ArmingWithoutACompanionHeartbeatIsRefusedWithAReason) {
  TruthState ground;
  ap_.on_message(0, 1, 191, command(mav::kMavCmdComponentArmDisarm, 1), ground, out_);
  EXPECT_FALSE(ap_.armed());
  ASSERT_EQ(out_.all<mav::CommandAck>().size(), 1u);
  EXPECT_EQ(out_.all<mav::CommandAck>()[0].result, 1) << "MAV_RESULT_TEMPORARILY_REJECTED";
  EXPECT_EQ(out_.all<mav::CommandAck>()[0].target_component, 191);
  EXPECT_THAT(out_.texts(), HasSubstr("arming refused: no companion heartbeat yet"));
}

TEST_F(SitlAutopilotTest, OffboardNeedsASetpointStreamAsPx4Does) {
  TruthState ground;
  ap_.on_message(0, 1, 191, command(mav::kMavCmdDoSetMode, 1, 6), ground, out_);
  EXPECT_EQ(ap_.mode(), SitlMode::kPosctl);
  EXPECT_EQ(out_.all<mav::CommandAck>().back().result, 1);
  EXPECT_THAT(out_.texts(), HasSubstr("offboard refused: no setpoint stream"));
  ap_.on_message(100 * kMs, 1, 191, level_setpoint(0.0f), ground, out_);
  ap_.on_message(700 * kMs, 1, 191, command(mav::kMavCmdDoSetMode, 1, 6), ground, out_);
  EXPECT_EQ(ap_.mode(), SitlMode::kPosctl) << "the last setpoint is 0.6 s old";
  ap_.on_message(800 * kMs, 1, 191, level_setpoint(0.0f), ground, out_);
  ap_.on_message(900 * kMs, 1, 191, command(mav::kMavCmdDoSetMode, 1, 6), ground, out_);
  EXPECT_EQ(ap_.mode(), SitlMode::kOffboard);
  EXPECT_EQ(out_.all<mav::CommandAck>().back().result, mav::kMavResultAccepted);
  EXPECT_EQ(out_.all<mav::Heartbeat>().back().custom_mode, 6u << 16);
}

TEST_F(SitlAutopilotTest, SetpointsAreFlownOnlyArmedAndInOffboard) {
  TruthState ground;
  mav::SetAttitudeTarget s = level_setpoint(0.5f);
  // q of ZYX Euler (roll 0.1, pitch -0.2, yaw 0.7) of the body FRD in NED.
  const Eigen::Quaterniond q = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX());
  s.q = {static_cast<float>(q.w()), static_cast<float>(q.x()), static_cast<float>(q.y()),
         static_cast<float>(q.z())};
  s.body_yaw_rate_radps = 0.3f;
  ap_.on_message(0, 1, 191, companion_heartbeat(), ground, out_);
  ap_.on_message(0, 1, 191, s, ground, out_);
  EXPECT_EQ(ap_.update(1 * kMs, ground, out_).thrust_n, 0.0) << "disarmed";
  ap_.on_message(2 * kMs, 1, 191, command(mav::kMavCmdComponentArmDisarm, 1), ground, out_);
  EXPECT_EQ(ap_.update(3 * kMs, ground, out_).thrust_n, 0.0) << "armed in POSCTL on the ground";
  ap_.on_message(4 * kMs, 1, 191, command(mav::kMavCmdDoSetMode, 1, 6), ground, out_);
  const hq::sim::AttitudeCommand c = ap_.update(5 * kMs, ground, out_);
  EXPECT_NEAR(c.thrust_n, 0.5 * ap_.max_thrust_n(), 1e-4);
  EXPECT_NEAR(c.roll_rad, 0.1, 1e-6);
  EXPECT_NEAR(c.pitch_rad, -0.2, 1e-6);
  EXPECT_NEAR(c.yaw_rate_radps, 0.3, 1e-6);
  s.type_mask |= mav::kAttitudeTargetIgnoreBodyYawRate;
  ap_.on_message(6 * kMs, 1, 191, s, ground, out_);
  EXPECT_EQ(ap_.update(7 * kMs, ground, out_).yaw_rate_radps, 0.0);
  const mav::Heartbeat h = out_.all<mav::Heartbeat>().back();
  EXPECT_EQ(h.base_mode, mav::kMavModeFlagCustomModeEnabled | mav::kMavModeFlagSafetyArmed);
  EXPECT_EQ(h.autopilot, mav::kMavAutopilotPx4);
  EXPECT_EQ(h.type, mav::kMavTypeQuadrotor);

  s.thrust = std::nanf("");
  ap_.on_message(8 * kMs, 1, 191, s, ground, out_);
  EXPECT_EQ(ap_.stats().setpoints_rejected, 1u);
}

TEST_F(SitlAutopilotTest, LostSetpointsLandAtHalfAMetrePerSecondThenDisarmOnTheGround) {
  TruthState flying = airborne(2.0);
  arm_offboard(flying);
  EXPECT_EQ(ap_.mode(), SitlMode::kOffboard);
  ap_.update(400 * kMs, flying, out_);
  EXPECT_EQ(ap_.mode(), SitlMode::kOffboard) << "0.4 s without a setpoint is within COM_OF_LOSS_T";
  const hq::sim::AttitudeCommand c = ap_.update(502 * kMs, flying, out_);
  EXPECT_EQ(ap_.mode(), SitlMode::kLand);
  EXPECT_THAT(out_.texts(), HasSubstr("offboard setpoints lost: landing"));
  EXPECT_EQ(out_.all<mav::Heartbeat>().back().custom_mode, 4u << 16 | 6u << 24);
  EXPECT_EQ(c.roll_rad, 0.0);
  EXPECT_EQ(c.pitch_rad, 0.0);
  EXPECT_LT(c.thrust_n, params_.mass_kg * 9.81) << "hovering: less thrust to start descending";
  // No vision: it descends on the barometer-like rate, whose error (0.1 m/s sigma) the 2/s
  // loop turns into at most 3 sigma x 2/s x m of thrust.
  EXPECT_NEAR(ap_.update(510 * kMs, airborne(1.5, -0.5), out_).thrust_n, params_.mass_kg * 9.81,
              3.0 * 0.1 * 2.0 * params_.mass_kg)
      << "at 0.5 m/s down: hover thrust";

  TruthState ground;
  ap_.update(2000 * kMs, ground, out_);
  EXPECT_TRUE(ap_.armed()) << "on the ground for less than 0.5 s";
  ap_.update(2500 * kMs, ground, out_);
  EXPECT_FALSE(ap_.armed());
  EXPECT_THAT(out_.texts(), HasSubstr("landed: disarmed"));
  EXPECT_EQ(ap_.update(2600 * kMs, ground, out_).thrust_n, 0.0);
}

TEST_F(SitlAutopilotTest, ASilentCompanionLandsTheVehicle) {
  TruthState flying = airborne(2.0);
  arm_offboard(flying);
  for (std::int64_t t = 10 * kMs; t < 2100 * kMs; t += 20 * kMs) {
    ap_.on_message(t, 1, 191, level_setpoint(0.3f), flying, out_);
    ap_.update(t, flying, out_);
  }
  EXPECT_EQ(ap_.mode(), SitlMode::kLand);
  EXPECT_THAT(out_.texts(), HasSubstr("companion heartbeat lost: landing"));
}

TEST_F(SitlAutopilotTest, DisarmInTheAirNeedsTheForceMagic) {
  TruthState flying = airborne(2.0);
  arm_offboard(flying);
  ap_.on_message(10 * kMs, 1, 191, command(mav::kMavCmdComponentArmDisarm, 0), flying, out_);
  EXPECT_TRUE(ap_.armed());
  EXPECT_EQ(out_.all<mav::CommandAck>().back().result, 2) << "MAV_RESULT_DENIED";
  ap_.on_message(20 * kMs, 1, 191, command(mav::kMavCmdComponentArmDisarm, 0, 21196), flying, out_);
  EXPECT_FALSE(ap_.armed());
  EXPECT_EQ(out_.all<mav::CommandAck>().back().result, mav::kMavResultAccepted);
}

TEST_F(SitlAutopilotTest, StreamsAttitudeAt50HzAndStatusAt1HzAndAcksEveryCommand) {
  TruthState ground;
  ground.euler_rad = Eigen::Vector3d(0.01, -0.02, 1.2);
  for (std::int64_t t = 0; t < 1000 * kMs; t += 2 * kMs) ap_.update(t, ground, out_);
  EXPECT_EQ(out_.all<mav::Attitude>().size(), 50u);
  EXPECT_FLOAT_EQ(out_.all<mav::Attitude>()[0].yaw_rad, 1.2f);
  EXPECT_EQ(out_.all<mav::Heartbeat>().size(), 1u);
  ASSERT_EQ(out_.all<mav::SysStatus>().size(), 1u);
  EXPECT_EQ(out_.all<mav::SysStatus>()[0].voltage_battery_mv, 16800);
  // MAV_CMD_SET_MESSAGE_INTERVAL is accepted, as PX4 does; a command it does not know is not.
  ap_.on_message(0, 1, 191, command(mav::kMavCmdSetMessageInterval, 105), ground, out_);
  EXPECT_EQ(out_.all<mav::CommandAck>().back().command, mav::kMavCmdSetMessageInterval);
  EXPECT_EQ(out_.all<mav::CommandAck>().back().result, mav::kMavResultAccepted);
  ap_.on_message(0, 1, 191, command(520, 0), ground, out_);
  EXPECT_EQ(out_.all<mav::CommandAck>().back().command, 520);
  EXPECT_EQ(out_.all<mav::CommandAck>().back().result, 3) << "MAV_RESULT_UNSUPPORTED";
  mav::CommandLong other = command(mav::kMavCmdComponentArmDisarm, 1);
  other.target_system = 2;
  const std::size_t acks = out_.all<mav::CommandAck>().size();
  ap_.on_message(0, 1, 191, other, ground, out_);
  EXPECT_EQ(out_.all<mav::CommandAck>().size(), acks) << "for system 2: not acked";
}

TEST_F(SitlAutopilotTest, ImuSamplesBecomeHighresImuInMicrosecondsOfSimulatedTime) {
  hq::sim::ImuSample s;
  s.t_ns = 1'234'000'000;
  s.f_B_mps2 = Eigen::Vector3d(0.1, 0.2, -9.81);
  s.omega_B_radps = Eigen::Vector3d(0.01, 0.02, 0.03);
  ap_.on_imu(s, TruthState{}, out_);
  const mav::HighresImu m = out_.all<mav::HighresImu>().at(0);
  EXPECT_EQ(m.time_usec, 1'234'000u);
  EXPECT_FLOAT_EQ(m.zacc_mps2, -9.81f);
  EXPECT_FLOAT_EQ(m.ygyro_radps, 0.02f);
  EXPECT_EQ(m.fields_updated, 0x3F);
}

mav::Odometry body_odometry(std::int64_t t_ns, const Eigen::Vector3d& v_B_mps,
                            double variance_m2ps2, std::uint8_t reset_counter = 0) {
  mav::Odometry o;
  o.time_usec = static_cast<std::uint64_t>(t_ns / 1000);
  o.x_m = o.y_m = o.z_m = std::numeric_limits<float>::quiet_NaN();
  o.q.fill(std::numeric_limits<float>::quiet_NaN());
  o.vx_mps = static_cast<float>(v_B_mps.x());
  o.vy_mps = static_cast<float>(v_B_mps.y());
  o.vz_mps = static_cast<float>(v_B_mps.z());
  o.velocity_covariance.fill(std::numeric_limits<float>::quiet_NaN());
  for (std::size_t i : {0u, 6u, 11u}) o.velocity_covariance[i] = static_cast<float>(variance_m2ps2);
  o.velocity_covariance[1] = o.velocity_covariance[2] = o.velocity_covariance[7] = 0.0f;
  o.frame_id = mav::kMavFrameLocalFrd;
  o.child_frame_id = mav::kMavFrameBodyFrd;
  o.estimator_type = mav::kMavEstimatorTypeVio;
  o.quality_pct = 90;
  o.reset_counter = reset_counter;
  return o;
}

hq::sim::ImuSample level_imu(std::int64_t t_ns, const Eigen::Vector3d& bias_mps2 = {0, 0, 0}) {
  hq::sim::ImuSample s;
  s.t_ns = t_ns;
  s.f_B_mps2 = Eigen::Vector3d(0.0, 0.0, -9.81) + bias_mps2;
  return s;
}

TEST_F(SitlAutopilotTest, VisionSpeedEstimateIsIgnoredCountedAndSaidOnce) {
  TruthState truth = airborne(1.0);
  mav::VisionSpeedEstimate v;
  v.x_mps = 1.0f;
  ap_.on_message(0, 1, 191, v, truth, out_);
  ap_.on_message(kMs, 1, 191, v, truth, out_);
  EXPECT_EQ(ap_.stats().vision_speed_ignored, 2u);
  EXPECT_EQ(ap_.stats().odometry_fused, 0u);
  const std::string texts = out_.texts();
  EXPECT_THAT(texts, HasSubstr("VISION_SPEED_ESTIMATE ignored"));
  EXPECT_EQ(texts.find("VISION_SPEED_ESTIMATE"), texts.rfind("VISION_SPEED_ESTIMATE"))
      << "said once";
}

TEST_F(SitlAutopilotTest, OdometryInAWrongFrameNanOrFromMocapIsRejectedWithItsReason) {
  TruthState truth = airborne(1.0);
  ap_.on_imu(level_imu(0), truth, out_);
  mav::Odometry o = body_odometry(0, Eigen::Vector3d(0.1, 0, 0), 0.01);
  o.child_frame_id = mav::kMavFrameLocalFrd;  // velocity in the VIO's own frame: not aligned
  ap_.on_message(0, 1, 191, o, truth, out_);
  o.child_frame_id = 8;  // MAV_FRAME_BODY_NED
  ap_.on_message(0, 1, 191, o, truth, out_);
  mav::Odometry nan = body_odometry(0, Eigen::Vector3d(0.1, 0, 0), 0.01);
  nan.vy_mps = std::numeric_limits<float>::quiet_NaN();
  ap_.on_message(0, 1, 191, nan, truth, out_);
  mav::Odometry mocap = body_odometry(0, Eigen::Vector3d(0.1, 0, 0), 0.01);
  mocap.estimator_type = 6;  // MAV_ESTIMATOR_TYPE_MOCAP: PX4 routes it away from EKF2
  ap_.on_message(0, 1, 191, mocap, truth, out_);
  const auto& st = ap_.stats();
  EXPECT_EQ(st.odometry_received, 4u);
  EXPECT_EQ(st.rejected_frame, 2u);
  EXPECT_EQ(st.rejected_nan, 1u);
  EXPECT_EQ(st.rejected_estimator, 1u);
  EXPECT_EQ(st.odometry_fused, 0u);
  ap_.on_message(0, 1, 191, body_odometry(0, Eigen::Vector3d(0.1, 0, 0), 0.01), truth, out_);
  EXPECT_EQ(ap_.stats().odometry_fused, 1u) << "the same velocity in BODY_FRD is taken";
}

TEST_F(SitlAutopilotTest, FusedOdometryIsCloserToTruthThanTheOdometryOrTheImuAlone) {
  // GIVEN a level vehicle cruising at constant velocity, a biased noisy accelerometer at 500 Hz
  // and a body velocity with 0.1 m/s of white noise at 30 Hz, stamped 40 ms late.
  TruthState truth = airborne(1.0);
  truth.v_N_mps = Eigen::Vector3d(0.5, -0.2, 0.1);  // NWU
  const Eigen::Vector3d v_NED(0.5, 0.2, -0.1);
  const Eigen::Vector3d bias(0.05, -0.04, 0.03);
  std::mt19937 rng(11);
  std::normal_distribution<double> unit(0.0, 1.0);
  const double accel_sigma = 2e-3 * std::sqrt(500.0);  // the sim's density at 500 Hz
  Eigen::Vector3d v_imu_only = v_NED;                  // dead reckoning from the truth at 0
  double imu_only_sq = 0.0;
  int imu_steps = 0;
  for (std::int64_t t = 0; t <= 20'000 * kMs; t += 2 * kMs) {
    hq::sim::ImuSample s = level_imu(t, bias);
    for (int i = 0; i < 3; ++i) s.f_B_mps2[i] += accel_sigma * unit(rng);
    ap_.on_imu(s, truth, out_);
    v_imu_only += (s.f_B_mps2 + Eigen::Vector3d(0, 0, 9.81)) * 0.002;
    imu_only_sq += (v_imu_only - v_NED).squaredNorm();
    ++imu_steps;
    if (t % (34 * kMs) == 0 && t >= 40 * kMs) {
      Eigen::Vector3d z = v_NED;
      for (int i = 0; i < 3; ++i) z[i] += 0.1 * unit(rng);
      ap_.on_message(t, 1, 191, body_odometry(t - 40 * kMs, z, 0.01), truth, out_);
    }
  }
  const auto& st = ap_.stats();
  const double raw = std::sqrt(st.raw_sq_error_sum / static_cast<double>(st.raw_samples));
  const double fused = std::sqrt(st.fused_sq_error_sum / static_cast<double>(st.fused_samples));
  const double imu_only = std::sqrt(imu_only_sq / imu_steps);
  fmt::print("RMSE (3 axes): odometry {:.3f}, fused {:.3f}, IMU alone {:.3f} m/s\n", raw, fused,
             imu_only);
  // THEN nearly all is fused, and the fusion beats both: white noise 0.17 m/s (3 axes) is
  // averaged down, the bias's drift (0.07 m/s^2 x 20 s) is held by the odometry.
  EXPECT_GT(st.odometry_fused, 550u);
  EXPECT_LT(st.rejected_gate, 10u);
  EXPECT_NEAR(raw, 0.1 * std::sqrt(3.0), 0.02);
  EXPECT_LT(fused, 0.5 * raw);
  EXPECT_LT(fused, 0.2 * imu_only);
}

TEST_F(SitlAutopilotTest, AResetCounterChangeReinitialisesInsteadOfFusingTheJump) {
  TruthState truth = airborne(1.0);
  std::int64_t t = 0;
  for (; t < 500 * kMs; t += 2 * kMs) {
    ap_.on_imu(level_imu(t), truth, out_);
    if (t % (34 * kMs) == 0) {
      ap_.on_message(t, 1, 191, body_odometry(t, Eigen::Vector3d::Zero(), 0.01), truth, out_);
    }
  }
  // A 2 m/s jump under the same counter: beyond the 3-sigma gate, not fused.
  ap_.on_message(t, 1, 191, body_odometry(t, Eigen::Vector3d(2.0, 0, 0), 0.01), truth, out_);
  EXPECT_EQ(ap_.stats().rejected_gate, 1u);
  EXPECT_EQ(ap_.stats().odometry_resets, 0u);
  // The same jump announced by a new reset_counter: the estimate restarts on it.
  ap_.on_message(t, 1, 191, body_odometry(t, Eigen::Vector3d(2.0, 0, 0), 0.01, 1), truth, out_);
  EXPECT_EQ(ap_.stats().odometry_resets, 1u);
  EXPECT_EQ(ap_.stats().rejected_gate, 1u);
  ap_.on_imu(level_imu(t + 2 * kMs), truth, out_);
  const double mean_error_before = ap_.stats().fused_sq_error_sum;
  ap_.on_imu(level_imu(t + 4 * kMs), truth, out_);
  EXPECT_NEAR(ap_.stats().fused_sq_error_sum - mean_error_before, 4.0, 0.05)
      << "the fused velocity is now 2 m/s north, the truth at rest";
}

TEST_F(SitlAutopilotTest, LandDescendsOnTheFusedVerticalVelocityNotTheTruth) {
  TruthState flying = airborne(2.0);
  arm_offboard(flying);
  std::int64_t t = 4 * kMs;
  // The vision says 0.5 m/s down while the truth hovers: LAND believes it is descending.
  for (; t < 700 * kMs; t += 2 * kMs) {
    ap_.on_imu(level_imu(t), flying, out_);
    if (t % (34 * kMs) == 0) {
      ap_.on_message(t, 1, 191, body_odometry(t, Eigen::Vector3d(0, 0, 0.5), 0.01), flying, out_);
    }
    ap_.update(t, flying, out_);
  }
  ASSERT_EQ(ap_.mode(), SitlMode::kLand);
  const hq::sim::AttitudeCommand c = ap_.update(t, flying, out_);
  EXPECT_NEAR(c.thrust_n, params_.mass_kg * 9.81, 0.02 * params_.mass_kg * 9.81)
      << "hover thrust: the fused estimate already descends at the landing speed";
  EXPECT_GT(ap_.stats().descent_on_vision_ns, 0);
  EXPECT_EQ(ap_.stats().descent_on_baro_ns, 0);
}

TEST_F(SitlAutopilotTest, TimesyncRequestsAreAnsweredWithTheSimulatedClock) {
  TruthState ground;
  ap_.on_message(7'000 * kMs, 1, 191, mav::Timesync{0, 123456789, 1, 1}, ground, out_);
  ASSERT_EQ(out_.all<mav::Timesync>().size(), 1u);
  const mav::Timesync answer = out_.all<mav::Timesync>()[0];
  EXPECT_EQ(answer.tc1_ns, 7'000 * kMs);
  EXPECT_EQ(answer.ts1_ns, 123456789);
  EXPECT_EQ(answer.target_system, 1);
  EXPECT_EQ(answer.target_component, 191);
  // An old-protocol request (no targets) is answered too; an answer (tc1 != 0) is not.
  ap_.on_message(7'001 * kMs, 1, 191, mav::Timesync{0, 5, 0, 0}, ground, out_);
  ap_.on_message(7'002 * kMs, 1, 191, mav::Timesync{99, 5, 1, 1}, ground, out_);
  EXPECT_EQ(out_.all<mav::Timesync>().size(), 2u);
  EXPECT_EQ(ap_.stats().timesync_answered, 2u);
}

std::array<char, 16> param_id(const char* name) {
  std::array<char, 16> id{};
  std::memcpy(id.data(), name, std::min<std::size_t>(std::strlen(name), id.size()));
  return id;
}

std::string name_of(const mav::ParamValue& v) {
  return {v.param_id.data(), strnlen(v.param_id.data(), v.param_id.size())};
}

TEST_F(SitlAutopilotTest, ParameterListGivesEveryParameterWithCountAndIndex) {
  TruthState ground;
  ap_.on_message(0, 255, 190, mav::ParamRequestList{1, 0}, ground, out_);
  const auto values = out_.all<mav::ParamValue>();
  ASSERT_EQ(values.size(), static_cast<std::size_t>(hq::sitl::kSitlParamCount));
  for (std::size_t i = 0; i < values.size(); ++i) {
    EXPECT_EQ(values[i].param_count, hq::sitl::kSitlParamCount);
    EXPECT_EQ(values[i].param_index, i);
    EXPECT_EQ(values[i].param_type, mav::kMavParamTypeReal32);
  }
  EXPECT_EQ(name_of(values[2]), "COM_OF_LOSS_T");
  EXPECT_FLOAT_EQ(values[2].param_value, 0.5f) << "SitlAutopilotConfig::offboard_loss_ns";
  EXPECT_EQ(name_of(values[3]), "MPC_LAND_SPEED");
  EXPECT_FLOAT_EQ(values[3].param_value, 0.5f);
  // For another system or component: not ours to answer.
  ap_.on_message(0, 255, 190, mav::ParamRequestList{2, 0}, ground, out_);
  ap_.on_message(0, 255, 190, mav::ParamRequestList{1, 191}, ground, out_);
  EXPECT_EQ(out_.all<mav::ParamValue>().size(), values.size());
}

TEST_F(SitlAutopilotTest, ParameterReadByNameOrIndex) {
  TruthState ground;
  ap_.on_message(0, 255, 190, mav::ParamRequestRead{-1, 1, 1, param_id("COM_OBC_LOSS_T")}, ground,
                 out_);
  ap_.on_message(0, 255, 190, mav::ParamRequestRead{0, 1, 1, {}}, ground, out_);
  ap_.on_message(0, 255, 190, mav::ParamRequestRead{-1, 1, 1, param_id("NO_SUCH_PARAM")}, ground,
                 out_);
  ap_.on_message(0, 255, 190, mav::ParamRequestRead{99, 1, 1, {}}, ground, out_);
  const auto values = out_.all<mav::ParamValue>();
  ASSERT_EQ(values.size(), 2u);
  EXPECT_EQ(name_of(values[0]), "COM_OBC_LOSS_T");
  EXPECT_FLOAT_EQ(values[0].param_value, 2.0f);
  EXPECT_EQ(name_of(values[1]), "COM_DISARM_LAND");
  EXPECT_EQ(ap_.stats().params_rejected, 2u);
}

TEST_F(SitlAutopilotTest, ParameterSetIsEchoedAndChangesTheFailsafe) {
  TruthState flying = airborne(2.0);
  ap_.on_message(0, 255, 190,
                 mav::ParamSet{2.0f, 1, 1, param_id("COM_OF_LOSS_T"), mav::kMavParamTypeReal32},
                 flying, out_);
  ASSERT_EQ(out_.all<mav::ParamValue>().size(), 1u);
  EXPECT_FLOAT_EQ(out_.all<mav::ParamValue>()[0].param_value, 2.0f);
  // Out of range: refused, and the echo says the old value.
  ap_.on_message(0, 255, 190,
                 mav::ParamSet{-1.0f, 1, 1, param_id("COM_OF_LOSS_T"), mav::kMavParamTypeReal32},
                 flying, out_);
  EXPECT_FLOAT_EQ(out_.all<mav::ParamValue>().back().param_value, 2.0f);
  EXPECT_THAT(out_.texts(), HasSubstr("param set refused"));
  EXPECT_EQ(ap_.stats().params_set, 1u);
  // The new COM_OF_LOSS_T is the one flown: 1 s without setpoints is no longer a loss.
  arm_offboard(flying);
  ap_.update(1000 * kMs, flying, out_);
  EXPECT_EQ(ap_.mode(), SitlMode::kOffboard);
  ap_.update(2100 * kMs, flying, out_);
  EXPECT_EQ(ap_.mode(), SitlMode::kLand);
}

TEST_F(SitlAutopilotTest, AGcsIsAnsweredAtOnceAndItsModeChangeObeyed) {
  TruthState flying = airborne(2.0);
  arm_offboard(flying);
  const std::size_t heartbeats = out_.all<mav::Heartbeat>().size();
  mav::Heartbeat gcs;
  gcs.type = mav::kMavTypeGcs;
  gcs.autopilot = mav::kMavAutopilotInvalid;
  ap_.on_message(5 * kMs, 255, 190, gcs, flying, out_);
  EXPECT_EQ(out_.all<mav::Heartbeat>().size(), heartbeats + 1) << "its first heartbeat answered";
  ap_.on_message(6 * kMs, 255, 190, gcs, flying, out_);
  EXPECT_EQ(out_.all<mav::Heartbeat>().size(), heartbeats + 1) << "later ones: the 1 Hz stream";
  EXPECT_EQ(ap_.stats().gcs_heartbeats, 2u);
  // The pilot at the GCS takes over (POSCTL): obeyed, acked to the GCS, in the next heartbeat.
  ap_.on_message(7 * kMs, 255, 190, command(mav::kMavCmdDoSetMode, 1, 3), flying, out_);
  EXPECT_EQ(ap_.mode(), SitlMode::kPosctl);
  EXPECT_EQ(out_.all<mav::CommandAck>().back().target_system, 255);
  EXPECT_EQ(out_.all<mav::Heartbeat>().back().custom_mode, 3u << 16);
}

}  // namespace
