#include "hq/console/flight_report.hpp"

#include <algorithm>
#include <cmath>

namespace hq::console {

namespace {

constexpr int kHeartbeatLostCode = 7;  // hq::link_bridge::EventCode::kHeartbeatLost

double seconds(std::int64_t from_ns, std::int64_t to_ns) {
  return 1e-9 * static_cast<double>(to_ns - from_ns);
}

}  // namespace

ReportFigures compute_report(const Recording& r) {
  ReportFigures f;
  f.states = r.states.size();
  f.timeline = make_timeline(r);
  if (r.states.empty()) return f;
  const std::int64_t t0_ns = f.timeline.t0_ns;
  f.duration_s = seconds(r.states.front().receipt_ns, r.states.back().receipt_ns);
  const std::vector<SessionStart> starts = find_sessions(r.states, t0_ns);
  for (std::size_t k = 0; k < starts.size(); ++k) {
    const std::size_t first = starts[k].first_state;
    const std::size_t end = k + 1 < starts.size() ? starts[k + 1].first_state : r.states.size();
    SessionFigures s;
    s.session_id = starts[k].session_id;
    s.why = starts[k].why;
    s.start_s = starts[k].t_s;
    s.end_s = seconds(t0_ns, r.states[end - 1].receipt_ns);
    s.states = end - first;
    s.vehicle_duration_s = seconds(r.states[first].vehicle_t_ns, r.states[end - 1].vehicle_t_ns);
    for (std::size_t i = first + 1; i < end; ++i) {
      if (r.states[i].sequence > r.states[i - 1].sequence + 1) {
        s.states_lost += r.states[i].sequence - r.states[i - 1].sequence - 1;
      }
    }
    f.states_lost += s.states_lost;
    f.sessions.push_back(s);
  }
  f.initial_mode = r.states.front().mode;
  std::vector<double> latencies;
  latencies.reserve(r.states.size());
  for (std::size_t i = 0; i < r.states.size(); ++i) {
    const RecordedState& s = r.states[i];
    const double t_s = seconds(t0_ns, s.receipt_ns);
    if (i > 0) {
      const RecordedState& p = r.states[i - 1];
      const double gap_s = seconds(p.receipt_ns, s.receipt_ns);
      if (gap_s > f.largest_gap_s) {
        f.largest_gap_s = gap_s;
        f.largest_gap_at_s = seconds(t0_ns, p.receipt_ns);
      }
      if (p.mode != s.mode) f.mode_changes.push_back({t_s, p.mode, s.mode});
    }
    if (std::isfinite(s.clearance_m) &&
        !(s.clearance_m >= f.closest_clearance_m)) {  // NaN compares false: the first one
      f.closest_clearance_m = s.clearance_m;
      f.closest_clearance_at_s = t_s;
    }
    if (std::isfinite(s.closest_obstacle_m)) {
      f.closest_cloud_point_m = std::isnan(f.closest_cloud_point_m)
                                    ? s.closest_obstacle_m
                                    : std::min(f.closest_cloud_point_m, s.closest_obstacle_m);
    }
    if (std::isfinite(s.height_m)) {
      f.max_height_m =
          std::isnan(f.max_height_m) ? s.height_m : std::max(f.max_height_m, s.height_m);
      ++f.height_states;
    }
    latencies.push_back(s.latency_ms);
  }
  std::sort(latencies.begin(), latencies.end());
  f.latency_p50_ms = latencies[latencies.size() / 2];
  f.latency_p99_ms = latencies[std::min(latencies.size() - 1, latencies.size() * 99 / 100)];
  f.latency_max_ms = latencies.back();
  for (const RecordedEvent& e : r.events) {
    f.warnings += e.severity >= 1 ? 1 : 0;
    if (e.code == kHeartbeatLostCode) f.link_lost_events_s.push_back(seconds(t0_ns, e.receipt_ns));
  }
  return f;
}

}  // namespace hq::console
