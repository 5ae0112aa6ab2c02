// A Recording from a flight record (flight.mcap): the link's samples decoded (flight_mcap.hpp)
// into the rows the CSV reader produces, so replay and hq-report treat both alike.
#include "hq/console/flight_mcap.hpp"
#include "hq/console/recording.hpp"

#include "recording_internal.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>

namespace hq::console {

namespace {

// The names the CSV recorder writes for the link's enums (ground_station.cpp), as static text.
const char* mode_name(hq_msgs_Mode v) {
  static constexpr std::array<const char*, 5> kModes = {"teleop", "hover", "land", "marker",
                                                        "explore"};
  const auto i = static_cast<std::size_t>(v);
  return intern(i < kModes.size() ? kModes[i] : "invalid");
}

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

bool finite3(const hq_msgs_Vector3f& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Closest point of the down-sampled cloud to the body origin, NaN without one (the CSV's
// closest_obstacle_m).
double closest_cloud_point_m(const link::VehicleState& s) {
  double best_sq = std::numeric_limits<double>::infinity();
  for (std::uint32_t i = 0; i < s.obstacle_points_body_m._length; ++i) {
    const hq_msgs_Vector3f& p = s.obstacle_points_body_m._buffer[i];
    const auto x = static_cast<double>(p.x);
    const auto y = static_cast<double>(p.y);
    const auto z = static_cast<double>(p.z);
    best_sq = std::min(best_sq, x * x + y * y + z * z);
  }
  return std::isfinite(best_sq) ? std::sqrt(best_sq) : std::numeric_limits<double>::quiet_NaN();
}

// The flight fields as load_recording reads them from the CSV: unknown for a vehicle that
// leaves them unfilled (session 0).
void set_flight_fields(const link::VehicleState& s, RecordedState& out) {
  out.session_id = s.session_id;
  out.commanding_station_id = s.commanding_station_id;
  out.flight_fields = s.session_id != 0;
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

RecordedState to_recorded(std::int64_t log_ns, std::int64_t publish_ns,
                          const link::VehicleState& s) {
  RecordedState out;
  out.receipt_ns = log_ns;
  out.latency_ms = 1e-6 * static_cast<double>(log_ns - publish_ns);
  out.sequence = s.sequence_number;
  out.vehicle_t_ns = s.t_ns;
  out.v_H_mps = array3(s.v_H_mps);
  out.omega_body_radps = array3(s.omega_body_radps);
  out.roll_rad = s.roll_rad;
  out.pitch_rad = s.pitch_rad;
  out.v_obs_H_mps = array3(s.v_obs_H_mps);
  out.mode = mode_name(s.mode);
  out.estimator_health = health_name(s.estimator_health);
  out.link_health = health_name(s.link_health);
  out.closest_obstacle_m = closest_cloud_point_m(s);
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
  return out;
}

// The CSV reader refuses rows with a non-finite number; so does this one.
bool finite(const link::VehicleState& s) {
  return finite3(s.v_H_mps) && finite3(s.omega_body_radps) && finite3(s.v_obs_H_mps) &&
         std::isfinite(s.roll_rad) && std::isfinite(s.pitch_rad) && finite3(s.p_W_m) &&
         std::isfinite(s.yaw_W_rad) && finite3(s.v_truth_H_mps) && finite3(s.v_cmd_flown_H_mps);
}

// Keeps the items whose vehicle is `vehicle` (`vehicles` runs beside `items`).
template <typename T>
void keep_vehicle(std::vector<T>& items, const std::vector<std::uint32_t>& vehicles,
                  std::uint32_t vehicle) {
  std::size_t kept = 0;
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (vehicles[i] != vehicle) continue;
    if (kept != i) items[kept] = std::move(items[i]);  // never onto itself: that empties it
    ++kept;
  }
  items.resize(kept);
}

class RecordingBuilder : public FlightSampleSink {
 public:
  explicit RecordingBuilder(Recording& r) : r_(r) {}

  void on_state(std::int64_t log_ns, std::int64_t publish_ns,
                const link::VehicleState& s) override {
    if (!finite(s)) {
      add_problem(r_, r_.directory + ": /hq/vehicle_state sequence " +
                          std::to_string(s.sequence_number) + ": a field is not finite; skipped");
      return;
    }
    r_.states.push_back(to_recorded(log_ns, publish_ns, s));
    state_vehicle_.push_back(s.vehicle_id);
    ++states_of_[s.vehicle_id];
  }
  void on_camera(std::int64_t log_ns, const link::CameraFrame& f) override {
    if (f.rgb_jpeg._length > 0) {
      r_.rgb.push_back({log_ns, "", {f.rgb_jpeg._buffer, f.rgb_jpeg._buffer + f.rgb_jpeg._length}});
      rgb_vehicle_.push_back(f.vehicle_id);
    }
    if (f.depth_preview._length > 0) {
      const auto& d = f.depth_preview;
      r_.depth_preview.push_back({log_ns, "", {d._buffer, d._buffer + d._length}});
      depth_vehicle_.push_back(f.vehicle_id);
    }
  }
  void on_event(std::int64_t log_ns, const link::Event& e) override {
    r_.events.push_back({log_ns, static_cast<int>(e.severity), static_cast<int>(e.code), e.text});
    event_vehicle_.push_back(e.vehicle_id);
  }
  void on_mode_request(std::int64_t log_ns, const link::ModeRequest& m) override {
    r_.mode_requests.push_back({log_ns, mode_name(m.requested_mode)});
  }
  void on_command(std::int64_t t_ns, bool valid, const std::array<float, 3>& v_H_mps,
                  float yaw_rate_radps) override {
    r_.commands.push_back({t_ns, v_H_mps, yaw_rate_radps, valid});
  }
  void on_problem(const std::string& text) override { add_problem(r_, text); }

  // One vehicle's track: the one the recording has most states of.
  void keep_main_vehicle() {
    if (states_of_.size() <= 1) return;
    const auto main =
        std::max_element(states_of_.begin(), states_of_.end(),
                         [](const auto& a, const auto& b) { return a.second < b.second; });
    std::string others;
    for (const auto& [vehicle, count] : states_of_) {
      if (vehicle == main->first) continue;
      others += (others.empty() ? "" : ", ") + std::to_string(vehicle) + " (" +
                std::to_string(count) + " states)";
    }
    add_problem(r_, r_.directory + ": vehicle " + std::to_string(main->first) +
                        " shown (most states); not shown: vehicle " + others);
    keep_vehicle(r_.states, state_vehicle_, main->first);
    keep_vehicle(r_.rgb, rgb_vehicle_, main->first);
    keep_vehicle(r_.depth_preview, depth_vehicle_, main->first);
    keep_vehicle(r_.events, event_vehicle_, main->first);
  }

 private:
  Recording& r_;
  std::vector<std::uint32_t> state_vehicle_;
  std::vector<std::uint32_t> rgb_vehicle_;
  std::vector<std::uint32_t> depth_vehicle_;
  std::vector<std::uint32_t> event_vehicle_;
  std::map<std::uint32_t, std::size_t> states_of_;
};

}  // namespace

Recording load_mcap_recording(const std::string& mcap_path) {
  const mcap::McapReader reader(mcap_path);
  Recording r;
  r.directory = mcap_path;
  r.from_mcap = true;
  const std::string name = std::filesystem::path(mcap_path).filename().string();
  if (!reader.report().has_summary) {
    add_problem(
        r, name + ": no summary (the recorder was killed?): " +
               std::to_string(reader.messages().size()) + " messages recovered, " +
               std::to_string(reader.report().file_size_bytes - reader.report().valid_end_bytes) +
               " bytes at the tail dropped");
  }
  // A damaged chunk or record was left out: the replay and the report say what is missing.
  for (const std::string& warning : reader.report().warnings) add_problem(r, warning);
  RecordingBuilder builder(r);
  read_flight(reader, name, builder);
  builder.keep_main_vehicle();
  return r;
}

}  // namespace hq::console
