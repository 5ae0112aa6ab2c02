#pragma once
/// Reading back a flight recorded by hq-ground --record (hq::ground::TelemetryRecorder's
/// layout) and replaying it into a ConsoleModel. A damaged recording is read as far as it goes:
/// every unreadable line is skipped and named ("telemetry.csv:17: ..."), so replay and
/// hq-report show what survives and say what did not.

#include "hq/console/console_model.hpp"

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace hq::console {

struct RecordedState {
  std::int64_t receipt_ns = 0;  ///< Ground clock.
  double latency_ms = 0;
  std::uint64_t sequence = 0;
  std::int64_t vehicle_t_ns = 0;
  std::array<float, 3> v_H_mps{};
  std::array<float, 3> omega_body_radps{};
  float roll_rad = 0;
  float pitch_rad = 0;
  std::array<float, 3> v_obs_H_mps{};
  const char* mode = "invalid";  ///< Static text (see intern()).
  const char* estimator_health = "invalid";
  const char* link_health = "invalid";
  double closest_obstacle_m = 0;  ///< NaN when unknown (or older recordings).
  /// Marker filter pose in the map frame W (NED); false when absent or not anchored.
  bool position_valid = false;
  std::array<float, 3> p_W_m{};
  float yaw_W_rad = 0;
  /// Simulator truth of the velocity in H; false on a real vehicle or older recordings.
  bool truth_valid = false;
  std::array<float, 3> v_truth_H_mps{};
  int markers_n = -1;  ///< Markers detected in the state's frame; -1 when not recorded.
};

struct RecordedCommand {
  std::int64_t t_ns = 0;  ///< Ground clock.
  std::array<float, 3> v_H_mps{};
  float yaw_rate_radps = 0;
  bool valid = false;
};

struct RecordedModeRequest {
  std::int64_t t_ns = 0;
  const char* mode = "invalid";
};

struct RecordedEvent {
  std::int64_t receipt_ns = 0;
  int severity = 0;
  std::string text;
};

struct RecordedFrame {
  std::int64_t t_ns = 0;  ///< Receipt on the ground clock.
  std::string path;       ///< Absolute or relative to the working directory.
};

struct Recording {
  std::string directory;
  std::vector<RecordedState> states;
  std::vector<RecordedCommand> commands;
  std::vector<RecordedModeRequest> mode_requests;
  std::vector<RecordedEvent> events;
  std::vector<RecordedFrame> rgb;
  std::vector<RecordedFrame> depth_preview;
  /// Optional columns the files lack ("telemetry.csv: truth_valid"): older layouts, read
  /// without them (their fields keep the defaults above).
  std::vector<std::string> absent_columns;
  std::vector<std::string> problems;  ///< "file:line: what", first kMaxProblems.
  std::size_t problem_count = 0;      ///< All of them.
  static constexpr std::size_t kMaxProblems = 100;
};

/// Reads `directory`. @throws hq::InputError if it is not a directory, holds neither
/// telemetry.csv nor rgb.txt (nothing of an hq-ground recording), or has a stamp out of time
/// order, more than an hour after its file's previous one, or a file starting more than an
/// hour from the others (file:line named). Every other defect is a problem in the result.
Recording load_recording(const std::string& directory);

/// The static name among the link's mode and health names equal to `text`, else "invalid".
const char* intern(std::string_view text);

/// Replays `recording` into `model` on its recorded timeline scaled by 1/`speed`, from the
/// calling thread, until its end or `stop`. JPEGs are read from disk as their time comes (a
/// missing or unreadable one is counted in `frames_missing`). Returns false if stopped.
bool replay(const Recording& recording, ConsoleModel& model, double speed,
            const std::atomic<bool>& stop, std::atomic<std::uint64_t>& frames_missing);

}  // namespace hq::console
