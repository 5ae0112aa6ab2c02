#include "hq/link/messages.hpp"

#include <cmath>

namespace hq::link {

namespace {

constexpr Validation kOk{};
/// The last VehicleState.position_invalid_reason (hq::navigation PositionInvalid).
constexpr std::uint8_t kMaxPositionInvalidReason = 4;

// The link carries float, the envelope is double: compare in double so a limit is never rounded.
bool exceeds(float value, double limit) { return static_cast<double>(std::abs(value)) > limit; }

bool finite(const hq_msgs_Vector3f& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Enums arrive as whatever integer the sender wrote; compare as integers so that an
// out-of-range value is never used as an enumerator.
bool valid_mode(hq_msgs_Mode mode) {
  const auto value = static_cast<int>(mode);
  return value >= static_cast<int>(hq_msgs_MODE_TELEOP) &&
         value <= static_cast<int>(hq_msgs_MODE_EXPLORE);
}

bool valid_health(hq_msgs_Health health) {
  const auto value = static_cast<int>(health);
  return value >= static_cast<int>(hq_msgs_HEALTH_OK) &&
         value <= static_cast<int>(hq_msgs_HEALTH_LOST);
}

template <typename Enum>
bool in_enum(Enum value, Enum first, Enum last) {
  const auto v = static_cast<int>(value);
  return v >= static_cast<int>(first) && v <= static_cast<int>(last);
}

}  // namespace

Validation validate(const VelocityCommand& command, const CommandEnvelope& envelope) {
  if (!std::isfinite(command.v_H_mps.x)) return {false, "v_H_mps.x is NaN or Inf"};
  if (!std::isfinite(command.v_H_mps.y)) return {false, "v_H_mps.y is NaN or Inf"};
  if (!std::isfinite(command.v_H_mps.z)) return {false, "v_H_mps.z is NaN or Inf"};
  if (!std::isfinite(command.yaw_rate_radps)) return {false, "yaw_rate_radps is NaN or Inf"};
  if (exceeds(command.v_H_mps.x, envelope.max_v_x_mps)) {
    return {false, "v_H_mps.x outside envelope max_v_x_mps"};
  }
  if (exceeds(command.v_H_mps.y, envelope.max_v_y_mps)) {
    return {false, "v_H_mps.y outside envelope max_v_y_mps"};
  }
  if (exceeds(command.v_H_mps.z, envelope.max_v_z_mps)) {
    return {false, "v_H_mps.z outside envelope max_v_z_mps"};
  }
  if (exceeds(command.yaw_rate_radps, envelope.max_yaw_rate_radps)) {
    return {false, "yaw_rate_radps outside envelope max_yaw_rate_radps"};
  }
  return kOk;
}

Validation validate(const ModeRequest& request) {
  if (!valid_mode(request.requested_mode)) return {false, "requested_mode outside Mode enum"};
  const auto task = static_cast<int>(request.marker_task);
  if (task < static_cast<int>(hq_msgs_MARKER_TASK_NONE) ||
      task > static_cast<int>(hq_msgs_MARKER_TASK_LAND)) {
    return {false, "marker_task outside MarkerTask enum"};
  }
  if (request.target_id < 0) return {false, "target_id is negative"};
  return kOk;
}

Validation validate(const Heartbeat& heartbeat) {
  const auto role = static_cast<int>(heartbeat.role);
  if (role != static_cast<int>(hq_msgs_ROLE_GROUND) &&
      role != static_cast<int>(hq_msgs_ROLE_VEHICLE)) {
    return {false, "role outside Role enum"};
  }
  return kOk;
}

Validation validate(const VehicleState& state) {
  if (!finite(state.v_H_mps)) return {false, "v_H_mps is NaN or Inf"};
  if (!finite(state.omega_B_radps)) return {false, "omega_B_radps is NaN or Inf"};
  if (!finite(state.v_obs_H_mps)) return {false, "v_obs_H_mps is NaN or Inf"};
  if (!std::isfinite(state.roll_rad) || !std::isfinite(state.pitch_rad)) {
    return {false, "roll_rad or pitch_rad is NaN or Inf"};
  }
  if (!valid_mode(state.mode)) return {false, "mode outside Mode enum"};
  if (!valid_health(state.estimator_health)) return {false, "estimator_health outside Health enum"};
  if (!valid_health(state.link_health)) return {false, "link_health outside Health enum"};
  if (state.obstacle_points_B_m._length > hq_msgs_kMaxObstaclePoints) {
    return {false, "obstacle_points_B_m longer than kMaxObstaclePoints"};
  }
  for (std::uint32_t i = 0; i < state.obstacle_points_B_m._length; ++i) {
    if (!finite(state.obstacle_points_B_m._buffer[i])) {
      return {false, "obstacle_points_B_m has a NaN or Inf point"};
    }
  }
  // Absent estimates travel as zeros, so these are finite whatever the flags say.
  if (!finite(state.p_W_m) || !std::isfinite(state.yaw_W_rad)) {
    return {false, "p_W_m or yaw_W_rad is NaN or Inf"};
  }
  if (!finite(state.v_truth_H_mps)) return {false, "v_truth_H_mps is NaN or Inf"};
  if (!in_enum(state.flight_state, hq_msgs_FLIGHT_LANDED, hq_msgs_FLIGHT_LANDING)) {
    return {false, "flight_state outside FlightState enum"};
  }
  if (!in_enum(state.height_source, hq_msgs_HEIGHT_NONE, hq_msgs_HEIGHT_ESTIMATE)) {
    return {false, "height_source outside HeightSource enum"};
  }
  if (!in_enum(state.operator_input, hq_msgs_INPUT_FLOWN, hq_msgs_INPUT_LIMITED_ENVELOPE)) {
    return {false, "operator_input outside OperatorInput enum"};
  }
  if (!std::isfinite(state.height_m) || !std::isfinite(state.clearance_m)) {
    return {false, "height_m or clearance_m is NaN or Inf"};
  }
  if (!finite(state.v_cmd_flown_H_mps)) return {false, "v_cmd_flown_H_mps is NaN or Inf"};
  // 0: a sender that reports none (the field's default).
  if (!(state.hover_thrust_gain >= 0.0F && state.hover_thrust_gain <= 10.0F)) {
    return {false, "hover_thrust_gain not in [0, 10]"};
  }
  if (state.position_invalid_reason > kMaxPositionInvalidReason) {
    return {false, "position_invalid_reason outside 0..4"};
  }
  if (state.position_valid && state.position_invalid_reason != 0) {
    return {false, "position_valid with a position_invalid_reason"};
  }
  if (!(state.position_age_s >= 0.0F && state.position_age_s <= 1e6F) ||
      !(state.position_sigma_m >= 0.0F && state.position_sigma_m <= 1e6F)) {
    return {false, "position_age_s or position_sigma_m not in [0, 1e6]"};
  }
  if (state.marker_target_valid && state.marker_target_id < 0) {
    return {false, "marker_target_id negative"};
  }
  if (state.explore_phase > 7) return {false, "explore_phase not in [0, 7]"};
  if ((state.modes_offered & ~kModesOfferedMask) != 0) {
    return {false, "modes_offered has a bit beyond MODE_EXPLORE"};
  }
  if (state.marker_mode_off_reason > kMaxModeOffReason ||
      state.explore_mode_off_reason > kMaxModeOffReason) {
    return {false, "marker_mode_off_reason or explore_mode_off_reason outside 0..1"};
  }
  if (((state.modes_offered & mode_bit(hq_msgs_MODE_MARKER)) != 0 &&
       state.marker_mode_off_reason != kModeOffNone) ||
      ((state.modes_offered & mode_bit(hq_msgs_MODE_EXPLORE)) != 0 &&
       state.explore_mode_off_reason != kModeOffNone)) {
    return {false, "a mode both offered and off (modes_offered with an off reason)"};
  }
  // The odom pose travels as zeros when absent: finite, its sigmas non-negative.
  if (!finite(state.p_odom_m) || !std::isfinite(state.yaw_odom_rad)) {
    return {false, "p_odom_m or yaw_odom_rad is NaN or Inf"};
  }
  if (!(state.odom_position_sigma_m >= 0.0F && state.odom_position_sigma_m <= 1e6F) ||
      !(state.odom_yaw_sigma_rad >= 0.0F && state.odom_yaw_sigma_rad <= 1e6F)) {
    return {false, "odom_position_sigma_m or odom_yaw_sigma_rad not in [0, 1e6]"};
  }
  if (!finite(state.v_H_sigma_mps) || state.v_H_sigma_mps.x < 0.0F ||
      state.v_H_sigma_mps.y < 0.0F || state.v_H_sigma_mps.z < 0.0F) {
    return {false, "v_H_sigma_mps negative, NaN or Inf"};
  }
  if (state.markers._length > hq_msgs_kMaxMarkersInState) {
    return {false, "markers longer than kMaxMarkersInState"};
  }
  for (std::uint32_t i = 0; i < state.markers._length; ++i) {
    const hq_msgs_MarkerInCamera& m = state.markers._buffer[i];
    if (m.id < 0) return {false, "markers has a negative id"};
    const hq_msgs_Quaternionf& q = m.q_camera_marker;
    if (!finite(m.p_camera_marker_m) || !std::isfinite(q.w) || !std::isfinite(q.x) ||
        !std::isfinite(q.y) || !std::isfinite(q.z)) {
      return {false, "markers has a NaN or Inf pose"};
    }
    // A detected marker is in front of the camera, and its rotation a unit quaternion.
    if (!(m.p_camera_marker_m.z > 0.0F)) return {false, "markers has a pose behind the camera"};
    const float norm2 = q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z;
    if (std::abs(norm2 - 1.0F) > 1e-3F) return {false, "markers has a non-unit quaternion"};
  }
  return kOk;
}

}  // namespace hq::link
