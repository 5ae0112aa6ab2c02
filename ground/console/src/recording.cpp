#include "hq/console/recording.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/console/flight_mcap.hpp"
#include "hq/console/replay_player.hpp"

#include "recording_internal.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string_view>
#include <thread>
#include <time.h>

namespace hq::console {

namespace {

namespace fs = std::filesystem;

constexpr std::array<const char*, 9> kNames = {"teleop", "hover",    "land", "marker", "explore",
                                               "ok",     "degraded", "lost", "invalid"};

// The recorder's names of the link's flight enums (ground_station.cpp), static for RecordedState.
constexpr std::array<const char*, 16> kFlightNames = {"landed",
                                                      "taking_off",
                                                      "airborne",
                                                      "landing",
                                                      "none",
                                                      "depth",
                                                      "estimate",
                                                      "flown",
                                                      "ignored_mode",
                                                      "ignored_landed",
                                                      "ignored_not_owner",
                                                      "ignored_failsafe",
                                                      "limited_unseen",
                                                      "limited_envelope",
                                                      "unknown",
                                                      "invalid"};

const char* intern_flight(std::string_view text) {
  for (const char* name : kFlightNames) {
    if (text == name) return name;
  }
  return nullptr;
}

std::vector<std::string_view> split(std::string_view line, std::size_t max_fields) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  while (fields.size() + 1 < max_fields) {
    const std::size_t comma = line.find(',', start);
    if (comma == std::string_view::npos) break;
    fields.push_back(line.substr(start, comma - start));
    start = comma + 1;
  }
  fields.push_back(line.substr(start));
  return fields;
}

// One garbled stamp (a flipped digit) used to make replay wait for years: every file's stamps
// must be in time order, at most this far apart, and the files of one recording must start
// within it of each other.
constexpr std::int64_t kMaxStampGapNs = 3600LL * 1'000'000'000LL;

std::string seconds_text(std::int64_t ns) {
  char text[32];
  hq::format_into(text, "{:.6g} s", 1e-9 * static_cast<double>(ns));
  return text;
}

// Checks the stamps of one file row by row; records where the file starts.
class StampOrder {
 public:
  StampOrder(std::string name, std::string column,
             std::vector<std::pair<std::string, std::int64_t>>& starts)
      : name_(std::move(name)), column_(std::move(column)), starts_(starts) {}

  /// @throws hq::InputError naming file:line, the stamp and the previous row's.
  void check(std::int64_t t_ns, std::size_t line) {
    const std::string where =
        name_ + ":" + std::to_string(line) + ": " + column_ + " = " + std::to_string(t_ns);
    if (t_ns < 0) throw InputError(where + ", expected a stamp >= 0");
    if (previous_line_ == 0) {
      starts_.emplace_back(name_ + ":" + std::to_string(line), t_ns);
    } else if (t_ns < previous_ns_ || t_ns - previous_ns_ > kMaxStampGapNs) {
      throw InputError(
          where + " is " +
          seconds_text(t_ns < previous_ns_ ? previous_ns_ - t_ns : t_ns - previous_ns_) +
          (t_ns < previous_ns_ ? " before" : " after") + " line " + std::to_string(previous_line_) +
          "'s " + std::to_string(previous_ns_) + ", expected rows in time order at most " +
          seconds_text(kMaxStampGapNs) + " apart (a garbled stamp?)");
    }
    previous_ns_ = t_ns;
    previous_line_ = line;
  }

 private:
  std::string name_;
  std::string column_;
  std::vector<std::pair<std::string, std::int64_t>>& starts_;
  std::int64_t previous_ns_ = 0;
  std::size_t previous_line_ = 0;
};

// Columns renamed to the frame letters of hq/geometry/frames.hpp, by their new name: the name
// recordings made before the rename have instead, read as the same column.
const std::pair<std::string_view, std::string_view> kColumnsRenamed[] = {
    {"omega_B_x_radps", "omega_x_radps"},  // vocabulary: old spelling
    {"omega_B_y_radps", "omega_y_radps"},  // vocabulary: old spelling
    {"omega_B_z_radps", "omega_z_radps"},  // vocabulary: old spelling
    {"v_obs_H_x_mps", "v_obs_x_mps"},      // vocabulary: old spelling
    {"v_obs_H_y_mps", "v_obs_y_mps"},      // vocabulary: old spelling
    {"v_obs_H_z_mps", "v_obs_z_mps"},      // vocabulary: old spelling
};

// Where `header` has column `name`, under its name or the one it had before the rename.
std::vector<std::string_view>::const_iterator find_column(
    const std::vector<std::string_view>& header, const std::string& name) {
  const auto it = std::find(header.begin(), header.end(), name);
  if (it != header.end()) return it;
  for (const auto& [renamed, before] : kColumnsRenamed) {
    if (renamed == name) return std::find(header.begin(), header.end(), before);
  }
  return header.end();
}

// A CSV of the recorder: '#' lines, then a header naming the columns, then rows. Calls
// `row(fields, where)` per row with the fields in the order of `columns`; returns false from
// `row` to report the row as unreadable. Columns from index `required` on are optional (added
// to the layout later): one the header lacks is named in absent_columns, has(i) is false for
// it and its field is empty.
class CsvFile {
 public:
  static constexpr std::size_t kAllRequired = std::numeric_limits<std::size_t>::max();

  CsvFile(Recording& recording, const std::string& name, std::vector<std::string> columns,
          bool last_field_is_text = false, std::size_t required = kAllRequired)
      : recording_(recording),
        name_(name),
        columns_(std::move(columns)),
        last_text_(last_field_is_text),
        required_(std::min(required, columns_.size())) {}

  /// Checks the stamp order of column 0 (StampOrder) and adds where the file starts.
  CsvFile& check_stamps(std::vector<std::pair<std::string, std::int64_t>>& starts) {
    starts_ = &starts;
    return *this;
  }

  [[nodiscard]] bool has(std::size_t column) const {
    return column < index_.size() && index_[column] != kAbsent;
  }

  template <typename Row>
  void read(Row row) {
    const fs::path path = fs::path(recording_.directory) / name_;
    std::ifstream in(path);
    if (!in) {
      add_problem(recording_, name_ + ": missing or unreadable");
      return;
    }
    std::string line;
    std::size_t line_number = 0;
    std::vector<std::size_t>& index = index_;
    index.clear();
    std::size_t header_fields = 0;
    std::vector<std::string_view> ordered(columns_.size());
    std::vector<std::pair<std::string, std::int64_t>> unused;
    StampOrder order((fs::path(recording_.directory) / name_).string(), columns_.front(),
                     starts_ != nullptr ? *starts_ : unused);
    while (std::getline(in, line)) {
      ++line_number;
      const std::string where = name_ + ":" + std::to_string(line_number);
      if (!line.empty() && line.back() == '\r') line.pop_back();
      if (line.empty() || line[0] == '#') continue;
      if (index.empty()) {
        const std::vector<std::string_view> header = split(line, 1000);
        header_fields = header.size();
        for (const std::string& c : columns_) {
          const auto it = find_column(header, c);
          if (it == header.end() && index.size() >= required_) {
            recording_.absent_columns.push_back(name_ + ": " + c);
            index.push_back(kAbsent);
            continue;
          }
          if (it == header.end()) {
            add_problem(recording_, where + ": header has no column " + c +
                                        " (not an hq-ground recording?); file skipped");
            return;
          }
          index.push_back(static_cast<std::size_t>(it - header.begin()));
        }
        continue;
      }
      const std::vector<std::string_view> fields = split(line, last_text_ ? header_fields : 1000);
      if (fields.size() != header_fields) {
        add_problem(recording_, where + ": expected " + std::to_string(header_fields) +
                                    " fields, got " + std::to_string(fields.size()) +
                                    (in.eof() ? " (truncated last line)" : ""));
        continue;
      }
      for (std::size_t i = 0; i < index.size(); ++i) {
        ordered[i] = index[i] == kAbsent ? std::string_view() : fields[index[i]];
      }
      std::string error;
      if (!row(ordered, error)) {
        add_problem(recording_, where + ": " + error);
        continue;
      }
      // Column 0 of every recorder CSV is its ground-clock stamp, parsed by `row` already.
      std::int64_t t_ns = 0;
      if (starts_ != nullptr && parse_stamp(ordered[0], t_ns)) order.check(t_ns, line_number);
    }
    if (index.empty()) add_problem(recording_, name_ + ": no header line");
  }

 private:
  Recording& recording_;
  std::string name_;
  static constexpr std::size_t kAbsent = std::numeric_limits<std::size_t>::max();
  std::vector<std::string> columns_;
  bool last_text_;
  std::size_t required_;
  std::vector<std::size_t> index_;
  std::vector<std::pair<std::string, std::int64_t>>* starts_ = nullptr;

  static bool parse_stamp(std::string_view text, std::int64_t& out) {
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
    return ec == std::errc{} && end == text.data() + text.size();
  }
};

template <typename T>
bool parse_integer(std::string_view text, T& out) {
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return ec == std::errc{} && end == text.data() + text.size();
}

// The vehicle session: 0x and 16 hex digits as the console writes it, or decimal (recordings
// before the console and the CSV said it alike).
bool parse_session_id(std::string_view text, std::uint64_t& out) {
  if (text.size() > 2 && text[0] == '0' && text[1] == 'x') {
    const auto [end, ec] = std::from_chars(text.data() + 2, text.data() + text.size(), out, 16);
    return ec == std::errc{} && end == text.data() + text.size();
  }
  return parse_integer(text, out);
}

bool parse_double(std::string_view text, double& out, bool allow_nan = false) {
  const std::string s(text);
  char* end = nullptr;
  errno = 0;
  out = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size() || errno == ERANGE) return false;
  return allow_nan || std::isfinite(out);
}

// Parses fields[first..first+n) as finite numbers into out; names the bad one in `error`.
template <std::size_t N>
bool parse_floats(const std::vector<std::string_view>& fields, std::size_t first,
                  const std::vector<std::string>& names, std::array<float, N>& out,
                  std::string& error) {
  for (std::size_t i = 0; i < N; ++i) {
    double v = 0;
    if (!parse_double(fields[first + i], v)) {
      error = names[first + i] + " = '" + std::string(fields[first + i]) +
              "', expected a finite number";
      return false;
    }
    out[i] = static_cast<float>(v);
  }
  return true;
}

bool known_name(std::string_view text) {
  return std::find(kNames.begin(), kNames.end() - 1, text) != kNames.end() - 1;
}

void read_frame_list(Recording& r, const std::string& name, std::vector<RecordedFrame>& out,
                     bool required, std::vector<std::pair<std::string, std::int64_t>>& starts) {
  StampOrder order((fs::path(r.directory) / name).string(), "timestamp", starts);
  const fs::path path = fs::path(r.directory) / name;
  std::ifstream in(path);
  if (!in) {
    if (required) add_problem(r, name + ": missing or unreadable");
    return;
  }
  std::string line;
  std::size_t line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ss(line);
    std::string stamp;
    std::string file;
    double t_s = 0;
    if (!(ss >> stamp >> file) || !parse_double(stamp, t_s)) {
      add_problem(r, name + ":" + std::to_string(line_number) +
                         ": expected \"timestamp filename\", got '" + line + "'");
      continue;
    }
    const fs::path frame = fs::path(r.directory) / file;
    if (!fs::exists(frame)) {
      add_problem(r, name + ":" + std::to_string(line_number) + ": " + file + " does not exist");
      continue;
    }
    if (!(std::abs(t_s) < 9e9)) {
      throw InputError(path.string() + ":" + std::to_string(line_number) +
                       ": timestamp = " + stamp + ", expected seconds since 1970 (below 9e9)");
    }
    const auto t_ns = static_cast<std::int64_t>(std::llround(t_s * 1e9));
    order.check(t_ns, line_number);
    out.push_back({t_ns, frame.string(), {}});
  }
}

std::int64_t monotonic_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec * 1'000'000'000LL + ts.tv_nsec;
}

}  // namespace

const char* intern(std::string_view text) {
  for (const char* name : kNames) {
    if (text == name) return name;
  }
  return kNames.back();
}

namespace {

using FileStarts = std::vector<std::pair<std::string, std::int64_t>>;  // "file:line", first stamp

const std::vector<std::string> kStateColumns = {
    "receipt_ns", "latency_us", "sequence", "t_ns", "v_H_x_mps", "v_H_y_mps", "v_H_z_mps",
    "omega_B_x_radps", "omega_B_y_radps", "omega_B_z_radps", "roll_rad", "pitch_rad",
    "v_obs_H_x_mps", "v_obs_H_y_mps", "v_obs_H_z_mps", "mode", "estimator_health", "link_health",
    // Optional from here: later layouts (older recordings lack them).
    "closest_obstacle_m", "position_valid", "p_W_x_m", "p_W_y_m", "p_W_z_m", "yaw_W_rad",
    "truth_valid", "v_truth_H_x_mps", "v_truth_H_y_mps", "v_truth_H_z_mps", "markers_n",
    "session_id", "commanding_station_id", "flight_state", "motors_armed", "height_source",
    "height_m", "operator_input", "v_cmd_flown_H_x_mps", "v_cmd_flown_H_y_mps",
    "v_cmd_flown_H_z_mps", "clearance_m", "hover_thrust_gain", "hover_thrust_converged",
    "position_invalid_reason", "position_age_s", "position_sigma_m", "modes_offered",
    "marker_mode_off_reason", "explore_mode_off_reason", "marker_target_valid", "marker_target_id",
    "explore_phase", "state_age_ms", "round_trip_ms",
    // The odometry's integrated pose (odom -> base_link) and the velocity's sigma.
    "odom_valid", "p_odom_x_m", "p_odom_y_m", "p_odom_z_m", "yaw_odom_rad", "odom_position_sigma_m",
    "odom_yaw_sigma_rad", "odom_yaw_relative_to_start", "v_H_sigma_x_mps", "v_H_sigma_y_mps",
    "v_H_sigma_z_mps"};
constexpr std::size_t kRequiredStateColumns = 18;

using Fields = std::vector<std::string_view>;

// Columns 0-17: every layout has them.
bool parse_state_core(const Fields& f, RecordedState& s, std::string& error) {
  double latency_us = 0;
  if (!parse_integer(f[0], s.receipt_ns)) {
    error = "receipt_ns = '" + std::string(f[0]) + "', expected an integer";
    return false;
  }
  if (!parse_double(f[1], latency_us) || !parse_integer(f[2], s.sequence) ||
      !parse_integer(f[3], s.vehicle_t_ns)) {
    error = "latency_us, sequence or t_ns is not a number";
    return false;
  }
  s.latency_ms = 1e-3 * latency_us;
  std::array<float, 11> values{};
  if (!parse_floats(f, 4, kStateColumns, values, error)) return false;
  s.v_H_mps = {values[0], values[1], values[2]};
  s.omega_B_radps = {values[3], values[4], values[5]};
  s.roll_rad = values[6];
  s.pitch_rad = values[7];
  s.v_obs_H_mps = {values[8], values[9], values[10]};
  for (std::size_t i = 15; i < 18; ++i) {
    if (!known_name(f[i])) {
      error = kStateColumns[i] + " = '" + std::string(f[i]) + "', expected a mode/health name";
      return false;
    }
  }
  s.mode = intern(f[15]);
  s.estimator_health = intern(f[16]);
  s.link_health = intern(f[17]);
  return true;
}

// Columns 18-28: cloud distance, marker pose, truth, marker count (each flag with its values:
// a layout has all of a group or none).
bool parse_state_pose_truth(const CsvFile& file, const Fields& f, RecordedState& s,
                            std::string& error) {
  s.closest_obstacle_m = std::numeric_limits<double>::quiet_NaN();
  if (file.has(18) && !parse_double(f[18], s.closest_obstacle_m, true)) {
    error = "closest_obstacle_m = '" + std::string(f[18]) + "', expected a number or nan";
    return false;
  }
  int flag = 0;
  if (file.has(19) && file.has(23)) {
    std::array<float, 4> pose{};
    if (!parse_integer(f[19], flag) || !parse_floats(f, 20, kStateColumns, pose, error)) {
      if (error.empty()) error = "position_valid = '" + std::string(f[19]) + "', expected 0/1";
      return false;
    }
    s.position_valid = flag != 0;
    s.p_W_m = {pose[0], pose[1], pose[2]};
    s.yaw_W_rad = pose[3];
  }
  if (file.has(24) && file.has(27)) {
    if (!parse_integer(f[24], flag) ||
        !parse_floats(f, 25, kStateColumns, s.v_truth_H_mps, error)) {
      if (error.empty()) error = "truth_valid = '" + std::string(f[24]) + "', expected 0/1";
      return false;
    }
    s.truth_valid = flag != 0;
  }
  if (file.has(28) && (!parse_integer(f[28], s.markers_n) || s.markers_n < 0)) {
    error = "markers_n = '" + std::string(f[28]) + "', expected a count";
    return false;
  }
  return true;
}

// Columns 29-39: the vehicle's flight fields.
bool parse_state_flight(const CsvFile& file, const Fields& f, RecordedState& s,
                        std::string& error) {
  if (!file.has(29) || !file.has(39)) return true;
  int armed = 0;
  double height = 0;
  double clearance = 0;
  const char* flight = intern_flight(f[31]);
  const char* source = intern_flight(f[33]);
  const char* input = intern_flight(f[35]);
  if (!parse_session_id(f[29], s.session_id) || !parse_integer(f[30], s.commanding_station_id) ||
      flight == nullptr || !parse_integer(f[32], armed) || source == nullptr ||
      !parse_double(f[34], height, true) || input == nullptr ||
      !parse_floats(f, 36, kStateColumns, s.v_cmd_flown_H_mps, error) ||
      !parse_double(f[39], clearance, true)) {
    if (error.empty()) error = "session_id .. clearance_m: a field is not a number or a known name";
    return false;
  }
  // A vehicle that does not fill them sends zeros: session 0 marks that.
  s.flight_fields = s.session_id != 0;
  if (!s.flight_fields) {
    s.v_cmd_flown_H_mps = {};
    return true;
  }
  s.flight_state = flight;
  s.motors_armed = armed;
  s.height_source = source;
  s.operator_input = input;
  if (std::string_view(source) != "none" && std::isfinite(height)) s.height_m = height;
  if (std::isfinite(clearance) && clearance >= 0) s.clearance_m = clearance;
  return true;
}

// Columns 40-41 (telemetry v2): the learnt hover thrust.
bool parse_state_thrust(const CsvFile& file, const Fields& f, RecordedState& s,
                        std::string& error) {
  if (!file.has(40) || !file.has(41)) return true;
  double gain = 0;
  int converged = 0;
  if (!parse_double(f[40], gain) || !parse_integer(f[41], converged)) {
    error = "hover_thrust_gain = '" + std::string(f[40]) + "', hover_thrust_converged = '" +
            std::string(f[41]) + "', expected a finite number and 0/1";
    return false;
  }
  s.hover_thrust_gain = static_cast<float>(gain);
  s.hover_thrust_converged = converged != 0;
  return true;
}

// Columns 42-44 (telemetry v2): why the position is invalid, its age and sigma (0: not said).
bool parse_state_position_validity(const CsvFile& file, const Fields& f, RecordedState& s,
                                   std::string& error) {
  if (!file.has(42) || !file.has(44)) return true;
  int reason = 0;
  std::array<float, 2> values{};
  if (!parse_integer(f[42], reason) || reason < 0 || reason > 255 ||
      !parse_floats(f, 43, kStateColumns, values, error)) {
    if (error.empty()) {
      error = "position_invalid_reason = '" + std::string(f[42]) + "', expected 0..255";
    }
    return false;
  }
  s.position_invalid_reason = static_cast<std::uint8_t>(reason);
  s.position_age_s = values[0];
  s.position_sigma_m = values[1];
  return true;
}

// Columns 45-47 (telemetry v3): the modes the vehicle offered and why marker and explore were
// off (0: not said).
bool parse_state_modes_offered(const CsvFile& file, const Fields& f, RecordedState& s,
                               std::string& error) {
  if (!file.has(45) || !file.has(47)) return true;
  if (!parse_integer(f[45], s.modes_offered) || s.modes_offered < 0 || s.modes_offered > 0x1F ||
      !parse_integer(f[46], s.marker_mode_off_reason) || s.marker_mode_off_reason < 0 ||
      s.marker_mode_off_reason > 255 || !parse_integer(f[47], s.explore_mode_off_reason) ||
      s.explore_mode_off_reason < 0 || s.explore_mode_off_reason > 255) {
    error = "modes_offered = '" + std::string(f[45]) + "', marker_mode_off_reason = '" +
            std::string(f[46]) + "', explore_mode_off_reason = '" + std::string(f[47]) +
            "', expected 0..31, 0..255, 0..255";
    return false;
  }
  return true;
}

// Columns 48-52 (telemetry v3): the marker target and explore phase the state carried, and the
// ground's link figures as the state arrived (0: unknown).
bool parse_state_target_and_link(const CsvFile& file, const Fields& f, RecordedState& s,
                                 std::string& error) {
  if (file.has(48) && file.has(50)) {
    int valid = 0;
    int id = 0;
    if (!parse_integer(f[48], valid) || !parse_integer(f[49], id) || id < 0 ||
        !parse_integer(f[50], s.explore_phase) || s.explore_phase < 0 || s.explore_phase > 7) {
      error = "marker_target_valid = '" + std::string(f[48]) + "', marker_target_id = '" +
              std::string(f[49]) + "', explore_phase = '" + std::string(f[50]) +
              "', expected 0/1, an id >= 0 and 0..7";
      return false;
    }
    s.marker_target_id = valid != 0 ? id : -1;
  }
  if (file.has(51) && file.has(52)) {
    std::array<float, 2> figures{};
    if (!parse_floats(f, 51, kStateColumns, figures, error) || figures[0] < 0 || figures[1] < 0) {
      if (error.empty())
        error = "state_age_ms or round_trip_ms negative, expected >= 0 (0: unknown)";
      return false;
    }
    s.state_age_ms = figures[0];
    s.round_trip_ms = figures[1];
  }
  return true;
}

// Columns 53-63 (telemetry v3; absent in older recordings): the odometry's integrated
// pose and the velocity's sigma.
bool parse_state_odom(const CsvFile& file, const Fields& f, RecordedState& s, std::string& error) {
  if (!file.has(53) || !file.has(63)) return true;
  int valid = 0;
  int relative = 0;
  std::array<float, 6> values{};
  if (!parse_integer(f[53], valid) || !parse_floats(f, 54, kStateColumns, values, error) ||
      !parse_integer(f[60], relative) ||
      !parse_floats(f, 61, kStateColumns, s.v_H_sigma_mps, error)) {
    if (error.empty()) {
      error = "odom_valid = '" + std::string(f[53]) + "', odom_yaw_relative_to_start = '" +
              std::string(f[60]) + "', expected 0/1";
    }
    return false;
  }
  s.odom_valid = valid != 0;
  s.p_odom_m = {values[0], values[1], values[2]};
  s.yaw_odom_rad = values[3];
  s.odom_position_sigma_m = values[4];
  s.odom_yaw_sigma_rad = values[5];
  s.odom_yaw_relative_to_start = relative != 0;
  return true;
}

void read_states(Recording& r, FileStarts& starts) {
  CsvFile telemetry(r, "telemetry.csv", kStateColumns, false, kRequiredStateColumns);
  telemetry.check_stamps(starts).read([&](const Fields& f, std::string& error) {
    RecordedState s;
    if (!parse_state_core(f, s, error) || !parse_state_pose_truth(telemetry, f, s, error) ||
        !parse_state_flight(telemetry, f, s, error) ||
        !parse_state_thrust(telemetry, f, s, error) ||
        !parse_state_position_validity(telemetry, f, s, error) ||
        !parse_state_modes_offered(telemetry, f, s, error) ||
        !parse_state_target_and_link(telemetry, f, s, error) ||
        !parse_state_odom(telemetry, f, s, error)) {
      return false;
    }
    r.states.push_back(s);
    return true;
  });
}

// The state a row of obstacles.csv or markers.csv belongs to: the one with its receipt_ns and
// sequence; null if none.
RecordedState* state_of(Recording& r, std::int64_t receipt_ns, std::uint64_t sequence) {
  const auto first =
      std::lower_bound(r.states.begin(), r.states.end(), receipt_ns,
                       [](const RecordedState& s, std::int64_t t) { return s.receipt_ns < t; });
  for (auto it = first; it != r.states.end() && it->receipt_ns == receipt_ns; ++it) {
    if (it->sequence == sequence) return &*it;
  }
  return nullptr;
}

// A file added to the layout later (telemetry v2): absent in older recordings, which replay
// without what it holds (named in absent_columns with what the replay lacks).
bool optional_file(Recording& r, const std::string& name, const char* lacking) {
  if (fs::exists(fs::path(r.directory) / name)) return true;
  r.absent_columns.push_back(name + " (the whole file: an older recording; " + lacking + ")");
  return false;
}

void read_obstacles(Recording& r) {
  if (!optional_file(r, "obstacles.csv", "replay shows no obstacle cloud")) return;
  const std::vector<std::string> columns = {"receipt_ns", "sequence", "p_B_x_m", "p_B_y_m",
                                            "p_B_z_m"};
  CsvFile(r, "obstacles.csv", columns).read([&](const Fields& f, std::string& error) {
    std::int64_t receipt_ns = 0;
    std::uint64_t sequence = 0;
    std::array<float, 3> p{};
    if (!parse_integer(f[0], receipt_ns) || !parse_integer(f[1], sequence)) {
      error = "receipt_ns or sequence is not an integer";
      return false;
    }
    if (!parse_floats(f, 2, columns, p, error)) return false;
    RecordedState* s = state_of(r, receipt_ns, sequence);
    if (s == nullptr) {
      error = "no state in telemetry.csv with receipt_ns " + std::string(f[0]) + " and sequence " +
              std::string(f[1]) + "; point skipped";
      return false;
    }
    if (s->obstacle_points_B_m.size() >= hq_msgs_kMaxObstaclePoints) {
      error = "more than " + std::to_string(hq_msgs_kMaxObstaclePoints) +
              " points for one state (the link's bound); point skipped";
      return false;
    }
    s->obstacle_points_B_m.push_back(p);
    return true;
  });
}

void read_markers(Recording& r) {
  if (!optional_file(r, "markers.csv", "replay shows marker counts, not their poses")) return;
  const std::vector<std::string> columns = {"receipt_ns", "sequence", "id",    "p_C_x_m", "p_C_y_m",
                                            "p_C_z_m",    "q_C_w",    "q_C_x", "q_C_y",   "q_C_z"};
  CsvFile(r, "markers.csv", columns).read([&](const Fields& f, std::string& error) {
    std::int64_t receipt_ns = 0;
    std::uint64_t sequence = 0;
    MarkerView m;
    std::array<float, 7> pose{};
    if (!parse_integer(f[0], receipt_ns) || !parse_integer(f[1], sequence) ||
        !parse_integer(f[2], m.id)) {
      error = "receipt_ns, sequence or id is not an integer";
      return false;
    }
    if (!parse_floats(f, 3, columns, pose, error)) return false;
    m.p_camera_marker_m = {pose[0], pose[1], pose[2]};
    m.q_camera_marker = {pose[3], pose[4], pose[5], pose[6]};
    RecordedState* s = state_of(r, receipt_ns, sequence);
    if (s == nullptr) {
      error = "no state in telemetry.csv with receipt_ns " + std::string(f[0]) + " and sequence " +
              std::string(f[1]) + "; marker skipped";
      return false;
    }
    if (s->markers.size() >= kMaxMarkerViews) {
      error = "more than " + std::to_string(kMaxMarkerViews) + " markers for one state; skipped";
      return false;
    }
    s->markers.push_back(m);
    return true;
  });
}

void read_commands(Recording& r, FileStarts& starts) {
  const std::vector<std::string> columns = {"t_ns",      "v_H_x_mps",      "v_H_y_mps",
                                            "v_H_z_mps", "yaw_rate_radps", "valid"};
  CsvFile(r, "commands.csv", columns)
      .check_stamps(starts)
      .read([&](const Fields& f, std::string& error) {
        RecordedCommand c;
        int valid = 0;
        if (!parse_integer(f[0], c.t_ns) || !parse_integer(f[5], valid)) {
          error = "t_ns or valid is not an integer";
          return false;
        }
        std::array<float, 4> v{};
        if (!parse_floats(f, 1, columns, v, error)) return false;
        c.v_H_mps = {v[0], v[1], v[2]};
        c.yaw_rate_radps = v[3];
        c.valid = valid != 0;
        r.commands.push_back(c);
        return true;
      });
}

void read_mode_requests(Recording& r, FileStarts& starts) {
  CsvFile(r, "mode_requests.csv", {"t_ns", "mode"})
      .check_stamps(starts)
      .read([&](const Fields& f, std::string& error) {
        RecordedModeRequest m;
        if (!parse_integer(f[0], m.t_ns) || !known_name(f[1])) {
          error = "expected \"t_ns,mode\"";
          return false;
        }
        m.mode = intern(f[1]);
        r.mode_requests.push_back(m);
        return true;
      });
}

void read_events(Recording& r, FileStarts& starts) {
  CsvFile events(r, "events.csv", {"receipt_ns", "severity", "text", "code"}, true, 3);
  events.check_stamps(starts).read([&](const Fields& f, std::string& error) {
    RecordedEvent e;
    if (!parse_integer(f[0], e.receipt_ns) || !parse_integer(f[1], e.severity) ||
        (events.has(3) && !parse_integer(f[3], e.code))) {
      error = "receipt_ns, severity or code is not an integer";
      return false;
    }
    std::string_view text = f[2];
    if (text.size() >= 2 && text.front() == '"' && text.back() == '"') {
      text = text.substr(1, text.size() - 2);
    }
    e.text = text;
    r.events.push_back(std::move(e));
    return true;
  });
}

// Each file is in order; a file that starts far from the others (one garbled row alone in it)
// would still stretch the merged timeline.
void check_file_starts(const FileStarts& starts) {
  const auto [earliest, latest] =
      std::minmax_element(starts.begin(), starts.end(),
                          [](const auto& a, const auto& b) { return a.second < b.second; });
  if (earliest != starts.end() && latest->second - earliest->second > kMaxStampGapNs) {
    throw InputError(latest->first + ": first stamp " + std::to_string(latest->second) + " is " +
                     seconds_text(latest->second - earliest->second) + " after " +
                     fs::path(earliest->first).filename().string() + "'s " +
                     std::to_string(earliest->second) +
                     ", expected the files of one recording to start within " +
                     seconds_text(kMaxStampGapNs) + " (a garbled stamp?)");
  }
}

bool has_csv_recording(const std::string& directory) {
  return fs::exists(fs::path(directory) / "telemetry.csv") ||
         fs::exists(fs::path(directory) / "rgb.txt");
}

Recording load_csv_recording(const std::string& directory) {
  Recording r;
  r.directory = directory;
  FileStarts starts;
  read_states(r, starts);
  read_obstacles(r);
  read_markers(r);
  read_commands(r, starts);
  read_mode_requests(r, starts);
  read_events(r, starts);
  read_frame_list(r, "rgb.txt", r.rgb, true, starts);
  read_frame_list(r, "depth_preview.txt", r.depth_preview, false, starts);
  check_file_starts(starts);
  return r;
}

// A folder's flight.mcap, or its CSV files when the MCAP is unreadable or empty of states
// (a recorder that failed early): the CSV recorder ran beside it.
Recording load_folder_mcap(const std::string& directory, const std::string& mcap_path) {
  std::string why;
  try {
    Recording r = load_mcap_recording(mcap_path);
    if (!r.states.empty() || !has_csv_recording(directory)) return r;
    why = "holds no vehicle state";
  } catch (const InputError& e) {
    if (!has_csv_recording(directory)) throw;
    why = std::string("unreadable (") + e.what() + ")";
  }
  Recording r = load_csv_recording(directory);
  add_problem(r, "flight.mcap " + why + "; the CSV files were read instead");
  return r;
}

}  // namespace

std::string find_flight_mcap(const std::string& path) {
  if (fs::is_regular_file(path)) return path;
  const fs::path in_folder = fs::path(path) / "flight.mcap";
  return fs::is_directory(path) && fs::exists(in_folder) ? in_folder.string() : "";
}

Recording load_recording(const std::string& path) {
  if (fs::is_regular_file(path)) {
    if (!is_mcap_file(path)) {
      throw InputError(path +
                       ": not an MCAP file (no MCAP magic), expected a flight.mcap or a "
                       "recording folder written by hq-ground --record");
    }
    return load_mcap_recording(path);
  }
  if (!fs::is_directory(path)) {
    throw InputError(path +
                     ": not found, expected a recording folder written by hq-ground "
                     "--record (or its flight.mcap)");
  }
  const std::string mcap_path = find_flight_mcap(path);
  if (!mcap_path.empty()) return load_folder_mcap(path, mcap_path);
  if (!has_csv_recording(path)) {
    throw InputError(path +
                     ": neither flight.mcap, telemetry.csv nor rgb.txt: not an hq-ground "
                     "recording");
  }
  return load_csv_recording(path);
}

bool replay(const Recording& recording, ConsoleModel& model, double speed,
            const std::atomic<bool>& stop, std::atomic<std::uint64_t>& frames_missing) {
  // Straight through on the player, in steps of 20 ms of wall time.
  ReplayPlayer player(recording);
  player.set_speed(speed);
  player.play();
  std::uint64_t missing = 0;
  std::int64_t last_ns = monotonic_ns();
  while (!stop.load()) {
    const std::int64_t now_ns = monotonic_ns();
    player.advance(1e-9 * static_cast<double>(now_ns - last_ns));
    last_ns = now_ns;
    player.feed(model, missing);
    frames_missing.store(missing);
    if (player.at_end()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return false;
}

}  // namespace hq::console
