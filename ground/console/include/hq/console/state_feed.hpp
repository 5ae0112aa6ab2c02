#pragma once
/// The one way a vehicle state reaches the console, live and replayed: a link sample becomes a
/// RecordedState (the row a flight record holds, the CSV's and the MCAP's alike) and the console
/// is fed from that row. The live link (hq-ground) goes through to_recorded() and feed_state();
/// a replay reads the row from the record and calls feed_state(). So whatever the live view
/// derives from a state (flight state, motors, height, clearance, obstacle cloud, markers,
/// top-view pose), the replay derives from the same fields by the same code, and a field the
/// record lacks shows as missing in both.

#include "hq/console/console_model.hpp"
#include "hq/console/recording.hpp"
#include "hq/link/link.hpp"

#include <array>
#include <cstdint>

namespace hq::console {

/// What the ground measured of the link when the state arrived (0: unknown; a replay of a
/// record that holds none passes zeros, as a live console before its first heartbeat).
struct LinkFigures {
  float state_age_ms = 0;   ///< One-way age from the vehicle stamp.
  float round_trip_ms = 0;  ///< The latest heartbeat round trip.
};

/// The row of `s` received at `receipt_ns` with `latency_ms` and the ground's link `figures`,
/// into `out` (its vectors reused: no allocation once they hold a full cloud and kMaxMarkerViews
/// markers). Enums by the names the recorders write; a vehicle that leaves the flight fields
/// unfilled (session 0) has them unknown.
void to_recorded(std::int64_t receipt_ns, double latency_ms, const link::VehicleState& s,
                 RecordedState& out, const LinkFigures& figures = {});

/// Hands `s` to `model` as the live link does (ConsoleModel::on_state with its StateExtras),
/// with the link figures the row holds.
void feed_state(ConsoleModel& model, const RecordedState& s);

/// The name the CSV recorder writes for a mode (ground_station.cpp), as static text.
const char* recorded_mode_name(hq_msgs_Mode mode);

/// The console's texts of a recorded name ("taking_off" shows as "taking off"); "-" if unknown.
const char* flight_state_text(const char* recorded_name);
/// The operator-input warning of a recorded name ("" when flown as is or unknown).
const char* operator_input_text(const char* recorded_name);

/// The live path: to_recorded() into a row sized once, then feed_state(). Allocates nothing per
/// state after construction.
class LiveStateFeed {
 public:
  LiveStateFeed();
  void on_state(ConsoleModel& model, std::int64_t receipt_ns, double latency_ms,
                const link::VehicleState& s, const LinkFigures& figures);
  /// The row of the latest state (for tests comparing it with a replayed one).
  [[nodiscard]] const RecordedState& latest() const { return row_; }

 private:
  RecordedState row_;
};

}  // namespace hq::console
