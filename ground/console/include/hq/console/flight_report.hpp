#pragma once
/// The figures of a flight report (hq-report) from a recording, pure: what the ground received,
/// measured as the vehicle measures it where both measure the same thing.
///   - sessions: where the vehicle restarted (replay_player.hpp's rule); the track, the losses
///     and the gaps are per session, a restart is listed, not counted as a loss;
///   - largest gap: the longest interval between consecutive states in ground receipt time
///     (unclamped), and the vehicle's "ground heartbeat lost" events;
///   - mode changes: every change of the vehicle's reported mode between consecutive states
///     (the count is the list's length; the first state's mode is the initial mode, not a change);
///   - closest obstacle: the vehicle's own clearance (VehicleState.clearance_m, the quantity of
///     its flight summary's "closest distance (clearance)") where recorded; the nearest point of
///     the down-sampled cloud from the body origin (closest_obstacle_m) is a different quantity
///     (no vehicle radius, a sparse cloud) and is reported under its own name.

#include "hq/console/recording.hpp"
#include "hq/console/replay_player.hpp"

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace hq::console {

struct SessionFigures {
  std::uint64_t session_id = 0;  ///< 0: unknown (recording without sessions).
  const char* why = "";          ///< How its start was found.
  double start_s = 0;            ///< Its first state.
  double end_s = 0;
  std::size_t states = 0;
  double vehicle_duration_s = 0;  ///< Span of its vehicle stamps (the vehicle's own clock).
  std::uint64_t states_lost = 0;  ///< Missing sequence numbers within the session.
};

struct ModeChange {
  double t_s = 0;
  const char* from = "";
  const char* to = "";
};

/// Times are seconds on the replay's timeline: from the recording's earliest stamp (Timeline).
struct ReportFigures {
  Timeline timeline;      ///< Its origin, span, mode bands, event marks and sessions.
  double duration_s = 0;  ///< First to last state, ground receipt time.
  std::size_t states = 0;
  std::vector<SessionFigures> sessions;
  std::uint64_t states_lost = 0;           ///< Over all sessions.
  double largest_gap_s = 0;                ///< Between consecutive states (across a restart too).
  double largest_gap_at_s = 0;             ///< Where it began.
  std::vector<double> link_lost_events_s;  ///< The vehicle's "ground heartbeat lost" events.
  const char* initial_mode = "-";
  std::vector<ModeChange> mode_changes;
  static constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
  double closest_clearance_m = kNan;  ///< The vehicle's clearance_m; NaN: not recorded.
  double closest_clearance_at_s = kNan;
  double closest_cloud_point_m = kNan;  ///< Nearest cloud point from the body origin.
  double max_height_m = kNan;           ///< NaN: no height recorded.
  std::size_t height_states = 0;
  double latency_p50_ms = 0;
  double latency_p99_ms = 0;
  double latency_max_ms = 0;
  std::size_t warnings = 0;  ///< Events of severity warning or error.
};

/// @throws nothing; an empty recording gives zeros.
ReportFigures compute_report(const Recording& recording);

}  // namespace hq::console
