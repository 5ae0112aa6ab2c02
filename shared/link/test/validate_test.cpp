#include "hq/link/messages.hpp"
#include "hq/testing/wire_enum.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace hq::link {
namespace {

using hq::testing::wire_enum;
using ::testing::HasSubstr;

VelocityCommand good_command() {
  VelocityCommand command{};
  command.vehicle_id = 1;
  command.v_H_mps = {1.0F, -1.0F, 0.5F};
  command.yaw_rate_radps = 0.5F;
  return command;
}

TEST(Validate, CommandInsideEnvelopeIsAccepted) {
  const Validation result = validate(good_command(), CommandEnvelope{});
  EXPECT_TRUE(result.ok) << result.reason;
}

TEST(Validate, CommandWithNanOrInfIsRejectedNamingTheField) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  VelocityCommand command = good_command();
  command.v_H_mps.x = nan;
  EXPECT_FALSE(validate(command, CommandEnvelope{}).ok);
  EXPECT_THAT(validate(command, CommandEnvelope{}).reason, HasSubstr("v_H_mps.x is NaN or Inf"));
  command = good_command();
  command.v_H_mps.y = -inf;
  EXPECT_THAT(validate(command, CommandEnvelope{}).reason, HasSubstr("v_H_mps.y"));
  command = good_command();
  command.v_H_mps.z = inf;
  EXPECT_THAT(validate(command, CommandEnvelope{}).reason, HasSubstr("v_H_mps.z"));
  command = good_command();
  command.yaw_rate_radps = nan;
  EXPECT_FALSE(validate(command, CommandEnvelope{}).ok);
  EXPECT_THAT(validate(command, CommandEnvelope{}).reason, HasSubstr("yaw_rate_radps"));
}

TEST(Validate, CommandOutsideEnvelopeIsRejectedPerAxis) {
  CommandEnvelope envelope;
  envelope.max_v_x_mps = 1.5;
  envelope.max_v_y_mps = 1.5;
  envelope.max_v_z_mps = 0.6;
  envelope.max_yaw_rate_radps = 0.6;
  VelocityCommand command = good_command();
  EXPECT_TRUE(validate(command, envelope).ok);
  command.v_H_mps.x = -1.6F;
  EXPECT_THAT(validate(command, envelope).reason, HasSubstr("max_v_x_mps"));
  command = good_command();
  command.v_H_mps.y = 1.6F;
  EXPECT_THAT(validate(command, envelope).reason, HasSubstr("max_v_y_mps"));
  command = good_command();
  command.v_H_mps.z = -0.7F;
  EXPECT_THAT(validate(command, envelope).reason, HasSubstr("max_v_z_mps"));
  command = good_command();
  command.yaw_rate_radps = 0.7F;
  EXPECT_FALSE(validate(command, envelope).ok);
  EXPECT_THAT(validate(command, envelope).reason, HasSubstr("max_yaw_rate_radps"));
}

TEST(Validate, ModeRequestWithOutOfRangeEnumIsRejected) {
  ModeRequest request{};
  request.requested_mode = hq_msgs_MODE_EXPLORE;
  EXPECT_TRUE(validate(request).ok);
  request.requested_mode = wire_enum<hq_msgs_Mode>(5);
  EXPECT_FALSE(validate(request).ok);
  EXPECT_THAT(validate(request).reason, HasSubstr("requested_mode outside Mode enum"));
  request.requested_mode = wire_enum<hq_msgs_Mode>(-1);
  EXPECT_FALSE(validate(request).ok);
}

TEST(Validate, ModeRequestMarkerTaskIsCheckedForEnumAndTargetId) {
  ModeRequest request{};
  request.requested_mode = hq_msgs_MODE_MARKER;
  EXPECT_TRUE(validate(request).ok) << "zeros are a plain mode request";
  request.marker_task = hq_msgs_MARKER_TASK_LAND;
  request.target_id = 7;
  EXPECT_TRUE(validate(request).ok) << validate(request).reason;
  request.marker_task = wire_enum<hq_msgs_MarkerTask>(4);
  EXPECT_FALSE(validate(request).ok);
  EXPECT_THAT(validate(request).reason, HasSubstr("marker_task outside MarkerTask enum"));
  request.marker_task = wire_enum<hq_msgs_MarkerTask>(-1);
  EXPECT_THAT(validate(request).reason, HasSubstr("marker_task outside MarkerTask enum"));
  request.marker_task = hq_msgs_MARKER_TASK_GO_TO;
  request.target_id = -1;
  EXPECT_FALSE(validate(request).ok);
  EXPECT_THAT(validate(request).reason, HasSubstr("target_id is negative"));
}

TEST(Validate, HeartbeatWithOutOfRangeRoleIsRejected) {
  Heartbeat beat{};
  beat.role = hq_msgs_ROLE_VEHICLE;
  EXPECT_TRUE(validate(beat).ok);
  beat.role = wire_enum<hq_msgs_Role>(7);
  EXPECT_THAT(validate(beat).reason, HasSubstr("role outside Role enum"));
}

TEST(Validate, VehicleStateWithNanOrBadEnumIsRejected) {
  VehicleState state{};
  EXPECT_TRUE(validate(state).ok);
  state.omega_B_radps.z = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THAT(validate(state).reason, HasSubstr("omega_B_radps"));
  state = VehicleState{};
  state.link_health = wire_enum<hq_msgs_Health>(3);
  EXPECT_THAT(validate(state).reason, HasSubstr("link_health"));
  state = VehicleState{};
  hq_msgs_Vector3f points[2] = {{0.0F, 0.0F, 0.0F}, {1.0F, std::nanf(""), 0.0F}};
  state.obstacle_points_B_m._buffer = points;
  state.obstacle_points_B_m._length = 2;
  state.obstacle_points_B_m._maximum = 2;
  EXPECT_THAT(validate(state).reason, HasSubstr("obstacle_points_B_m has a NaN"));
  state = VehicleState{};
  state.hover_thrust_gain = 1.4F;
  EXPECT_TRUE(validate(state).ok);
  state.hover_thrust_gain = std::nanf("");
  EXPECT_THAT(validate(state).reason, HasSubstr("hover_thrust_gain not in [0, 10]"));
  state.hover_thrust_gain = -1.0F;
  EXPECT_FALSE(validate(state).ok);
  state = VehicleState{};
  state.position_invalid_reason = 2;  // no marker for too long
  state.position_age_s = 3.5F;
  state.position_sigma_m = 0.2F;
  EXPECT_TRUE(validate(state).ok);
  state.position_invalid_reason = 5;
  EXPECT_THAT(validate(state).reason, HasSubstr("position_invalid_reason outside 0..4"));
  state.position_invalid_reason = 2;
  state.position_valid = true;
  EXPECT_THAT(validate(state).reason, HasSubstr("position_valid with a position_invalid_reason"));
  state.position_valid = false;
  state.position_age_s = std::nanf("");
  EXPECT_THAT(validate(state).reason, HasSubstr("position_age_s or position_sigma_m"));
  state.position_age_s = 1.0F;
  state.position_sigma_m = -0.1F;
  EXPECT_FALSE(validate(state).ok);
  state = VehicleState{};
  state.marker_target_valid = true;
  state.marker_target_id = 12;
  state.explore_phase = 7;
  EXPECT_TRUE(validate(state).ok);
  state.explore_phase = 8;
  EXPECT_THAT(validate(state).reason, HasSubstr("explore_phase not in [0, 7]"));
  state.explore_phase = 0;
  state.marker_target_id = -3;
  EXPECT_THAT(validate(state).reason, HasSubstr("marker_target_id negative"));
}

TEST(Validate, ModesOfferedBitsAndOffReasonsAgree) {
  VehicleState state{};
  const std::uint8_t basic = kModesWithoutMarkerStage;
  state.modes_offered = basic;
  state.marker_mode_off_reason = kModeOffMarkerStageDisabled;
  state.explore_mode_off_reason = kModeOffMarkerStageDisabled;
  EXPECT_TRUE(validate(state).ok);
  state.modes_offered = static_cast<std::uint8_t>(basic | mode_bit(hq_msgs_MODE_EXPLORE));
  EXPECT_THAT(validate(state).reason, HasSubstr("both offered and off"));
  state.modes_offered = kModesOfferedMask;
  state.marker_mode_off_reason = state.explore_mode_off_reason = kModeOffNone;
  EXPECT_TRUE(validate(state).ok);
  state.modes_offered = 0x20;
  EXPECT_THAT(validate(state).reason, HasSubstr("beyond MODE_EXPLORE"));
  state.modes_offered = basic;
  state.marker_mode_off_reason = 2;
  EXPECT_THAT(validate(state).reason, HasSubstr("outside 0..1"));
}

}  // namespace
}  // namespace hq::link
