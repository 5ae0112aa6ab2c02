#pragma once
/// The operator's side of the DDS link (hq-ground): publishes the haptic loop's velocity
/// commands, mode requests and heartbeats; receives vehicle state, events, heartbeats and camera
/// frames, with the one-way latency of each state (source timestamp to receipt, both on the
/// host's clock, so meaningful on loopback or with synchronised clocks).

#include "hq/haptics/teleop_mapping.hpp"
#include "hq/link/link.hpp"
#include "hq/link/sequence_tracker.hpp"

#include <array>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace hq::ground {

/// Mode toggles from device buttons, on rising edges only (a held button asks once):
/// button 0 switches teleop <-> hover, button 1 asks to land.
class ModeToggle {
 public:
  /// The mode to request now, given the buttons held and the vehicle's last reported mode.
  std::optional<hq_msgs_Mode> on_buttons(std::uint32_t buttons, hq_msgs_Mode vehicle_mode);

 private:
  std::uint32_t previous_ = 0;
};

/// The marker a mode request asks the vehicle's marker mode to fly to; NONE: none.
struct MarkerChoice {
  hq_msgs_MarkerTask task = hq_msgs_MARKER_TASK_NONE;
  std::int32_t target_id = 0;
};

/// The task named "hold", "goto" or "land"; nullopt for any other text.
std::optional<hq_msgs_MarkerTask> marker_task_of(std::string_view name);

/// Name of a link mode ("teleop", "hover", "land", "marker", "explore", "invalid").
const char* to_string(hq_msgs_Mode mode);
const char* to_string(hq_msgs_Health health);

/// Plausibility of a vehicle state beyond validate() (finite values, enums in range): speeds
/// and rates a multirotor can have, attitudes inside (-pi, pi), height, clearance and position
/// of sane size. A state failing it is a broken or forged sender's and must never reach the
/// force feedback. Static reason text.
link::Validation plausible(const link::VehicleState& state);

/// Bounds of plausible() (SI units).
inline constexpr double kMaxPlausibleSpeedMps = 20.0;
inline constexpr double kMaxPlausibleRateRadps = 35.0;  ///< 2000 deg/s, a gyro's full scale.
inline constexpr double kMaxPlausibleHeightM = 1000.0;
inline constexpr double kMaxPlausibleDistanceM = 100'000.0;
/// A forward jump of the sequence number larger than this (~1 h of states at 30 Hz) is a
/// forged sample, not lost ones, and dropped, unless a consistent run follows it
/// (link::SequenceTracker): a smaller forged jump is taken, and the real states resync after it.
inline constexpr std::uint64_t kMaxSequenceJump = 100'000;
/// The vehicle session whose states arrived this recently is live: a state of another session
/// meanwhile is forged (or a second vehicle process with the same id) and rejected.
inline constexpr std::int64_t kSessionLiveNs = 1'000'000'000;

/// Event codes the ground raises itself (Event.code in events.csv), apart from the vehicle's.
inline constexpr std::uint32_t kGroundEventControlLost = 1001;
inline constexpr std::uint32_t kGroundEventControlRegained = 1002;
inline constexpr std::uint32_t kGroundEventVehicleRestarted = 1003;
inline constexpr std::uint32_t kGroundEventWaiting = 1004;
inline constexpr std::uint32_t kGroundEventSequenceResync = 1005;

/// Latencies in a fixed histogram (10 us bins up to 100 ms); add() allocates nothing.
class LatencyStats {
 public:
  /// `bins` bins of `bin_ns` each (default 10 us up to 2 s); the last holds everything beyond.
  explicit LatencyStats(std::int64_t bin_ns = 10'000, std::size_t bins = 200'000)
      : bin_ns_(bin_ns), bins_(bins, 0) {}
  void add(std::int64_t latency_ns);
  [[nodiscard]] double quantile_ms(double q) const;
  [[nodiscard]] std::int64_t count() const { return count_; }

 private:
  std::int64_t bin_ns_;
  std::vector<std::uint32_t> bins_;
  std::int64_t count_ = 0;
};

/// What the ground knows of the vehicle and the link.
struct LinkStatus {
  bool have_state = false;
  link::VehicleState state{};         ///< Latest (obstacle cloud not kept).
  std::int64_t state_receipt_ns = 0;  ///< When it arrived (dds_time()).
  std::int64_t last_latency_ns = 0;   ///< Its source timestamp to receipt.
  std::int64_t last_vehicle_heartbeat_ns = 0;
  bool have_vehicle_heartbeat = false;
  std::uint64_t states = 0;
  std::uint64_t events = 0;
  std::uint64_t camera_frames = 0;
  std::uint64_t camera_bytes = 0;
  std::uint64_t commands_sent = 0;
  std::uint64_t mode_requests_sent = 0;
  /// Latest heartbeat round trip, ns (-1 before the vehicle echoes one).
  std::int64_t round_trip_ns = -1;
  /// Vehicle clock minus the ground's CLOCK_MONOTONIC, from the heartbeat with the least round
  /// trip of the last 16 (NTP's estimate; error at most half that round trip).
  std::int64_t clock_offset_ns = 0;
  bool have_clock_offset = false;
  /// One-way age of the latest state at receipt: its vehicle stamp through the clock offset,
  /// ns (-1 until the offset is known). What the force law's fade is given.
  std::int64_t last_state_age_ns = -1;
  std::uint64_t heartbeats_sent = 0;
  std::uint64_t write_failures = 0;
  std::array<char, 161> last_event{};     ///< Text of the latest event.
  std::uint64_t state_sequence_gaps = 0;  ///< States missing between consecutive sequences.
  std::uint64_t states_reordered = 0;     ///< Arrived after a newer one: dropped, not missing.
  /// The sequence followed was abandoned for a consistent run of dropped states (a forger's
  /// number far ahead, then the vehicle's own again): link::SequenceTracker.
  std::uint64_t states_resynced = 0;
  /// States of the selected vehicle rejected: all reasons below, never handed to the loop.
  std::uint64_t states_rejected = 0;
  std::uint64_t states_invalid = 0;        ///< Failing validate() (NaN, enums).
  std::uint64_t states_implausible = 0;    ///< Failing plausible() (magnitudes).
  std::uint64_t states_wrong_session = 0;  ///< Another session while the current one is live.
  std::uint64_t states_sequence_jump = 0;  ///< Sequence ahead by more than kMaxSequenceJump.
  std::uint64_t events_rejected = 0;       ///< Events not of the current vehicle session.
  /// The vehicle session (VehicleState.session_id) followed; 0 before the first state.
  std::uint64_t vehicle_session = 0;
  std::uint64_t vehicle_restarts = 0;  ///< New sessions after the first.
  /// A mode request waits for the vehicle's session (nothing heard yet): sent once it is.
  bool waiting_for_vehicle = false;
  /// The vehicle reports another station as its commander: this station lost control.
  bool control_lost = false;
  std::uint32_t commanding_station_id = 0;  ///< As the vehicle reports it (0: none).
  std::uint64_t control_losses = 0;
  /// The vehicle's intrusion reports (link::kEventCodeIntrusion): samples claiming a station
  /// their writer's certificate is not, this one's id among them possibly.
  std::uint64_t intrusion_reports = 0;
  std::array<char, 161> last_intrusion{};           ///< Text of the latest one.
  std::array<std::uint32_t, 8> vehicle_ids_seen{};  ///< Ids of every vehicle heard from.
  std::size_t vehicle_ids_seen_count = 0;
  /// The current session said goodbye (link::kEventCodeVehicleEnded): its silence is an end,
  /// not a link loss, and the next session may start at once. Cleared by a new session.
  bool vehicle_ended = false;
  std::array<char, 161> vehicle_ended_text{};  ///< "vehicle ended: <reason>".
};

/// Everything the station takes from the link for the selected vehicle, as it arrives (called
/// on the thread that polls; keep it short and non-blocking). The state still carries its
/// obstacle cloud, which LinkStatus drops.
class LinkObserver {
 public:
  virtual ~LinkObserver() = default;
  virtual void on_state(std::int64_t /*receipt_ns*/, std::int64_t /*latency_ns*/,
                        const link::VehicleState& /*state*/) {}
  virtual void on_camera(std::int64_t /*receipt_ns*/, const link::CameraFrame& /*frame*/) {}
  virtual void on_event(std::int64_t /*receipt_ns*/, const link::Event& /*event*/) {}
};

/// Recording of a flight as the ground saw it, in DIR: telemetry.csv (one row per vehicle
/// state), commands.csv (one row per velocity command sent), mode_requests.csv, events.csv,
/// and the camera in the TUM RGB-D layout: rgb/<t>.jpg listed in rgb.txt, depth colour maps in
/// depth_preview/ listed in depth_preview.txt. Every CSV starts with '#' lines naming frames,
/// clocks and units. All stamps named receipt_ns/t_ns here are the ground's dds_time() (the
/// host's real-time clock); vehicle_t_ns is the vehicle's own stamp.
/// @throws hq::InputError if the directory or files cannot be created, or DIR already holds a
/// recording (never overwritten). A failed write later (disk full) is not thrown from the
/// flight loop: writing stops and error() says which file and why; flush() and close() return
/// false from then on, for the operator to be told.
class TelemetryRecorder {
 public:
  explicit TelemetryRecorder(const std::string& directory);
  ~TelemetryRecorder();
  TelemetryRecorder(const TelemetryRecorder&) = delete;
  TelemetryRecorder& operator=(const TelemetryRecorder&) = delete;
  /// A state's row, with what the ground measured of the link as it arrived (the state's age
  /// through the clock offset and the latest heartbeat round trip; < 0: unknown, written 0).
  void state(std::int64_t receipt_ns, std::int64_t latency_ns, const link::VehicleState& s,
             std::int64_t state_age_ns = -1, std::int64_t round_trip_ns = -1);
  void event(std::int64_t receipt_ns, const link::Event& e);
  /// A velocity command as sent at `t_ns` (zero when not valid).
  void command(std::int64_t t_ns, const haptics::VelocityCommand& command, bool valid);
  void mode_request(std::int64_t t_ns, hq_msgs_Mode mode);
  /// Writes the JPEG (and the depth preview if any) as received, without re-encoding.
  void camera(std::int64_t receipt_ns, const link::CameraFrame& frame);
  /// Writes buffered rows to disk (called about once a second, not per row). False once any
  /// write has failed (see error()).
  bool flush();
  /// Flushes and closes every file (the destructor does too, silently); false if any write or
  /// close failed.
  bool close();
  /// The first failed write, "DIR/telemetry.csv: write failed: No space left on device; ...",
  /// or empty.
  [[nodiscard]] const std::string& error() const { return error_; }

 private:
  std::string directory_;
  std::FILE* telemetry_ = nullptr;
  std::FILE* events_ = nullptr;
  std::FILE* commands_ = nullptr;
  std::FILE* modes_ = nullptr;
  std::FILE* rgb_list_ = nullptr;
  std::FILE* depth_list_ = nullptr;
  std::FILE* obstacles_ = nullptr;  ///< obstacles.csv: each state's cloud, a point a row.
  std::FILE* markers_ = nullptr;    ///< markers.csv: each state's marker poses.
  std::string path_;                ///< Reused for frame file names.
  std::uint64_t frame_write_failures_ = 0;
  std::string error_;
  void written(int result, const char* file);
};

/// The link as the operator station (OperatorStation) drives it: GroundStation over DDS, a fake
/// in tests. Clocks as in GroundStation: deadlines and heartbeats on CLOCK_MONOTONIC.
class VehicleLink {
 public:
  virtual ~VehicleLink() = default;
  VehicleLink() = default;
  VehicleLink(const VehicleLink&) = delete;
  VehicleLink& operator=(const VehicleLink&) = delete;

  /// Takes what arrives until a vehicle state does (true) or until `deadline_ns` (false).
  virtual bool poll_until(std::int64_t deadline_ns) = 0;
  [[nodiscard]] virtual const LinkStatus& status() const = 0;
  /// Seconds since the last vehicle state (infinity before the first).
  [[nodiscard]] virtual double state_age_s() const = 0;
  [[nodiscard]] virtual std::uint32_t vehicle_id() const = 0;
  virtual void select_vehicle(std::uint32_t vehicle_id) = 0;
  /// One velocity command (zero when `valid` is false).
  virtual void send_command(std::int64_t t_ns, const haptics::VelocityCommand& command,
                            bool valid) = 0;
  /// A mode request; false while it waits for the vehicle (see GroundStation::request_mode).
  virtual bool request_mode(std::int64_t t_ns, hq_msgs_Mode mode, const MarkerChoice& marker,
                            bool take_off) = 0;
  virtual void send_heartbeat(std::int64_t t_ns) = 0;
  [[nodiscard]] virtual const LatencyStats& latency() const = 0;
  [[nodiscard]] virtual const LatencyStats& round_trip() const = 0;
  [[nodiscard]] virtual const LatencyStats& state_age() const = 0;
  /// Fraction of vehicle states missing by sequence number (0 before any).
  [[nodiscard]] virtual double state_loss() const = 0;
};

class GroundStation final : public VehicleLink {
 public:
  /// @throws hq::InputError naming the DDS call that failed.
  explicit GroundStation(const link::LinkConfig& config, TelemetryRecorder* recorder = nullptr);

  /// Also hands every state, frame and event of the selected vehicle to `observer` (may be
  /// null; must outlive the station or be reset first).
  void set_observer(LinkObserver* observer) { observer_ = observer; }
  /// Commands and listens to vehicle `vehicle_id` from now on (the console's selector).
  void select_vehicle(std::uint32_t vehicle_id) override;
  [[nodiscard]] std::uint32_t vehicle_id() const override { return config_.vehicle_id; }

  /// Publishes one command of the haptic loop (zero when `valid` is false).
  void send_command(std::int64_t t_ns, const haptics::VelocityCommand& command,
                    bool valid) override;
  /// Requests `mode`, with a marker task for the vehicle's marker stage if `marker` has one,
  /// for the vehicle session last heard from. Before any session is known the request waits
  /// (status().waiting_for_vehicle; the latest one replaces an earlier one) and goes out when
  /// the first state arrives; returns false then. A vehicle that restarts (a new session)
  /// gets nothing re-sent: the station raises "vehicle restarted" and the operator asks again.
  /// With take_off, the vehicle takes off first and then flies `mode`.
  bool request_mode(std::int64_t t_ns, hq_msgs_Mode mode, const MarkerChoice& marker = {},
                    bool take_off = false) override;
  /// Where the ground's own notices (control lost, vehicle restarted) are printed once each
  /// (e.g. stdout); null: not printed. They also go to the recorder and the observer as events.
  void set_log(std::FILE* log) { log_ = log; }
  /// @param t_ns  on CLOCK_MONOTONIC (haptics::monotonic_now_ns()): the vehicle echoes it back
  /// for the round trip.
  void send_heartbeat(std::int64_t t_ns) override;
  /// Takes everything pending. Returns true if a new vehicle state arrived.
  bool poll();
  /// Blocks on a waitset until a vehicle state arrives (returns true at once) or until
  /// `deadline_ns` on CLOCK_MONOTONIC (false), taking whatever arrives in the meantime; so
  /// receipt times, and the latency figures, are not quantised by the caller's period.
  bool poll_until(std::int64_t deadline_ns) override;

  [[nodiscard]] const LinkStatus& status() const override { return status_; }
  [[nodiscard]] const LatencyStats& latency() const override { return latency_; }
  /// Heartbeat round trips and state ages over the flight (1 ms bins up to 10 s).
  [[nodiscard]] const LatencyStats& round_trip() const override { return round_trip_; }
  [[nodiscard]] const LatencyStats& state_age() const override { return state_age_; }
  /// Fraction of vehicle states missing by sequence number (0 before any).
  [[nodiscard]] double state_loss() const override;
  /// Seconds since the last vehicle state (infinity before the first).
  [[nodiscard]] double state_age_s() const override;

 private:
  link::LinkConfig config_;
  TelemetryRecorder* recorder_;
  LinkObserver* observer_ = nullptr;
  link::SequenceTracker state_sequence_{{.max_forward_jump = kMaxSequenceJump}};
  void note_vehicle(std::uint32_t vehicle_id);
  /// Checks a state of the selected vehicle (session, sequence, values); false: rejected and
  /// counted. Adopts a new session when the current one is not live.
  /// `writer`: the DDS publication handle, so a resync follows one writer's run.
  bool admit_state(const link::VehicleState& s, std::uint64_t writer, std::int64_t receipt_ns);
  /// Counts and tells a resync of the state sequence.
  void note_resync(std::uint64_t sequence, std::uint64_t abandoned);
  void note_control(const link::VehicleState& s);
  /// A notice of the ground's own: printed to log_, recorded, shown.
  void notice(hq_msgs_Severity severity, std::uint32_t code, const char* text);
  void send_mode_request(std::int64_t t_ns, hq_msgs_Mode mode, const MarkerChoice& marker,
                         bool take_off);
  std::FILE* log_ = nullptr;
  std::uint64_t session_id_ = 0;         ///< This station's own, in its heartbeats.
  std::int64_t session_receipt_ns_ = 0;  ///< Last accepted state of the current session.
  bool pending_request_ = false;
  hq_msgs_Mode pending_mode_ = hq_msgs_MODE_HOVER;
  MarkerChoice pending_marker_;
  bool pending_take_off_ = false;
  /// Events that arrive before the vehicle's first state (its transient-local history reaches
  /// a new reader before the first periodic state): held until the session is known, then
  /// delivered if they are of it. Bounded; beyond kEarlyEvents they are rejected.
  static constexpr std::size_t kEarlyEvents = 8;
  std::array<link::Event, kEarlyEvents> early_events_{};
  std::size_t early_event_count_ = 0;
  void deliver_event(const link::Event& event);
  /// Delivers the held events of the session just learned; rejects the rest.
  void release_early_events();
  void note_echo(const link::Heartbeat& heartbeat);
  link::Participant participant_;
  link::Topics topics_;
  link::Writer<link::VelocityCommand> command_writer_;
  link::Writer<link::ModeRequest> mode_writer_;
  link::Writer<link::Heartbeat> heartbeat_writer_;
  link::Reader<link::VehicleState> state_reader_;
  link::Reader<link::CameraFrame> camera_reader_;
  link::Reader<link::Event> event_reader_;
  link::Reader<link::Heartbeat> heartbeat_reader_;
  link::ReadCondition state_condition_;
  link::ReadCondition event_condition_;
  link::WaitSet waitset_;
  link::Sample<link::VehicleState> state_sample_;
  link::Sample<link::CameraFrame> camera_sample_;
  std::uint64_t command_sequence_ = 0;
  std::uint64_t mode_sequence_ = 0;
  std::uint64_t heartbeat_sequence_ = 0;
  LinkStatus status_;
  LatencyStats latency_;
  LatencyStats round_trip_{1'000'000, 10'000};
  LatencyStats state_age_{1'000'000, 10'000};
  struct Echo {
    std::int64_t round_trip_ns = 0;
    std::int64_t offset_ns = 0;
  };
  std::array<Echo, 16> echoes_{};
  std::size_t echo_count_ = 0;
  /// The vehicle session whose heartbeats the echoes are from: another session's clock is
  /// another clock, so its offset must not be mixed with this one's.
  std::uint64_t echo_session_ = 0;
};

}  // namespace hq::ground
