#include "hq/console/state_feed.hpp"

#include "hq/link/state_figures.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string_view>

namespace hq::console {

namespace {

// The names the CSV recorder writes for the link's enums (ground_station.cpp), as static text.
const char* health_name(hq_msgs_Health v) {
  static constexpr std::array<const char*, 3> kHealth = {"ok", "degraded", "lost"};
  const auto i = static_cast<std::size_t>(v);
  return intern(i < kHealth.size() ? kHealth[i] : "invalid");
}

template <std::size_t N>
const char* name_of(const std::array<const char*, N>& names, int v) {
  return v >= 0 && static_cast<std::size_t>(v) < N ? names[static_cast<std::size_t>(v)] : "unknown";
}

constexpr std::array<const char*, 4> kFlightStates = {"landed", "taking_off", "airborne",
                                                      "landing"};
constexpr std::array<const char*, 3> kHeightSources = {"none", "depth", "estimate"};
constexpr std::array<const char*, 8> kOperatorInputs = {"flown",
                                                        "none",
                                                        "ignored_mode",
                                                        "ignored_landed",
                                                        "ignored_not_owner",
                                                        "ignored_failsafe",
                                                        "limited_unseen",
                                                        "limited_envelope"};

std::array<float, 3> array3(const hq_msgs_Vector3f& v) { return {v.x, v.y, v.z}; }

// The flight fields as load_recording reads them from the CSV: unknown for a vehicle that
// leaves them unfilled (session 0).
void set_flight_fields(const link::VehicleState& s, RecordedState& out) {
  out.session_id = s.session_id;
  out.commanding_station_id = s.commanding_station_id;
  out.flight_fields = s.session_id != 0;
  out.flight_state = "unknown";
  out.motors_armed = -1;
  out.height_source = "unknown";
  out.height_m = std::numeric_limits<double>::quiet_NaN();
  out.operator_input = "unknown";
  out.v_cmd_flown_H_mps = {};
  out.clearance_m = std::numeric_limits<double>::quiet_NaN();
  if (!out.flight_fields) return;
  out.flight_state = name_of(kFlightStates, static_cast<int>(s.flight_state));
  out.motors_armed = s.motors_armed ? 1 : 0;
  out.height_source = name_of(kHeightSources, static_cast<int>(s.height_source));
  out.operator_input = name_of(kOperatorInputs, static_cast<int>(s.operator_input));
  out.v_cmd_flown_H_mps = array3(s.v_cmd_flown_H_mps);
  if (std::string_view(out.height_source) != "none" && std::isfinite(s.height_m)) {
    out.height_m = s.height_m;
  }
  if (std::isfinite(s.clearance_m) && s.clearance_m >= 0) out.clearance_m = s.clearance_m;
}

}  // namespace

void to_recorded(std::int64_t receipt_ns, double latency_ms, const link::VehicleState& s,
                 RecordedState& out, const LinkFigures& figures) {
  out.receipt_ns = receipt_ns;
  out.latency_ms = latency_ms;
  out.state_age_ms = std::isfinite(figures.state_age_ms) ? figures.state_age_ms : 0.0F;
  out.round_trip_ms = std::isfinite(figures.round_trip_ms) ? figures.round_trip_ms : 0.0F;
  out.sequence = s.sequence_number;
  out.vehicle_t_ns = s.t_ns;
  out.v_H_mps = array3(s.v_H_mps);
  out.omega_B_radps = array3(s.omega_B_radps);
  out.roll_rad = s.roll_rad;
  out.pitch_rad = s.pitch_rad;
  out.v_obs_H_mps = array3(s.v_obs_H_mps);
  out.mode = recorded_mode_name(s.mode);
  out.estimator_health = health_name(s.estimator_health);
  out.link_health = health_name(s.link_health);
  out.closest_obstacle_m = link::closest_cloud_point_m(s);
  out.position_valid = s.position_valid;
  out.p_W_m = array3(s.p_W_m);
  out.yaw_W_rad = s.yaw_W_rad;
  out.position_invalid_reason = s.position_invalid_reason;
  out.position_age_s = std::isfinite(s.position_age_s) ? s.position_age_s : 0.0F;
  out.position_sigma_m = std::isfinite(s.position_sigma_m) ? s.position_sigma_m : 0.0F;
  out.truth_valid = s.truth_valid;
  out.v_truth_H_mps = array3(s.v_truth_H_mps);
  out.markers_n = static_cast<int>(s.markers._length);
  set_flight_fields(s, out);
  out.hover_thrust_gain = s.hover_thrust_gain;
  out.hover_thrust_converged = s.hover_thrust_converged;
  out.marker_target_id = s.marker_target_valid ? s.marker_target_id : -1;
  out.explore_phase = s.explore_phase;
  out.modes_offered = s.modes_offered;
  out.marker_mode_off_reason = s.marker_mode_off_reason;
  out.explore_mode_off_reason = s.explore_mode_off_reason;
  out.odom_valid = s.odom_valid;
  out.p_odom_m = array3(s.p_odom_m);
  out.yaw_odom_rad = s.yaw_odom_rad;
  out.odom_position_sigma_m = s.odom_position_sigma_m;
  out.odom_yaw_sigma_rad = s.odom_yaw_sigma_rad;
  out.odom_yaw_relative_to_start = s.odom_yaw_relative_to_start;
  out.v_H_sigma_mps = array3(s.v_H_sigma_mps);
  // resize() within the capacity reserved by LiveStateFeed: no allocation on the live path.
  out.obstacle_points_B_m.resize(s.obstacle_points_B_m._length);
  for (std::uint32_t i = 0; i < s.obstacle_points_B_m._length; ++i) {
    out.obstacle_points_B_m[i] = array3(s.obstacle_points_B_m._buffer[i]);
  }
  out.markers.resize(std::min<std::size_t>(s.markers._length, kMaxMarkerViews));
  for (std::size_t i = 0; i < out.markers.size(); ++i) {
    const hq_msgs_MarkerInCamera& m = s.markers._buffer[i];
    out.markers[i] = {
        m.id,
        {m.p_camera_marker_m.x, m.p_camera_marker_m.y, m.p_camera_marker_m.z},
        {m.q_camera_marker.w, m.q_camera_marker.x, m.q_camera_marker.y, m.q_camera_marker.z}};
  }
}

namespace {

// The explore mode's phase as the state carries it (0: not exploring).
const char* explore_phase_text(int phase) {
  static const char* const kNames[8] = {"",     "lift-off", "search", "explore",
                                        "edge", "navigate", "land",   "done"};
  return phase >= 0 && phase < 8 ? kNames[phase] : "";
}

// Why the vehicle does not offer `mode`, in the operator's words with what turns it on; "" when
// offered or when the vehicle does not say what it offers (modes_offered 0: an older vehicle).
const char* mode_off_text(int modes_offered, hq_msgs_Mode mode, int reason) {
  if (modes_offered == 0 || (modes_offered & link::mode_bit(mode)) != 0) return "";
  if (reason == link::kModeOffMarkerStageDisabled) {
    return "off on this vehicle (markers.enabled: false in its config; fly with --config "
           "config/markers.yaml)";
  }
  return "off on this vehicle";  // no reason, or a newer vehicle's this console does not know
}

}  // namespace

const char* recorded_mode_name(hq_msgs_Mode mode) {
  static constexpr std::array<const char*, 5> kModes = {"teleop", "hover", "land", "marker",
                                                        "explore"};
  const auto i = static_cast<std::size_t>(mode);
  return intern(i < kModes.size() ? kModes[i] : "invalid");
}

const char* flight_state_text(const char* recorded_name) {
  const std::string_view n = recorded_name != nullptr ? recorded_name : "";
  if (n == "landed") return "landed";
  if (n == "taking_off") return "taking off";
  if (n == "airborne") return "airborne";
  if (n == "landing") return "landing";
  return "-";
}

const char* operator_input_text(const char* recorded_name) {
  const std::string_view n = recorded_name != nullptr ? recorded_name : "";
  if (n == "ignored_landed") return "commands ignored: take off first";
  if (n == "ignored_mode") return "commands ignored: not teleop";
  if (n == "ignored_not_owner") return "commands ignored: another station commands";
  if (n == "ignored_failsafe") return "commands ignored: fail-safe";
  if (n == "limited_unseen") return "slowed: unseen space";
  if (n == "limited_envelope") return "slowed: flight envelope (ceiling)";
  return "";
}

void feed_state(ConsoleModel& model, const RecordedState& s) {
  StateExtras extras;
  extras.position_valid = s.position_valid;
  extras.p_W_m = s.p_W_m;
  extras.yaw_W_rad = s.yaw_W_rad;
  extras.position_invalid_reason = s.position_invalid_reason;
  extras.position_age_s = s.position_age_s;
  extras.position_sigma_m = s.position_sigma_m;
  extras.truth_valid = s.truth_valid;
  extras.v_truth_H_mps = s.v_truth_H_mps;
  extras.state_age_ms = s.state_age_ms;
  extras.round_trip_ms = s.round_trip_ms;
  extras.markers = s.markers.data();
  extras.marker_count = s.markers.size();
  extras.flight_state = s.flight_fields ? flight_state_text(s.flight_state) : "-";
  extras.motors_armed = s.flight_fields && s.motors_armed == 1;
  const std::string_view source = s.height_source;
  extras.height_valid =
      s.flight_fields && std::isfinite(s.height_m) && (source == "depth" || source == "estimate");
  extras.height_m = extras.height_valid ? static_cast<float>(s.height_m) : 0.0F;
  extras.height_source = !s.flight_fields       ? "-"
                         : source == "depth"    ? "depth"
                         : source == "estimate" ? "estimate"
                                                : "-";
  extras.operator_input = s.flight_fields ? operator_input_text(s.operator_input) : "";
  extras.clearance_m = std::isfinite(s.clearance_m) ? static_cast<float>(s.clearance_m) : -1.0F;
  extras.hover_thrust_gain = s.hover_thrust_gain;
  extras.hover_thrust_converged = s.hover_thrust_converged;
  extras.marker_target_id = s.marker_target_id;
  extras.explore_phase = explore_phase_text(s.explore_phase);
  extras.modes_offered = static_cast<std::uint8_t>(s.modes_offered);
  extras.marker_mode_off =
      mode_off_text(s.modes_offered, hq_msgs_MODE_MARKER, s.marker_mode_off_reason);
  extras.explore_mode_off =
      mode_off_text(s.modes_offered, hq_msgs_MODE_EXPLORE, s.explore_mode_off_reason);
  static_assert(sizeof(std::array<float, 3>) == 3 * sizeof(float));
  const float* cloud =
      s.obstacle_points_B_m.empty() ? nullptr : s.obstacle_points_B_m.front().data();
  model.on_state(s.receipt_ns, s.latency_ms, s.v_H_mps, s.omega_B_radps, s.roll_rad, s.pitch_rad,
                 s.v_obs_H_mps, s.mode, s.estimator_health, s.link_health, cloud,
                 s.obstacle_points_B_m.size(), extras);
}

LiveStateFeed::LiveStateFeed() {
  row_.obstacle_points_B_m.reserve(hq_msgs_kMaxObstaclePoints);
  row_.markers.reserve(kMaxMarkerViews);
}

void LiveStateFeed::on_state(ConsoleModel& model, std::int64_t receipt_ns, double latency_ms,
                             const link::VehicleState& s, const LinkFigures& figures) {
  to_recorded(receipt_ns, latency_ms, s, row_, figures);
  feed_state(model, row_);
}

}  // namespace hq::console
