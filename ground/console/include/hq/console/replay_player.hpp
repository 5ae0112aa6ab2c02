#pragma once
/// A seekable player of a recording (hq-ground --replay): the recording indexed by time, a
/// position that plays, pauses, changes speed (0.25x to 8x), seeks and steps, and an end state.
/// Pure: no clock and no thread; the caller says how much wall time passed (advance()) and the
/// player brings a ConsoleModel to its position (feed(), the only part that reads files: the
/// camera frame on show). Everything it reports (counts, rates) is of the replayed data up to
/// the position, never of the playback itself.
///
/// Vehicle sessions: a restarted vehicle is a new session. A state starts one when its
/// session_id differs from the previous state's (both known), or, in a recording without
/// sessions, when its sequence number restarts (falls below the previous and is at most
/// kRestartSequence) or its vehicle stamp jumps back. Replay and hq-report split tracks there.

#include "hq/console/console_model.hpp"
#include "hq/console/recording.hpp"

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

namespace hq::console {

/// A stretch of the recording in one vehicle mode (from the states' mode), seconds from t0.
struct ModeBand {
  double start_s = 0;
  double end_s = 0;
  const char* mode = "invalid";  ///< Static (intern()).
};

struct EventMark {
  double t_s = 0;
  int severity = 0;
};

struct SessionStart {
  double t_s = 0;
  std::size_t first_state = 0;   ///< Index into Recording::states.
  std::uint64_t session_id = 0;  ///< 0: unknown (recording without sessions).
  const char* why = "";          ///< "first", "new session_id", "sequence restarted", ...
};

/// A sequence number at most this after a fall is a restarted vehicle, not a reordered state.
inline constexpr std::uint64_t kRestartSequence = 100;

/// Indices of `states` that begin a vehicle session (see the file comment); the first state
/// always begins one.
std::vector<SessionStart> find_sessions(const std::vector<RecordedState>& states,
                                        std::int64_t t0_ns);

/// The recording's timeline: its span, mode bands, event marks and sessions.
struct Timeline {
  std::int64_t t0_ns = 0;  ///< Earliest stamp of states, commands, events and frames.
  double duration_s = 0;   ///< To the latest of them.
  std::vector<ModeBand> bands;
  std::vector<EventMark> marks;
  std::vector<SessionStart> sessions;
};
Timeline make_timeline(const Recording& recording);

/// What the replayed data holds up to the position.
struct ReplayCounts {
  std::size_t states = 0;
  std::size_t commands = 0;
  std::size_t events = 0;  ///< Recorded events plus "vehicle restarted" lines: those shown.
  std::size_t frames = 0;
  double state_rate_hz = 0;         ///< States in the last second of recording time.
  double camera_rate_hz = 0;        ///< Frames in the last second of recording time.
  std::uint64_t sequence_gaps = 0;  ///< States missing by sequence number within sessions.
  std::size_t sessions = 0;
  double latency_p50_ms = 0;  ///< Over the states of the last second.
  double latency_last_ms = 0;
  double state_age_s = -1;  ///< Position minus the newest state's time; < 0: none yet.
};

class ReplayPlayer {
 public:
  static constexpr double kMinSpeed = 0.25;
  static constexpr double kMaxSpeed = 8.0;

  /// `recording` must outlive the player. Starts paused at 0 (play() to start).
  explicit ReplayPlayer(const Recording& recording);

  [[nodiscard]] const Timeline& timeline() const { return timeline_; }
  [[nodiscard]] double position_s() const { return position_s_; }
  [[nodiscard]] double duration_s() const { return timeline_.duration_s; }
  [[nodiscard]] bool playing() const { return playing_; }
  [[nodiscard]] double speed() const { return speed_; }
  /// At the end of the recording: nothing more will come (shown as such, not as a live link).
  [[nodiscard]] bool at_end() const { return position_s_ >= timeline_.duration_s; }

  /// Plays; at the end, from the start again.
  void play();
  void pause() { playing_ = false; }
  void toggle_play();
  /// Clamped to [kMinSpeed, kMaxSpeed].
  void set_speed(double speed);
  /// The next of 0.25, 0.5, 1, 2, 4, 8 above / below the current speed.
  void faster();
  void slower();
  /// Clamped to [0, duration].
  void seek(double t_s);
  /// Moves the position by dt_s (either way), playing or not.
  void step(double dt_s) { seek(position_s_ + dt_s); }
  /// `wall_dt_s` of wall time passed: while playing the position moves speed * wall_dt_s; at
  /// the end it stops there and pauses.
  void advance(double wall_dt_s);

  [[nodiscard]] ReplayCounts counts() const;
  [[nodiscard]] ReplayStatus status() const;

  /// Brings `model` to the position: forwards by feeding what lies between, backwards by
  /// model.reset() and feeding from the start. Of the camera frames passed only the newest is
  /// shown (read from disk in a CSV recording); one missing or unreadable counts in
  /// frames_missing. Also sets the model's LinkHealth (counts(), the recorded round trip and
  /// state age, a recorded goodbye) and ReplayStatus.
  void feed(ConsoleModel& model, std::uint64_t& frames_missing);

 private:
  [[nodiscard]] std::int64_t position_ns() const;
  // feed()'s stages: back to the start if the position moved back; states, commands and
  // events up to t_ns; the newest camera frame; counts and replay status.
  void rewind_if_behind(ConsoleModel& model, std::int64_t t_ns);
  void feed_streams(ConsoleModel& model, std::int64_t t_ns);
  void feed_state(ConsoleModel& model);
  void feed_camera(ConsoleModel& model, std::int64_t t_ns, std::uint64_t& frames_missing);
  void publish_status(ConsoleModel& model) const;

  const Recording& recording_;
  Timeline timeline_;
  std::vector<std::uint64_t> gaps_before_;  ///< Sequence gaps among states [0, i].
  std::vector<std::size_t> session_of_;     ///< Session index of each state.
  double position_s_ = 0;
  double speed_ = 1;
  bool playing_ = false;
  // What the model holds: items before these indices have been fed.
  bool fed_any_ = false;
  std::int64_t fed_ns_ = 0;
  std::size_t is_ = 0;
  std::size_t ic_ = 0;
  std::size_t ie_ = 0;
  std::size_t ir_ = 0;
  std::size_t next_session_ = 0;
  // The fed session's goodbye (link::kEventCodeVehicleEnded), shown as the live console's
  // banner until the next session starts.
  bool vehicle_ended_ = false;
  std::array<char, 161> vehicle_ended_text_{};
  std::vector<std::uint8_t> jpeg_;
  std::vector<std::uint8_t> depth_;
  mutable std::vector<double> latency_window_;
};

/// "mm:ss.s" of a replay clock.
void format_clock(double t_s, char* out, std::size_t size);

/// Requests from the UI thread to the thread that owns the player: lock-free, the latest of
/// each kind wins.
struct ReplayControl {
  std::atomic<int> toggles{0};
  std::atomic<int> speed_steps{0};    ///< +1 faster, -1 slower, summed.
  std::atomic<double> seek_to_s{-1};  ///< < 0: none.
  std::atomic<double> seek_by_s{0};
  /// Applies and clears what is pending.
  void apply(ReplayPlayer& player);
};

}  // namespace hq::console
