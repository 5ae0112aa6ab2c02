#pragma once
/// Reading back a flight recorded by hq-ground --record and replaying it into a ConsoleModel.
/// Two sources, one Recording: the flight record DIR/flight.mcap (ground/mcap_recorder; the
/// link's samples as received, decoded with the IDL's generated descriptors, see
/// flight_mcap.hpp) or, for recordings from before it, the CSV files beside it
/// (hq::ground::TelemetryRecorder's layout). A damaged recording is read as far as it goes:
/// every unreadable line or message is skipped and named ("telemetry.csv:17: ...",
/// "flight.mcap: /hq/vehicle_state message 17: ..."), so replay and hq-report show what
/// survives and say what did not.

#include "hq/console/console_model.hpp"

#include <array>
#include <atomic>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

namespace hq::console {

struct RecordedState {
  std::int64_t receipt_ns = 0;  ///< Ground clock.
  double latency_ms = 0;
  std::uint64_t sequence = 0;
  std::int64_t vehicle_t_ns = 0;
  std::array<float, 3> v_H_mps{};
  std::array<float, 3> omega_B_radps{};
  float roll_rad = 0;
  float pitch_rad = 0;
  std::array<float, 3> v_obs_H_mps{};
  const char* mode = "invalid";  ///< Static text (see intern()).
  const char* estimator_health = "invalid";
  const char* link_health = "invalid";
  double closest_obstacle_m = 0;  ///< NaN when unknown (or older recordings).
  /// Marker filter pose in the map frame W (NED); false when absent or not anchored.
  bool position_valid = false;
  std::array<float, 3> p_W_m{};
  float yaw_W_rad = 0;
  /// Why the position is invalid (VehicleState.position_invalid_reason; 0: valid or not said,
  /// as in older recordings), seconds since the last marker, horizontal 1-sigma (m).
  std::uint8_t position_invalid_reason = 0;
  float position_age_s = 0;
  float position_sigma_m = 0;
  /// Simulator truth of the velocity in H; false on a real vehicle or older recordings.
  bool truth_valid = false;
  std::array<float, 3> v_truth_H_mps{};
  int markers_n = -1;  ///< Markers detected in the state's frame; -1 when not recorded.
  /// The vehicle's flight fields (later layouts). False when the columns are absent or the
  /// vehicle left them unfilled (session_id 0: a vehicle from before sessions); then every
  /// field below is unknown ("unknown", -1, NaN).
  bool flight_fields = false;
  std::uint64_t session_id = 0;
  std::uint32_t commanding_station_id = 0;
  const char* flight_state = "unknown";  ///< "landed", "taking_off", "airborne", "landing".
  int motors_armed = -1;
  const char* height_source = "unknown";                       ///< "none", "depth", "estimate".
  double height_m = std::numeric_limits<double>::quiet_NaN();  ///< NaN: unknown or source none.
  const char* operator_input = "unknown";  ///< "flown", "ignored_mode", ... (the IDL's names).
  std::array<float, 3> v_cmd_flown_H_mps{};
  /// The vehicle's closest obstacle clearance; NaN when unknown or none seen.
  double clearance_m = std::numeric_limits<double>::quiet_NaN();
  /// The learnt thrust gain (0: not reported or not recorded) and whether it converged.
  float hover_thrust_gain = 0;
  bool hover_thrust_converged = false;
  /// The marker the marker or explore mode flies to (< 0: none) and the explore phase (0: not
  /// exploring, else ExplorePhase + 1), as the state carried them.
  int marker_target_id = -1;
  int explore_phase = 0;
  /// The modes the vehicle offered (VehicleState.modes_offered: bit per hq_msgs_Mode; 0: not
  /// said or not recorded) and why marker and explore were off (link::ModeOffReason; 0: not).
  int modes_offered = 0;
  int marker_mode_off_reason = 0;
  int explore_mode_off_reason = 0;
  /// What the ground measured of the link when the state arrived: the state's one-way age
  /// through the clock offset and the latest heartbeat round trip (ms; 0: unknown then, or not
  /// recorded). CSV: columns of the state's row; MCAP: the ground's /ground/link channel.
  float state_age_ms = 0;
  float round_trip_ms = 0;
  /// The odometry's integrated pose, odom -> base_link (VehicleState.p_odom_m, NED-like odom
  /// frame of the start), its horizontal and yaw 1-sigma, whether the yaw is relative to the
  /// start, and the velocity's 1-sigma per axis; odom_valid false when absent (older records).
  bool odom_valid = false;
  std::array<float, 3> p_odom_m{};
  float yaw_odom_rad = 0;
  float odom_position_sigma_m = 0;
  float odom_yaw_sigma_rad = 0;
  bool odom_yaw_relative_to_start = false;
  std::array<float, 3> v_H_sigma_mps{};
  /// The obstacle cloud the state carried, body frame FRD (x, y, z in m); empty when it
  /// carried none (the cloud rides on about one state a second) or the record lacks it.
  std::vector<std::array<float, 3>> obstacle_points_B_m;
  /// The markers detected in the state's frame with their poses; empty when none or when the
  /// record holds only their count (markers_n).
  std::vector<MarkerView> markers;
};

struct RecordedCommand {
  std::int64_t t_ns = 0;  ///< Ground clock.
  std::array<float, 3> v_H_mps{};
  float yaw_rate_radps = 0;
  bool valid = false;
};

struct RecordedModeRequest {
  std::int64_t t_ns = 0;
  const char* mode = "invalid";
};

struct RecordedEvent {
  std::int64_t receipt_ns = 0;
  int severity = 0;
  int code = -1;  ///< The vehicle's event code (7: ground heartbeat lost); -1 not recorded.
  std::string text;
};

struct RecordedFrame {
  std::int64_t t_ns = 0;  ///< Receipt on the ground clock.
  std::string path;       ///< Absolute or relative to the working directory (CSV recordings).
  std::vector<std::uint8_t> data;  ///< The image itself (MCAP recordings); empty: read `path`.
};

struct Recording {
  std::string directory;  ///< The folder (CSV) or the .mcap file read.
  bool from_mcap = false;
  std::vector<RecordedState> states;
  std::vector<RecordedCommand> commands;
  std::vector<RecordedModeRequest> mode_requests;
  std::vector<RecordedEvent> events;
  std::vector<RecordedFrame> rgb;
  std::vector<RecordedFrame> depth_preview;
  /// Optional columns the files lack ("telemetry.csv: truth_valid"): older layouts, read
  /// without them (their fields keep the defaults above).
  std::vector<std::string> absent_columns;
  std::vector<std::string> problems;  ///< "file:line: what", first kMaxProblems.
  std::size_t problem_count = 0;      ///< All of them.
  static constexpr std::size_t kMaxProblems = 100;
};

/// The flight record to read for `path`: `path` itself if it is a file, DIR/flight.mcap if the
/// folder holds one, else "" (a CSV recording, or nothing).
std::string find_flight_mcap(const std::string& path);

/// Reads a recording: `path` is a .mcap file or a recording folder; a folder's flight.mcap is
/// preferred, its CSV files are read when it has none, when it cannot be read (named in
/// problems) or holds no vehicle state. From an MCAP: the states, frames and events of the
/// vehicle with the most states (others named in problems; the recorder took every vehicle on
/// the domain, the CSV only the station's), the recording station's commands
/// (/ground/haptics), every mode request; latency is log time minus publish time.
/// @throws hq::InputError if `path` is neither a folder nor an MCAP file, a folder holds
/// neither flight.mcap, telemetry.csv nor rgb.txt (nothing of an hq-ground recording), an MCAP
/// file cannot be read (hq::mcap::McapReader's error), or a CSV file has a stamp out of time
/// order, more than an hour after its file's previous one, or a file starting more than an
/// hour from the others (file:line named). Every other defect is a problem in the result.
Recording load_recording(const std::string& path);

/// The static name among the link's mode and health names equal to `text`, else "invalid".
const char* intern(std::string_view text);

/// Replays `recording` into `model` on its recorded timeline scaled by 1/`speed` (clamped to
/// ReplayPlayer's 0.25x..8x), from the calling thread, until its end or `stop`. JPEGs are read from
/// disk as their time comes (a missing or unreadable one is counted in `frames_missing`). Returns
/// false if stopped.
bool replay(const Recording& recording, ConsoleModel& model, double speed,
            const std::atomic<bool>& stop, std::atomic<std::uint64_t>& frames_missing);

}  // namespace hq::console
