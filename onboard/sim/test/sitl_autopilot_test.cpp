// SitlAutopilot, the PX4-like flight controller of hq-sim --sitl: arming and offboard rules,
// setpoint conversion, the offboard failsafes into LAND and the disarm on the ground, the
// messages it streams and the vision-speed error in NED.
#include "hq/sim/sitl_autopilot.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

namespace {

namespace mav = hq::mavlink;
using hq::sim::SitlAutopilot;
using hq::sim::SitlMode;
using hq::sim::TruthState;
using ::testing::HasSubstr;

constexpr std::int64_t kMs = 1'000'000;

class Capture final : public hq::sim::MessageSink {
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
  t.T_world_body.translation().z() = altitude_m;
  t.v_world_mps.z() = v_up_mps;
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
  EXPECT_NEAR(ap_.update(510 * kMs, airborne(1.5, -0.5), out_).thrust_n, params_.mass_kg * 9.81,
              1e-9)
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
  s.f_body_mps2 = Eigen::Vector3d(0.1, 0.2, -9.81);
  s.omega_body_radps = Eigen::Vector3d(0.01, 0.02, 0.03);
  ap_.send_imu(s, out_);
  const mav::HighresImu m = out_.all<mav::HighresImu>().at(0);
  EXPECT_EQ(m.time_usec, 1'234'000u);
  EXPECT_FLOAT_EQ(m.zacc_mps2, -9.81f);
  EXPECT_FLOAT_EQ(m.ygyro_radps, 0.02f);
  EXPECT_EQ(m.fields_updated, 0x3F);
}

TEST_F(SitlAutopilotTest, VisionSpeedErrorIsTakenAgainstTruthInNed) {
  TruthState truth = airborne(1.0);
  truth.v_world_mps = Eigen::Vector3d(1.0, 2.0, 3.0);  // NWU: north 1, west 2, up 3
  mav::VisionSpeedEstimate v;
  v.x_mps = 1.0f;
  v.y_mps = -2.0f;
  v.z_mps = -3.0f;
  ap_.on_message(0, 1, 191, v, truth, out_);
  EXPECT_NEAR(ap_.stats().vision_sq_error_sum, 0.0, 1e-12);
  v.y_mps = 2.0f;
  v.z_mps = 3.0f;
  ap_.on_message(0, 1, 191, v, truth, out_);
  EXPECT_NEAR(ap_.stats().vision_sq_error_sum, 16.0 + 36.0, 1e-9);
  EXPECT_EQ(ap_.stats().vision_estimates, 2u);
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
  ASSERT_EQ(values.size(), static_cast<std::size_t>(hq::sim::kSitlParamCount));
  for (std::size_t i = 0; i < values.size(); ++i) {
    EXPECT_EQ(values[i].param_count, hq::sim::kSitlParamCount);
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
