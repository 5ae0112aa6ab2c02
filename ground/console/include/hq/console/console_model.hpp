#pragma once
/// What the operator console shows, fed from the DDS thread (live) or a replay thread and read
/// by the UI thread. Writers call the on_*() methods; the UI copies everything into its own
/// Snapshot with snapshot(). Both hold one mutex only for a bounded copy into storage sized at
/// construction, so neither side allocates per sample and the writer (which also drives the
/// haptic loop's feedback) is never held up by rendering or JPEG decoding.
///
/// Frames: H is the core paper's horizontal NED frame (eq. 5), which turns with the heading;
/// W is a world frame fixed at the first state (NED, heading 0 there). While the vehicle sends
/// no position, the top view integrates p_W += R_z(yaw) v_H dt with yaw integrated from the
/// gyro's z rate (a dead-reckoned track: it drifts, and says so on screen). Once the vehicle
/// sends its position (the marker filter's, in the marker map's W) the track and the cloud
/// follow that, and the view says which one it shows. When the vehicle says its position is
/// lost (position_invalid_reason 2..4: no marker for too long, uncertainty over its bound,
/// markers disagreeing), the view neither follows nor dead-reckons from it: it keeps the last
/// valid position, greyed, and says why.

#include <array>
#include <cstdint>
#include <mutex>
#include <string>
#include <vector>

namespace hq::console {

/// One plotted instant (time of the state on the console's clock, seconds from the first).
struct PlotSample {
  float t_s = 0;
  std::array<float, 3> v_est_H_mps{};  ///< Estimated velocity in H (eq. 5).
  std::array<float, 3> v_cmd_H_mps{};  ///< Latest operator command in H at that time.
  std::array<float, 3> v_obs_H_mps{};  ///< Obstacle repulsion.
  float yaw_rate_cmd_radps = 0;
  float yaw_rate_meas_radps = 0;  ///< Gyro z (FRD).
  float latency_ms = 0;
  float state_age_ms = 0;                ///< One-way age from the vehicle stamp (0: unknown).
  float round_trip_ms = 0;               ///< Heartbeat round trip at that time (0: none yet).
  bool truth_valid = false;              ///< Simulator truth present in this sample.
  std::array<float, 3> v_truth_H_mps{};  ///< Simulator truth velocity in H.
};

/// A marker detected in the latest frame, its pose in the camera (optical) frame.
struct MarkerView {
  std::int32_t id = -1;
  std::array<float, 3> p_camera_marker_m{};
  std::array<float, 4> q_camera_marker{1, 0, 0, 0};  ///< w, x, y, z.
};

inline constexpr std::size_t kMaxMarkerViews = 16;  ///< hq_msgs_kMaxMarkersInState.

/// What a vehicle state carries beyond the velocity: position, markers, simulator truth.
struct StateExtras {
  bool position_valid = false;  ///< False: the top view dead-reckons.
  std::array<float, 3> p_W_m{};
  float yaw_W_rad = 0;
  const MarkerView* markers = nullptr;  ///< marker_count of them (more are dropped).
  std::size_t marker_count = 0;
  bool truth_valid = false;
  std::array<float, 3> v_truth_H_mps{};
  float state_age_ms = 0;   ///< Its one-way age from its vehicle stamp (0: unknown yet).
  float round_trip_ms = 0;  ///< The latest heartbeat round trip (0: none yet).
  /// Flight: static texts (the link's enums by name); "-" when the state carried none.
  const char* flight_state = "-";
  bool motors_armed = false;
  bool height_valid = false;        ///< False: the vehicle does not know its height.
  float height_m = 0;               ///< Body above the floor.
  const char* height_source = "-";  ///< "depth" or "estimate".
  /// What the vehicle does with the operator's input, as a warning ("" when flown as is).
  const char* operator_input = "";
  float clearance_m = -1;  ///< Closest obstacle clearance; < 0: none seen.
  /// Actual over commanded thrust as the vehicle learnt it in flight (0: not reported);
  /// converged once learnt.
  float hover_thrust_gain = 0;
  bool hover_thrust_converged = false;
  /// Why position_valid is false, as VehicleState.position_invalid_reason (0: not said);
  /// seconds since the vehicle's last marker; horizontal 1-sigma (m).
  std::uint8_t position_invalid_reason = 0;
  float position_age_s = 0;
  float position_sigma_m = 0;
  /// The marker the marker or explore mode flies to (< 0: none); the explore mode's phase
  /// (static text, "" when not exploring).
  int marker_target_id = -1;
  const char* explore_phase = "";
  /// The modes the vehicle offers (bit per hq_msgs_Mode, as VehicleState.modes_offered; 0: not
  /// said, every button stays on) and, for marker and explore when not offered, why in plain
  /// words (static text, "" when offered or not said).
  std::uint8_t modes_offered = 0;
  const char* marker_mode_off = "";
  const char* explore_mode_off = "";
};

struct TrackPoint {
  float x_W_m = 0;
  float y_W_m = 0;
};

struct EventLine {
  double t_s = 0;
  int severity = 0;
  std::array<char, 161> text{};
};

struct HapticState {
  bool valid = false;
  std::array<float, 3> p_D_m{};
  std::array<float, 3> F_D_n{};
  std::uint32_t buttons = 0;
  bool connected = false;
  float cue_weight = 0;
  float passivity_energy_j = 0;
  std::array<char, 128> status{};
};

struct LinkHealth {
  double latency_p50_ms = 0;
  double latency_p99_ms = 0;
  double last_latency_ms = 0;
  double state_age_s = -1;       ///< < 0: no state yet.
  double round_trip_ms = -1;     ///< Latest heartbeat round trip; < 0: none yet.
  double round_trip_p50_ms = 0;  ///< Over the flight.
  double round_trip_p99_ms = 0;
  double state_one_way_ms = -1;  ///< Latest state's age at receipt (vehicle stamp); < 0: none.
  double state_one_way_p99_ms = 0;
  double state_loss_percent = 0;  ///< States missing by sequence number, over the flight.
  double state_rate_hz = 0;
  double camera_rate_hz = 0;
  std::uint64_t states = 0;
  std::uint64_t camera_frames = 0;
  std::uint64_t events = 0;
  std::uint64_t commands_sent = 0;
  std::uint64_t write_failures = 0;
  std::uint64_t sequence_gaps = 0;  ///< States lost on the way.
  std::uint64_t states_rejected = 0;
  std::uint64_t states_implausible = 0;    ///< Of states_rejected: magnitudes out of range.
  std::uint64_t states_wrong_session = 0;  ///< Of states_rejected: another vehicle session.
  std::uint64_t events_rejected = 0;       ///< Not of the current vehicle session.
  std::uint64_t vehicle_session = 0;       ///< 0: no vehicle heard yet.
  bool waiting_for_vehicle = false;        ///< A mode request waits for the vehicle's session.
  /// The vehicle reports another station as its commander than this one (own_station).
  bool control_lost = false;
  std::uint32_t commanding_station = 0;
  std::uint32_t own_station = 0;
  /// The vehicle reported samples claiming a station their certificate is not (refused).
  std::uint64_t intrusion_reports = 0;
  std::array<char, 161> last_intrusion{};
  bool heartbeat_seen = false;
  std::array<std::uint32_t, 8> vehicle_ids{};
  std::size_t vehicle_id_count = 0;
  std::uint32_t selected_vehicle = 0;
  /// Link-loss alarm (LinkLossMonitor): no vehicle state for longer than its threshold.
  bool link_lost = false;
  std::uint32_t link_losses = 0;  ///< Losses so far.
  double longest_loss_s = 0;      ///< Longest loss so far (the current one included).
  /// The vehicle said goodbye (its run ended on purpose): no link-loss alarm for its silence.
  bool vehicle_ended = false;
  std::array<char, 161> vehicle_ended_text{};  ///< "vehicle ended: <reason>".
};

/// Where a replay stands (hq-ground --replay); inactive in a live console.
struct ReplayStatus {
  bool active = false;
  double position_s = 0;  ///< Recording time from its first stamp.
  double duration_s = 0;
  double speed = 1;
  bool playing = false;
  bool at_end = false;       ///< Stopped at the end of the recording (not a live link).
  std::size_t sessions = 0;  ///< Vehicle sessions begun up to position_s.
};

/// The loud line a station that lost control shows ("CONTROL LOST: station 7 commands vehicle
/// 1; this station 1 does not"), written into `out`; false (out empty) while in control.
bool control_banner(const LinkHealth& link, char* out, std::size_t size);

/// The loud line of a vehicle that reported an intrusion (another certificate speaking for a
/// station; refused on board), written into `out`; false (out empty) if none was reported.
bool intrusion_banner(const LinkHealth& link, char* out, std::size_t size);

/// The calm line of a vehicle that said goodbye ("vehicle ended: stopped by SIGTERM; landed"),
/// written into `out`; false (out empty) while the vehicle has not ended.
bool vehicle_ended_banner(const LinkHealth& link, char* out, std::size_t size);

/// The link-loss alarm's logic: lost once the newest vehicle state is older than lost_after_s,
/// regained at the next fresh state; counts the losses and keeps the longest. Pure: the age is
/// an argument.
class LinkLossMonitor {
 public:
  enum class Change { kNone, kLost, kRegained };
  explicit LinkLossMonitor(double lost_after_s = 0.5) : lost_after_s_(lost_after_s) {}
  /// @param state_age_s  age of the newest vehicle state (< 0: none received yet, never lost).
  Change update(double state_age_s);
  [[nodiscard]] bool lost() const { return lost_; }
  [[nodiscard]] std::uint32_t losses() const { return losses_; }
  [[nodiscard]] double longest_s() const { return longest_s_; }
  /// Length of the current loss, or of the last one once regained.
  [[nodiscard]] double last_loss_s() const { return last_loss_s_; }
  [[nodiscard]] double lost_after_s() const { return lost_after_s_; }

 private:
  double lost_after_s_;
  bool lost_ = false;
  std::uint32_t losses_ = 0;
  double longest_s_ = 0;
  double last_loss_s_ = 0;
  double previous_age_s_ = -1;
};

/// The UI's copy; buffers sized by ConsoleModel::make_snapshot(), reused on every copy.
struct Snapshot {
  std::vector<PlotSample> plot;  ///< Oldest first, plot_count valid.
  std::size_t plot_count = 0;
  std::uint64_t plot_total = 0;  ///< Samples ever added.
  std::vector<TrackPoint> track;
  std::size_t track_count = 0;
  /// The previous vehicle session's track (before a restart), drawn greyed; oldest first.
  std::vector<TrackPoint> previous_track;
  std::size_t previous_track_count = 0;
  std::uint64_t sessions = 0;       ///< Vehicle sessions shown (1 + restarts); 0 before any.
  std::vector<TrackPoint> cloud_W;  ///< Latest obstacle cloud, top view in W.
  std::size_t cloud_count = 0;
  std::vector<EventLine> events;  ///< Oldest first.
  std::size_t event_count = 0;
  std::vector<std::uint8_t> jpeg;  ///< Latest camera frame, jpeg_size valid.
  std::size_t jpeg_size = 0;
  std::vector<std::uint8_t> depth;
  std::size_t depth_size = 0;
  std::uint64_t camera_sequence = 0;     ///< Bumps with every frame (decode only when it moves).
  std::int64_t camera_exposure_ns = -1;  ///< Its exposure on CLOCK_MONOTONIC; -1 unknown.
  std::int64_t camera_receipt_ns = -1;   ///< Its receipt on CLOCK_MONOTONIC; -1 unknown.
  bool have_state = false;
  std::string mode = "-";
  std::string estimator_health = "-";
  std::string link_health = "-";
  const char* flight_state = "-";  ///< Static texts, see StateExtras.
  /// Seconds since the take-off while off the ground, else the last flight's length (< 0: none
  /// yet), on the vehicle states' time (it stops when they stop).
  double flight_time_s = -1;
  bool airborne = false;  ///< Off the ground (taking off, airborne or landing).
  bool motors_armed = false;
  bool height_valid = false;
  float height_m = 0;
  const char* height_source = "-";
  const char* operator_input = "";
  float clearance_m = -1;
  float hover_thrust_gain = 0;  ///< See StateExtras.
  bool hover_thrust_converged = false;
  int marker_target_id = -1;  ///< See StateExtras.
  const char* explore_phase = "";
  std::uint8_t modes_offered = 0;  ///< See StateExtras.
  const char* marker_mode_off = "";
  const char* explore_mode_off = "";
  float roll_rad = 0;
  float pitch_rad = 0;
  float yaw_W_rad = 0;
  TrackPoint position_W{};
  bool position_from_vehicle = false;  ///< position_W is the vehicle's estimate, not ours.
  std::uint64_t position_states = 0;   ///< States that carried a position.
  /// The vehicle says its position is lost (position_lost()): position_W is the last valid one.
  bool position_lost = false;
  std::uint8_t position_invalid_reason = 0;  ///< See StateExtras.
  float position_age_s = 0;
  float position_sigma_m = 0;
  bool have_truth = false;                            ///< Some state carried simulator truth.
  std::array<MarkerView, kMaxMarkerViews> markers{};  ///< Of the latest state.
  std::size_t marker_count = 0;
  std::uint64_t marker_detections = 0;  ///< Markers in all states so far.
  PlotSample latest{};
  HapticState haptics{};
  LinkHealth link{};
  std::array<char, 192> source{};  ///< "live domain 3" or "replay DIR".
  ReplayStatus replay{};
};

class ConsoleModel {
 public:
  struct Capacity {
    std::size_t plot = 4096;  ///< ~2 min at 30 states/s.
    std::size_t track = 16384;
    std::size_t cloud = 2048;  ///< hq_msgs_kMaxObstaclePoints.
    std::size_t events = 256;
    std::size_t jpeg_bytes = 262144;   ///< hq_msgs_kMaxJpegBytes.
    std::size_t depth_bytes = 131072;  ///< hq_msgs_kMaxDepthPreviewBytes.
  };
  ConsoleModel() : ConsoleModel(Capacity{}) {}
  explicit ConsoleModel(const Capacity& capacity);

  /// A vehicle state at `t_ns` (any monotonic clock shared by all on_*() calls).
  /// `cloud_B_m` is x,y,z triples in the body frame (FRD), `cloud_points` of them.
  void on_state(std::int64_t t_ns, double latency_ms, const std::array<float, 3>& v_H_mps,
                const std::array<float, 3>& omega_B_radps, float roll_rad, float pitch_rad,
                const std::array<float, 3>& v_obs_H_mps, const char* mode,
                const char* estimator_health, const char* link_health, const float* cloud_B_m,
                std::size_t cloud_points, const StateExtras& extras = StateExtras{});
  void on_command(std::int64_t t_ns, const std::array<float, 3>& v_H_mps, float yaw_rate_radps);
  void on_event(std::int64_t t_ns, int severity, const char* text);
  /// Copies the bytes (truncated to the capacity, which the link's bounds match). For the video
  /// latency: exposure_ns and receipt_ns on the ground's CLOCK_MONOTONIC, -1 when unknown.
  void on_camera(std::int64_t t_ns, const std::uint8_t* jpeg, std::size_t jpeg_size,
                 const std::uint8_t* depth, std::size_t depth_size, std::int64_t exposure_ns = -1,
                 std::int64_t receipt_ns = -1);
  void on_haptics(const HapticState& haptics);
  void on_link(const LinkHealth& link);
  void set_source(const std::string& text);
  void on_replay(const ReplayStatus& replay);
  /// Forgets every state, command, event and frame (a replay seeking backwards refills it);
  /// keeps the source and the buffers' storage.
  void reset();
  /// A restarted vehicle (a new session): what belonged to the old one is reset. Its track
  /// starts afresh at W's origin with yaw 0 instead of being joined to its predecessor's (which
  /// is kept as previous_track, drawn greyed), its cloud, markers and pose are dropped, and the
  /// plots restart empty with the new session's first state at t = 0, so no axis spans two
  /// sessions. Events are kept. Allocates nothing.
  void start_new_track();

  /// A Snapshot with every buffer at its capacity.
  [[nodiscard]] Snapshot make_snapshot() const;
  /// Copies the current state into `out` (from make_snapshot()); allocates nothing.
  void snapshot(Snapshot& out) const;

 private:
  double seconds(std::int64_t t_ns);
  void add_event(double t_s, int severity, const char* text);  ///< With mutex_ held.
  void track_flight(double t_s, const char* flight_state);     ///< With mutex_ held.

  Capacity capacity_;
  mutable std::mutex mutex_;
  std::int64_t t0_ns_ = 0;
  bool have_t0_ = false;
  std::int64_t last_state_ns_ = 0;
  std::vector<PlotSample> plot_;  ///< Ring.
  std::uint64_t plot_total_ = 0;
  std::vector<TrackPoint> track_;  ///< Ring.
  std::uint64_t track_total_ = 0;
  std::vector<TrackPoint> previous_track_;  ///< Oldest first, sized as track_.
  std::size_t previous_track_count_ = 0;
  std::uint64_t sessions_ = 0;
  std::vector<TrackPoint> cloud_W_;
  std::size_t cloud_count_ = 0;
  std::vector<EventLine> events_;  ///< Ring.
  std::uint64_t events_total_ = 0;
  std::vector<std::uint8_t> jpeg_;
  std::size_t jpeg_size_ = 0;
  std::vector<std::uint8_t> depth_;
  std::size_t depth_size_ = 0;
  std::uint64_t camera_sequence_ = 0;
  std::int64_t camera_exposure_ns_ = -1;
  std::int64_t camera_receipt_ns_ = -1;
  std::array<float, 3> command_{};
  float yaw_rate_command_ = 0;
  double yaw_W_rad_ = 0;
  double x_W_m_ = 0;
  double y_W_m_ = 0;
  bool position_from_vehicle_ = false;
  std::uint64_t position_states_ = 0;
  bool position_lost_ = false;
  std::uint8_t position_invalid_reason_ = 0;
  float position_age_s_ = 0;
  float position_sigma_m_ = 0;
  bool have_truth_ = false;
  std::array<MarkerView, kMaxMarkerViews> markers_{};
  std::size_t marker_count_ = 0;
  std::uint64_t marker_detections_ = 0;
  bool have_state_ = false;
  const char* mode_ = "-";  ///< Static strings (to_string of the link's enums).
  const char* estimator_health_ = "-";
  const char* link_health_ = "-";
  const char* flight_state_ = "-";
  bool motors_armed_ = false;
  bool height_valid_ = false;
  float height_m_ = 0;
  const char* height_source_ = "-";
  const char* operator_input_ = "";
  float clearance_m_ = -1;
  float hover_thrust_gain_ = 0;
  bool hover_thrust_converged_ = false;
  float roll_rad_ = 0;
  float pitch_rad_ = 0;
  PlotSample latest_{};
  HapticState haptics_{};
  LinkHealth link_{};
  std::array<char, 192> source_{};
  ReplayStatus replay_{};
  double take_off_s_ = -1;  ///< < 0: on the ground.
  int marker_target_id_ = -1;
  const char* explore_phase_ = "";
  std::uint8_t modes_offered_ = 0;
  const char* marker_mode_off_ = "";
  const char* explore_mode_off_ = "";
  double last_flight_s_ = -1;
  double last_state_s_ = 0;
};

}  // namespace hq::console
