#pragma once
/// hq-ground's flight loop: at the command rate, the hand's velocity command (eq. 6-10, from
/// the haptic loop) goes to the vehicle; vehicle states feed the force feedback the moment they
/// arrive; device buttons and the console's requests become mode requests; the link-loss alarm,
/// heartbeats, the console's link health and the headless status line run on their own
/// periods. The link, the haptic loop and the clock are passed in, so tests drive it with a fake
/// link and a fake clock (no DDS, no thread).

#include "hq/console/console_model.hpp"
#include "hq/ground/ground_station.hpp"
#include "hq/haptics/haptic_loop.hpp"

#include <atomic>
#include <cstdint>
#include <cstdio>

namespace hq::mcap_recorder {
class FlightRecorder;
}

namespace hq::ground {

/// The station's two clocks: CLOCK_MONOTONIC (deadlines, the haptic loop's stamps) and the
/// wall clock of recorded receipts (dds_time()).
class StationClock {
 public:
  virtual ~StationClock() = default;
  [[nodiscard]] virtual std::int64_t monotonic_ns() = 0;
  [[nodiscard]] virtual std::int64_t wall_ns() = 0;
};

/// haptics::monotonic_now_ns() and dds_time().
class SystemClock final : public StationClock {
 public:
  [[nodiscard]] std::int64_t monotonic_ns() override;
  [[nodiscard]] std::int64_t wall_ns() override;
};

/// What the console window asks of the flying thread (any thread writes, the station takes).
struct OperatorRequests {
  std::atomic<int> mode{-1};  ///< hq_msgs_Mode, -1: none.
  /// With a marker mode request: hq_msgs_MarkerTask and target id (the window's marker panel).
  std::atomic<int> marker_task{hq_msgs_MARKER_TASK_NONE};
  std::atomic<int> marker_id{0};
  std::atomic<std::int64_t> vehicle{-1};  ///< Vehicle id to select, -1: none.
  std::atomic<bool> take_off{false};      ///< The window's take-off button or key.
};

/// hq-ground's flight options (command line).
struct OperatorStationOptions {
  double command_rate_hz = 50.0;   ///< Velocity commands per second.
  double duration_s = 0.0;         ///< Stop after this long; 0: until stopped.
  bool headless = false;           ///< One status line per second on `log`.
  bool take_off = false;           ///< Ask for take-off (then teleop) once the vehicle is heard.
  MarkerChoice marker;             ///< Marker mode request once the vehicle is heard; NONE: none.
  double link_lost_after_s = 0.5;  ///< Link-loss alarm: no vehicle state for longer.
  std::uint32_t station_id = 0;    ///< This station's id, shown beside the commander's.
};

/// Where the station writes besides the link and the console (all optional).
struct OperatorOutputs {
  TelemetryRecorder* recorder = nullptr;          ///< CSV recording.
  mcap_recorder::FlightRecorder* mcap = nullptr;  ///< MCAP record: one GroundSample per tick.
  std::FILE* out = stdout;                        ///< Link lost / regained lines.
  std::FILE* log = stderr;                        ///< Requests, device loss, status lines.
};

/// Figures of the flight for hq-ground's summary.
struct OperatorStats {
  std::uint64_t ticks = 0;          ///< Command ticks run.
  std::uint64_t device_losses = 0;  ///< Device connected -> lost transitions.
  double max_state_gap_s = 0.0;     ///< Largest gap between vehicle states.
  double max_force_n = 0.0;         ///< Largest force on the hand (sampled per command tick).
};

class OperatorStation {
 public:
  /// Starts the periods now (clock.monotonic_ns()). Every reference must outlive the station.
  /// `hand` may run its own thread (HapticLoop::start) or be ticked by the caller.
  OperatorStation(const OperatorStationOptions& options, VehicleLink& link,
                  haptics::HapticLoop& hand, console::ConsoleModel& model, StationClock& clock,
                  const OperatorOutputs& outputs = {});
  OperatorStation(const OperatorStation&) = delete;
  OperatorStation& operator=(const OperatorStation&) = delete;

  /// Waits for the next command tick, handing vehicle states to the force feedback as they
  /// arrive, and runs the tick. False once duration_s is over (nothing sent then).
  bool step();
  /// step() until `stop`, `done` or the duration.
  void run(const std::atomic<bool>& stop, const std::atomic<bool>& done);

  [[nodiscard]] OperatorRequests& requests() { return requests_; }
  [[nodiscard]] const OperatorStats& stats() const { return stats_; }
  [[nodiscard]] const console::LinkLossMonitor& link_loss() const { return link_loss_; }
  /// When the station started, on CLOCK_MONOTONIC.
  [[nodiscard]] std::int64_t start_ns() const { return start_ns_; }

 private:
  void take_state(std::int64_t now_ns);
  void watch_link_loss(std::int64_t now_ns, double t_s);
  bool send_command(const haptics::LoopOutput& hand, std::int64_t now_ns, std::int64_t wall_ns);
  void show_hand(const haptics::LoopOutput& hand, bool valid, std::int64_t wall_ns);
  void request_modes(const haptics::LoopOutput& hand, std::int64_t now_ns, std::int64_t wall_ns,
                     double t_s);
  void send_heartbeat(std::int64_t now_ns);
  void report_health(std::int64_t now_ns);
  void report_status(std::int64_t now_ns, double t_s, const haptics::LoopOutput& hand);

  OperatorStationOptions options_;
  VehicleLink& link_;
  haptics::HapticLoop& hand_;
  console::ConsoleModel& model_;
  StationClock& clock_;
  OperatorOutputs outputs_;
  OperatorRequests requests_;
  OperatorStats stats_;
  console::LinkLossMonitor link_loss_;
  ModeToggle toggle_;
  std::int64_t start_ns_ = 0;
  std::int64_t period_ns_ = 0;
  std::int64_t next_ns_ = 0;  ///< Next command tick.
  std::int64_t next_heartbeat_ns_ = 0;
  std::int64_t next_status_ns_ = 0;
  std::int64_t next_health_ns_ = 0;
  std::int64_t last_state_ns_ = 0;  ///< Receipt of the last vehicle state, 0: none yet.
  std::uint64_t last_states_ = 0;   ///< States and frames at the last health report (rates).
  std::uint64_t last_frames_ = 0;
  bool marker_sent_ = false;    ///< options_.marker requested.
  bool take_off_sent_ = false;  ///< options_.take_off requested.
  bool was_connected_ = true;
  bool recording_failure_told_ = false;
  bool mcap_failure_told_ = false;
};

}  // namespace hq::ground
