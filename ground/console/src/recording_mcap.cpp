// A Recording from a flight record (flight.mcap): the link's samples decoded (flight_mcap.hpp)
// into the rows the CSV reader produces, so replay and hq-report treat both alike.
#include "hq/console/flight_mcap.hpp"
#include "hq/console/recording.hpp"
#include "hq/console/state_feed.hpp"

#include "recording_internal.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>

namespace hq::console {

namespace {

bool finite3(const hq_msgs_Vector3f& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// The CSV reader refuses rows with a non-finite number; so does this one.
bool finite(const link::VehicleState& s) {
  return finite3(s.v_H_mps) && finite3(s.omega_B_radps) && finite3(s.v_obs_H_mps) &&
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
    RecordedState row;
    to_recorded(log_ns, 1e-6 * static_cast<double>(log_ns - publish_ns), s, row, link_figures_);
    r_.states.push_back(std::move(row));
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
    r_.mode_requests.push_back({log_ns, recorded_mode_name(m.requested_mode)});
  }
  void on_command(std::int64_t t_ns, bool valid, const std::array<float, 3>& v_H_mps,
                  float yaw_rate_radps) override {
    r_.commands.push_back({t_ns, v_H_mps, yaw_rate_radps, valid});
  }
  // The ground's figures at its latest tick before a state stand for that state's (the recorder
  // writes them per command tick, not per state).
  void on_ground_link(std::int64_t /*t_ns*/, float state_age_ms, float round_trip_ms) override {
    link_figures_.state_age_ms = std::max(state_age_ms, 0.0F);
    link_figures_.round_trip_ms = std::max(round_trip_ms, 0.0F);
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
  LinkFigures link_figures_;
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
