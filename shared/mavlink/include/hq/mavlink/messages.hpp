#pragma once
/// The MAVLink v2 messages HaptiQuad exchanges with a flight controller (common.xml), as plain
/// structs. Field names are the specification's, with the unit appended where the spec gives
/// one, so a reader can hold this file beside https://mavlink.io/en/messages/common.html.
/// Extension fields are included: a v2 frame carries them (zero-trimmed), a v1 frame does not.

#include <array>
#include <cstddef>
#include <cstdint>
#include <variant>

namespace hq::mavlink {

/// HEARTBEAT (0).
struct Heartbeat {
  static constexpr std::uint32_t kId = 0;
  std::uint32_t custom_mode = 0;
  std::uint8_t type = 0;       ///< MAV_TYPE.
  std::uint8_t autopilot = 0;  ///< MAV_AUTOPILOT.
  std::uint8_t base_mode = 0;  ///< MAV_MODE_FLAG bits.
  std::uint8_t system_status = 0;
  std::uint8_t mavlink_version = 3;
  bool operator==(const Heartbeat&) const = default;  ///< Field by field (tests, tools).
};

/// SYS_STATUS (1): the battery part is what the operator needs.
struct SysStatus {
  static constexpr std::uint32_t kId = 1;
  std::uint32_t onboard_control_sensors_present = 0;
  std::uint32_t onboard_control_sensors_enabled = 0;
  std::uint32_t onboard_control_sensors_health = 0;
  std::uint16_t load_permille = 0;
  std::uint16_t voltage_battery_mv = 0;    ///< UINT16_MAX: unknown.
  std::int16_t current_battery_ca = -1;    ///< centiampere; -1: unknown.
  std::int8_t battery_remaining_pct = -1;  ///< -1: unknown.
  std::uint16_t drop_rate_comm_cpct = 0;
  std::uint16_t errors_comm = 0;
  std::array<std::uint16_t, 4> errors_count{};
  // Extensions.
  std::uint32_t onboard_control_sensors_present_extended = 0;
  std::uint32_t onboard_control_sensors_enabled_extended = 0;
  std::uint32_t onboard_control_sensors_health_extended = 0;
  bool operator==(const SysStatus&) const = default;  ///< Field by field (tests, tools).
};

/// ATTITUDE (30): Euler angles of the body FRD in the local NED frame.
struct Attitude {
  static constexpr std::uint32_t kId = 30;
  std::uint32_t time_boot_ms = 0;
  float roll_rad = 0, pitch_rad = 0, yaw_rad = 0;
  float rollspeed_radps = 0, pitchspeed_radps = 0, yawspeed_radps = 0;
  bool operator==(const Attitude&) const = default;  ///< Field by field (tests, tools).
};

/// COMMAND_LONG (76).
struct CommandLong {
  static constexpr std::uint32_t kId = 76;
  std::array<float, 7> param{};  ///< param1..param7.
  std::uint16_t command = 0;     ///< MAV_CMD.
  std::uint8_t target_system = 0;
  std::uint8_t target_component = 0;
  std::uint8_t confirmation = 0;
  bool operator==(const CommandLong&) const = default;  ///< Field by field (tests, tools).
};

/// COMMAND_ACK (77).
struct CommandAck {
  static constexpr std::uint32_t kId = 77;
  std::uint16_t command = 0;
  std::uint8_t result = 0;  ///< MAV_RESULT.
  // Extensions.
  std::uint8_t progress = 0;
  std::int32_t result_param2 = 0;
  std::uint8_t target_system = 0;
  std::uint8_t target_component = 0;
  bool operator==(const CommandAck&) const = default;  ///< Field by field (tests, tools).
};

/// SET_ATTITUDE_TARGET (82).
struct SetAttitudeTarget {
  static constexpr std::uint32_t kId = 82;
  std::uint32_t time_boot_ms = 0;
  std::array<float, 4> q{1, 0, 0, 0};  ///< w, x, y, z: body FRD in local NED.
  float body_roll_rate_radps = 0, body_pitch_rate_radps = 0, body_yaw_rate_radps = 0;
  float thrust = 0;  ///< Collective thrust, normalised 0..1.
  std::uint8_t target_system = 0;
  std::uint8_t target_component = 0;
  std::uint8_t type_mask = 0;  ///< ATTITUDE_TARGET_TYPEMASK bits: what to ignore.
  // Extensions.
  std::array<float, 3> thrust_body{};
  bool operator==(const SetAttitudeTarget&) const = default;  ///< Field by field (tests, tools).
};

/// VISION_SPEED_ESTIMATE (103): velocity in the local NED frame.
struct VisionSpeedEstimate {
  static constexpr std::uint32_t kId = 103;
  std::uint64_t usec = 0;
  float x_mps = 0, y_mps = 0, z_mps = 0;
  // Extensions.
  std::array<float, 9> covariance{};  ///< Row-major 3x3, m^2/s^2; NaN in [0]: unknown.
  std::uint8_t reset_counter = 0;
  bool operator==(const VisionSpeedEstimate&) const = default;  ///< Field by field (tests, tools).
};

/// TIMESYNC (111): a request carries tc1 = 0 and ts1 = the requester's time; the answer carries
/// tc1 = the responder's time and ts1 echoed (https://mavlink.io/en/services/timesync.html).
/// Senders of the older protocol leave the target extension fields zero.
struct Timesync {
  static constexpr std::uint32_t kId = 111;
  std::int64_t tc1_ns = 0;
  std::int64_t ts1_ns = 0;
  // Extensions.
  std::uint8_t target_system = 0;
  std::uint8_t target_component = 0;
  bool operator==(const Timesync&) const = default;  ///< Field by field (tests, tools).
};

/// HIGHRES_IMU (105): body FRD.
struct HighresImu {
  static constexpr std::uint32_t kId = 105;
  std::uint64_t time_usec = 0;
  float xacc_mps2 = 0, yacc_mps2 = 0, zacc_mps2 = 0;
  float xgyro_radps = 0, ygyro_radps = 0, zgyro_radps = 0;
  float xmag_gauss = 0, ymag_gauss = 0, zmag_gauss = 0;
  float abs_pressure_hpa = 0, diff_pressure_hpa = 0, pressure_alt_m = 0, temperature_degc = 0;
  std::uint16_t fields_updated = 0;
  // Extensions.
  std::uint8_t id = 0;
  bool operator==(const HighresImu&) const = default;  ///< Field by field (tests, tools).
};

/// STATUSTEXT (253).
struct Statustext {
  static constexpr std::uint32_t kId = 253;
  std::uint8_t severity = 0;    ///< MAV_SEVERITY.
  std::array<char, 50> text{};  ///< Not NUL-terminated when all 50 are used.
  // Extensions.
  std::uint16_t id = 0;
  std::uint8_t chunk_seq = 0;
  bool operator==(const Statustext&) const = default;  ///< Field by field (tests, tools).
};

/// ODOMETRY (331), REP 147 shaped: pose in frame_id, twist (velocity, rates) in child_frame_id.
/// Covariances are the upper-right triangle of a 6x6 matrix, row-major (21 values: the first
/// six are row 0, the next five row 1, ...); NaN in [0]: unknown. NaN fields: not known.
struct Odometry {
  static constexpr std::uint32_t kId = 331;
  std::uint64_t time_usec = 0;
  float x_m = 0, y_m = 0, z_m = 0;
  std::array<float, 4> q{1, 0, 0, 0};  ///< w, x, y, z: child frame in frame_id.
  float vx_mps = 0, vy_mps = 0, vz_mps = 0;
  float rollspeed_radps = 0, pitchspeed_radps = 0, yawspeed_radps = 0;
  std::array<float, 21> pose_covariance{};      ///< x, y, z, roll, pitch, yaw (m^2, rad^2).
  std::array<float, 21> velocity_covariance{};  ///< vx, vy, vz, rates (m^2/s^2, rad^2/s^2).
  std::uint8_t frame_id = 0;                    ///< MAV_FRAME of the pose.
  std::uint8_t child_frame_id = 0;              ///< MAV_FRAME of the velocity and rates.
  // Extensions.
  std::uint8_t reset_counter = 0;   ///< Bumped when the estimate jumps (re-initialisation).
  std::uint8_t estimator_type = 0;  ///< MAV_ESTIMATOR_TYPE.
  std::int8_t quality_pct = 0;      ///< -1 failed, 0 unknown, 1 worst .. 100 best.
  bool operator==(const Odometry&) const = default;  ///< Field by field (NaN never equal).
};

// The parameter protocol (mavlink.io "Parameter Protocol"), which a GCS runs with the FC
// through the companion and hq-sim --sitl answers.

/// PARAM_REQUEST_READ (20): by param_index, or by param_id when the index is -1.
struct ParamRequestRead {
  static constexpr std::uint32_t kId = 20;
  std::int16_t param_index = -1;
  std::uint8_t target_system = 0;
  std::uint8_t target_component = 0;
  std::array<char, 16> param_id{};  ///< Not NUL-terminated when all 16 are used.
  bool operator==(const ParamRequestRead&) const = default;  ///< Field by field (tests, tools).
};

/// PARAM_REQUEST_LIST (21).
struct ParamRequestList {
  static constexpr std::uint32_t kId = 21;
  std::uint8_t target_system = 0;
  std::uint8_t target_component = 0;
  bool operator==(const ParamRequestList&) const = default;  ///< Field by field (tests, tools).
};

/// PARAM_VALUE (22).
struct ParamValue {
  static constexpr std::uint32_t kId = 22;
  float param_value = 0;
  std::uint16_t param_count = 0;
  std::uint16_t param_index = 0;
  std::array<char, 16> param_id{};
  std::uint8_t param_type = 0;                         ///< MAV_PARAM_TYPE.
  bool operator==(const ParamValue&) const = default;  ///< Field by field (tests, tools).
};

/// PARAM_SET (23).
struct ParamSet {
  static constexpr std::uint32_t kId = 23;
  float param_value = 0;
  std::uint8_t target_system = 0;
  std::uint8_t target_component = 0;
  std::array<char, 16> param_id{};
  std::uint8_t param_type = 0;                       ///< MAV_PARAM_TYPE.
  bool operator==(const ParamSet&) const = default;  ///< Field by field (tests, tools).
};

using Message =
    std::variant<Heartbeat, SysStatus, Attitude, CommandLong, CommandAck, SetAttitudeTarget,
                 VisionSpeedEstimate, HighresImu, Statustext, Timesync, Odometry, ParamRequestRead,
                 ParamRequestList, ParamValue, ParamSet>;

// The enum values HaptiQuad uses (common.xml, minimal.xml; PX4 custom modes from px4_custom_mode.h
// as documented on docs.px4.io; ArduCopter modes from its documentation).
inline constexpr std::uint8_t kMavTypeQuadrotor = 2;
inline constexpr std::uint8_t kMavTypeOnboardController = 18;
inline constexpr std::uint8_t kMavAutopilotGeneric = 0;
inline constexpr std::uint8_t kMavAutopilotArdupilotMega = 3;
inline constexpr std::uint8_t kMavAutopilotInvalid = 8;
inline constexpr std::uint8_t kMavAutopilotPx4 = 12;
inline constexpr std::uint8_t kMavModeFlagCustomModeEnabled = 1;
inline constexpr std::uint8_t kMavModeFlagSafetyArmed = 128;
inline constexpr std::uint8_t kMavStateStandby = 3;
inline constexpr std::uint8_t kMavStateActive = 4;
inline constexpr std::uint8_t kMavStateCritical = 5;
inline constexpr std::uint16_t kMavCmdDoSetMode = 176;
inline constexpr std::uint16_t kMavCmdComponentArmDisarm = 400;
inline constexpr std::uint16_t kMavCmdSetMessageInterval = 511;
inline constexpr std::uint8_t kMavResultAccepted = 0;
inline constexpr std::uint8_t kMavCompIdAutopilot1 = 1;
inline constexpr std::uint8_t kMavTypeGcs = 6;
inline constexpr std::uint8_t kMavParamTypeReal32 = 9;
inline constexpr std::uint8_t kMavCompIdOnboardComputer = 191;
inline constexpr std::uint8_t kMavFrameLocalNed = 1;
inline constexpr std::uint8_t kMavFrameBodyFrd = 12;
inline constexpr std::uint8_t kMavFrameLocalFrd = 20;
inline constexpr std::uint8_t kMavEstimatorTypeVio = 3;
/// Index of row r, column c (r <= c) of a 6x6 covariance's upper-right triangle in ODOMETRY.
constexpr std::size_t upper_triangle_index(std::size_t r, std::size_t c) {
  return r * 6 - r * (r - 1) / 2 + (c - r);
}
inline constexpr std::uint8_t kAttitudeTargetIgnoreBodyRollRate = 1;
inline constexpr std::uint8_t kAttitudeTargetIgnoreBodyPitchRate = 2;
inline constexpr std::uint8_t kAttitudeTargetIgnoreBodyYawRate = 4;
inline constexpr std::uint8_t kAttitudeTargetIgnoreThrust = 64;
inline constexpr std::uint8_t kAttitudeTargetIgnoreAttitude = 128;
/// PX4: custom_mode = main_mode << 16 | sub_mode << 24; OFFBOARD is main mode 6.
inline constexpr std::uint32_t kPx4MainModeOffboard = 6;
/// ArduCopter GUIDED_NOGPS.
inline constexpr std::uint32_t kArduCopterModeGuidedNoGps = 20;

}  // namespace hq::mavlink
