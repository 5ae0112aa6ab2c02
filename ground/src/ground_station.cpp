#include "hq/ground/ground_station.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/base/quantile.hpp"
#include "hq/link/state_figures.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fmt/format.h>
#include <limits>
#include <random>
#include <sys/stat.h>
#include <system_error>
#include <time.h>
#include <unistd.h>
#include <utility>

namespace hq::ground {

std::optional<hq_msgs_Mode> ModeToggle::on_buttons(std::uint32_t buttons,
                                                   hq_msgs_Mode vehicle_mode) {
  const std::uint32_t pressed = buttons & ~previous_;
  previous_ = buttons;
  if ((pressed & 0x2U) != 0) return hq_msgs_MODE_LAND;  // landing wins over a toggle
  if ((pressed & 0x1U) != 0) {
    return vehicle_mode == hq_msgs_MODE_TELEOP ? hq_msgs_MODE_HOVER : hq_msgs_MODE_TELEOP;
  }
  return std::nullopt;
}

const char* to_string(hq_msgs_Mode mode) {
  switch (static_cast<int>(mode)) {
    case hq_msgs_MODE_TELEOP:
      return "teleop";
    case hq_msgs_MODE_HOVER:
      return "hover";
    case hq_msgs_MODE_LAND:
      return "land";
    case hq_msgs_MODE_MARKER:
      return "marker";
    case hq_msgs_MODE_EXPLORE:
      return "explore";
    default:
      return "invalid";
  }
}

const char* to_string(hq_msgs_Health health) {
  switch (static_cast<int>(health)) {
    case hq_msgs_HEALTH_OK:
      return "ok";
    case hq_msgs_HEALTH_DEGRADED:
      return "degraded";
    case hq_msgs_HEALTH_LOST:
      return "lost";
    default:
      return "invalid";
  }
}

namespace {

double norm(const hq_msgs_Vector3f& v) {
  const auto x = static_cast<double>(v.x);
  const auto y = static_cast<double>(v.y);
  const auto z = static_cast<double>(v.z);
  return std::sqrt(x * x + y * y + z * z);
}

// |x| of a link field (float) against a double bound.
double magnitude(float x) { return std::abs(static_cast<double>(x)); }

// A link field (float) widened to double, as the CSV rows have always printed it.
double as_double(float x) { return static_cast<double>(x); }

// fmt::print reports a failed write by throwing std::system_error; a recorder row reports it as
// fprintf did, a negative result with errno set, so written() names the file and stops the
// recording instead of the station.
template <typename... Args>
int print_row(std::FILE* file, fmt::format_string<Args...> format, Args&&... args) {
  try {
    fmt::print(file, format, std::forward<Args>(args)...);
    return 0;
  } catch (const std::system_error& e) {
    errno = e.code().value();
    return -1;
  }
}

}  // namespace

link::Validation plausible(const link::VehicleState& s) {
  // Compared with !(x <= bound) so that a NaN (validate() lets none through, but this function
  // stands alone) fails too.
  if (!(norm(s.v_H_mps) <= kMaxPlausibleSpeedMps)) return {false, "v_H_mps beyond 20 m/s"};
  if (!(norm(s.v_obs_H_mps) <= kMaxPlausibleSpeedMps)) return {false, "v_obs_H_mps beyond 20 m/s"};
  if (!(norm(s.v_cmd_flown_H_mps) <= kMaxPlausibleSpeedMps)) {
    return {false, "v_cmd_flown_H_mps beyond 20 m/s"};
  }
  if (!(norm(s.v_truth_H_mps) <= kMaxPlausibleSpeedMps)) {
    return {false, "v_truth_H_mps beyond 20 m/s"};
  }
  if (!(norm(s.omega_B_radps) <= kMaxPlausibleRateRadps)) {
    return {false, "omega_B_radps beyond 35 rad/s"};
  }
  if (!(magnitude(s.roll_rad) < M_PI) || !(magnitude(s.pitch_rad) < M_PI)) {
    return {false, "roll_rad or pitch_rad outside (-pi, pi)"};
  }
  if (!(magnitude(s.yaw_W_rad) <= 2.0 * M_PI)) return {false, "yaw_W_rad outside [-2 pi, 2 pi]"};
  if (!(magnitude(s.height_m) <= kMaxPlausibleHeightM)) return {false, "height_m beyond 1000 m"};
  if (!(magnitude(s.clearance_m) <= kMaxPlausibleDistanceM)) {
    return {false, "clearance_m not finite or beyond 100 km"};
  }
  if (!(norm(s.p_W_m) <= kMaxPlausibleDistanceM)) return {false, "p_W_m beyond 100 km"};
  if (s.markers._length > hq_msgs_kMaxMarkersInState) {
    return {false, "markers longer than kMaxMarkersInState"};
  }
  return {true, ""};
}

void LatencyStats::add(std::int64_t latency_ns) {
  const std::int64_t bin = std::clamp<std::int64_t>(latency_ns / bin_ns_, 0,
                                                    static_cast<std::int64_t>(bins_.size()) - 1);
  ++bins_[static_cast<std::size_t>(bin)];
  ++count_;
}

double LatencyStats::quantile_ms(double q) const {
  if (count_ == 0) return 0.0;
  // The upper edge of the bin; the last bin's when the quantile lies beyond the range.
  const std::size_t b = histogram_quantile_bin(bins_, count_, q);
  return 1e-6 * static_cast<double>(bin_ns_) * static_cast<double>(std::min(b + 1, bins_.size()));
}

namespace {

// "x": never truncates a file already there (another recording's).
std::FILE* open_for_writing(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "wx");
  if (f == nullptr && errno == EEXIST) {
    throw InputError("--record " + path +
                     ": exists; refusing to overwrite a recording, "
                     "expected a new folder");
  }
  if (f == nullptr) throw InputError(path + ": cannot open for writing: " + std::strerror(errno));
  return f;
}

void make_directory(const std::string& path) {
  if (mkdir(path.c_str(), 0755) != 0 && errno != EEXIST) {
    throw InputError("--record " + path + ": cannot create directory: " + std::strerror(errno));
  }
}

// Names of the link's flight enums as recorded (hq::console::load_recording reads them back);
// a value the recorder does not know (a newer vehicle) goes out as "unknown".
const char* flight_state_name(hq_msgs_FlightState v) {
  switch (v) {
    case hq_msgs_FLIGHT_LANDED:
      return "landed";
    case hq_msgs_FLIGHT_TAKING_OFF:
      return "taking_off";
    case hq_msgs_FLIGHT_AIRBORNE:
      return "airborne";
    case hq_msgs_FLIGHT_LANDING:
      return "landing";
  }
  return "unknown";
}

const char* height_source_name(hq_msgs_HeightSource v) {
  switch (v) {
    case hq_msgs_HEIGHT_NONE:
      return "none";
    case hq_msgs_HEIGHT_DEPTH:
      return "depth";
    case hq_msgs_HEIGHT_ESTIMATE:
      return "estimate";
  }
  return "unknown";
}

const char* operator_input_name(hq_msgs_OperatorInput v) {
  switch (v) {
    case hq_msgs_INPUT_FLOWN:
      return "flown";
    case hq_msgs_INPUT_NONE:
      return "none";
    case hq_msgs_INPUT_IGNORED_MODE:
      return "ignored_mode";
    case hq_msgs_INPUT_IGNORED_LANDED:
      return "ignored_landed";
    case hq_msgs_INPUT_IGNORED_NOT_OWNER:
      return "ignored_not_owner";
    case hq_msgs_INPUT_IGNORED_FAILSAFE:
      return "ignored_failsafe";
    case hq_msgs_INPUT_LIMITED_UNSEEN:
      return "limited_unseen";
    case hq_msgs_INPUT_LIMITED_ENVELOPE:
      return "limited_envelope";
  }
  return "unknown";
}

// The files' heads: the '#' lines naming frames, clocks and units, then the columns.
constexpr const char* kTelemetryHeader =
    "# hq-ground telemetry v3: one row per vehicle state received (v2 added the hover\n"
    "# thrust columns, v3 the modes offered, marker target, explore phase, the ground's\n"
    "# link figures and the odometry's integrated pose; the cloud and marker poses are in\n"
    "# obstacles.csv and markers.csv).\n"
    "# receipt_ns: ground clock (dds_time, ns); latency_us: source stamp to receipt;\n"
    "# t_ns: vehicle stamp; v_H: estimated velocity in H, the horizontal NED frame of\n"
    "# eq. 5 of the core paper (x forward along the heading, y right, z down), m/s;\n"
    "# omega: body gyro rates (FRD), rad/s; v_obs_H: obstacle repulsion in H, m/s;\n"
    "# closest_obstacle_m: nearest point of the sent cloud (nan: no cloud).\n"
    "# position_valid 1: p_W (m) and yaw_W (rad) are the marker filter's pose in the\n"
    "# marker map's world frame W (NED); 0: no anchored pose (values meaningless).\n"
    "# truth_valid 1: v_truth_H is the simulator's true velocity in H (m/s); 0: a\n"
    "# real vehicle, no truth. markers_n: markers detected in the state's frame.\n"
    "# session_id: the vehicle process's session, hex as the console says it (new: restart);\n"
    "# commanding_station_id: the station it obeys (0 none); flight_state, motors_armed;\n"
    "# height_m above the floor from height_source (none: meaningless);\n"
    "# operator_input: what the vehicle did with the command; v_cmd_flown_H: the\n"
    "# command as flown (m/s); clearance_m: the vehicle's closest obstacle clearance\n"
    "# (m, < 0: none seen); hover_thrust_gain: thrust given over commanded, learnt in "
    "flight (0: not reported), hover_thrust_converged 1 once learnt;\n"
    "# position_invalid_reason: why position_valid is 0 (0 valid or not said, 1 no marker "
    "seen yet, 2 no marker for too long, 3 uncertainty over its bound, 4 markers disagree), "
    "position_age_s since the last marker, position_sigma_m (m) 1-sigma.\n"
    "# modes_offered: the modes the vehicle offers, bit per mode (1 teleop, 2 hover, 4 land,\n"
    "# 8 marker, 16 explore; 0 not said); marker_mode_off_reason, explore_mode_off_reason: why\n"
    "# not offered (0 offered or not said, 1 markers.enabled: false in the vehicle's config).\n"
    "# marker_target_valid 1: marker_target_id is the marker the marker or explore mode flies\n"
    "# to; explore_phase 0 not exploring, 1 lift-off 2 search 3 explore 4 edge 5 navigate 6 land\n"
    "# 7 done; state_age_ms: the state's age at receipt through the clock offset, round_trip_ms:\n"
    "# the latest heartbeat round trip, both as the ground measured them (0: unknown).\n"
    "# odom_valid 1: p_odom (m) and yaw_odom (rad) are the odometry's integrated pose in the "
    "odom frame (origin and heading of the start, x forward, y right, z down), "
    "odom_position_sigma_m and odom_yaw_sigma_rad its 1-sigma, odom_yaw_relative_to_start 1: "
    "the world heading unknown; v_H_sigma: the estimated velocity's 1-sigma (m/s).\n"
    "receipt_ns,latency_us,sequence,t_ns,v_H_x_mps,v_H_y_mps,v_H_z_mps,"
    "omega_B_x_radps,omega_B_y_radps,omega_B_z_radps,roll_rad,pitch_rad,v_obs_H_x_mps,"
    "v_obs_H_y_mps,v_obs_H_z_mps,mode,estimator_health,link_health,vehicle_id,"
    "closest_obstacle_m,position_valid,p_W_x_m,p_W_y_m,p_W_z_m,yaw_W_rad,"
    "truth_valid,v_truth_H_x_mps,v_truth_H_y_mps,v_truth_H_z_mps,markers_n,"
    "session_id,commanding_station_id,flight_state,motors_armed,height_source,height_m,"
    "operator_input,v_cmd_flown_H_x_mps,v_cmd_flown_H_y_mps,v_cmd_flown_H_z_mps,"
    "clearance_m,hover_thrust_gain,hover_thrust_converged,position_invalid_reason,"
    "position_age_s,position_sigma_m,modes_offered,marker_mode_off_reason,"
    "explore_mode_off_reason,marker_target_valid,marker_target_id,explore_phase,state_age_ms,"
    "round_trip_ms,"
    "odom_valid,p_odom_x_m,p_odom_y_m,p_odom_z_m,yaw_odom_rad,"
    "odom_position_sigma_m,odom_yaw_sigma_rad,odom_yaw_relative_to_start,v_H_sigma_x_mps,"
    "v_H_sigma_y_mps,v_H_sigma_z_mps\n";
constexpr const char* kObstaclesHeader =
    "# hq-ground obstacles v1: the obstacle cloud a vehicle state carried, one row per point\n"
    "# (states without a cloud have none). receipt_ns and sequence: its state's row in\n"
    "# telemetry.csv; p_B: the point in the body frame B (FRD), m.\n"
    "receipt_ns,sequence,p_B_x_m,p_B_y_m,p_B_z_m\n";
constexpr const char* kMarkersHeader =
    "# hq-ground markers v1: the markers a vehicle state reported, one row per marker.\n"
    "# receipt_ns and sequence: its state's row in telemetry.csv; id: AprilTag 36h11 id;\n"
    "# p_C, q_C: the marker's pose in the camera frame C (optical: x right, y down, z\n"
    "# forward), m, unit quaternion w x y z.\n"
    "receipt_ns,sequence,id,p_C_x_m,p_C_y_m,p_C_z_m,q_C_w,q_C_x,q_C_y,q_C_z\n";
constexpr const char* kEventsHeader =
    "# hq-ground events v1: receipt_ns ground clock (ns), t_ns vehicle stamp (ns),\n"
    "# severity 0 info 1 warning 2 error.\n"
    "receipt_ns,sequence,t_ns,severity,code,text\n";
constexpr const char* kCommandsHeader =
    "# hq-ground commands v1: one row per velocity command sent (eqs. 6-10 of the core\n"
    "# paper). t_ns: ground clock (dds_time, ns); v_H: desired velocity in H (NED,\n"
    "# m/s); yaw_rate: desired yaw rate (rad/s, + turns right); valid 0: zero sent.\n"
    "t_ns,v_H_x_mps,v_H_y_mps,v_H_z_mps,yaw_rate_radps,valid\n";
constexpr const char* kModesHeader =
    "# hq-ground mode requests v1: t_ns ground clock (dds_time, ns).\n"
    "t_ns,mode\n";
constexpr const char* kRgbListHeader =
    "# color images (JPEG as received)\n"
    "# timestamp filename (timestamp: receipt on the ground clock, s)\n";
constexpr const char* kDepthListHeader =
    "# depth colour-map previews (not metric depth)\n"
    "# timestamp filename (timestamp: receipt on the ground clock, s)\n";

}  // namespace

TelemetryRecorder::TelemetryRecorder(const std::string& directory) : directory_(directory) {
  for (const char* name : {"telemetry.csv", "rgb.txt"}) {
    if (access((directory + "/" + name).c_str(), F_OK) == 0) {
      throw InputError("--record " + directory + ": already holds a recording (" + name +
                       "); refusing to overwrite it, expected a new folder");
    }
  }
  make_directory(directory);
  make_directory(directory + "/rgb");
  make_directory(directory + "/depth_preview");
  // Opened one by one; a later failure closes the earlier files in the destructor's order.
  struct Closer {
    TelemetryRecorder* r;
    bool armed = true;
    ~Closer() {
      if (!armed) return;
      for (std::FILE* f : {r->telemetry_, r->events_, r->commands_, r->modes_, r->rgb_list_,
                           r->depth_list_, r->obstacles_, r->markers_}) {
        if (f != nullptr) std::fclose(f);
      }
    }
  } closer{this};
  telemetry_ = open_for_writing(directory + "/telemetry.csv");
  events_ = open_for_writing(directory + "/events.csv");
  commands_ = open_for_writing(directory + "/commands.csv");
  modes_ = open_for_writing(directory + "/mode_requests.csv");
  rgb_list_ = open_for_writing(directory + "/rgb.txt");
  depth_list_ = open_for_writing(directory + "/depth_preview.txt");
  obstacles_ = open_for_writing(directory + "/obstacles.csv");
  markers_ = open_for_writing(directory + "/markers.csv");
  closer.armed = false;
  written(std::fputs(kTelemetryHeader, telemetry_), "telemetry.csv");
  written(std::fputs(kEventsHeader, events_), "events.csv");
  written(std::fputs(kCommandsHeader, commands_), "commands.csv");
  written(std::fputs(kModesHeader, modes_), "mode_requests.csv");
  written(std::fputs(kRgbListHeader, rgb_list_), "rgb.txt");
  written(std::fputs(kDepthListHeader, depth_list_), "depth_preview.txt");
  written(std::fputs(kObstaclesHeader, obstacles_), "obstacles.csv");
  written(std::fputs(kMarkersHeader, markers_), "markers.csv");
  path_.reserve(directory.size() + 64);
}

TelemetryRecorder::~TelemetryRecorder() { close(); }

void TelemetryRecorder::written(int result, const char* file) {
  if (result >= 0 || !error_.empty()) return;
  error_ = directory_ + "/" + file + ": write failed: " + std::strerror(errno) +
           "; the recording stops here (disk full?)";
}

bool TelemetryRecorder::flush() {
  if (!error_.empty() || telemetry_ == nullptr) return error_.empty();
  written(std::fflush(telemetry_), "telemetry.csv");
  written(std::fflush(events_), "events.csv");
  written(std::fflush(commands_), "commands.csv");
  written(std::fflush(modes_), "mode_requests.csv");
  written(std::fflush(rgb_list_), "rgb.txt");
  written(std::fflush(depth_list_), "depth_preview.txt");
  written(std::fflush(obstacles_), "obstacles.csv");
  written(std::fflush(markers_), "markers.csv");
  return error_.empty();
}

bool TelemetryRecorder::close() {
  if (telemetry_ == nullptr) return error_.empty();
  // fclose writes what is buffered: its result is the last word on whether the data landed.
  written(std::fclose(telemetry_), "telemetry.csv");
  written(std::fclose(events_), "events.csv");
  written(std::fclose(commands_), "commands.csv");
  written(std::fclose(modes_), "mode_requests.csv");
  written(std::fclose(rgb_list_), "rgb.txt");
  written(std::fclose(depth_list_), "depth_preview.txt");
  written(std::fclose(obstacles_), "obstacles.csv");
  written(std::fclose(markers_), "markers.csv");
  telemetry_ = events_ = commands_ = modes_ = rgb_list_ = depth_list_ = obstacles_ = markers_ =
      nullptr;
  return error_.empty();
}

void TelemetryRecorder::state(std::int64_t receipt_ns, std::int64_t latency_ns,
                              const link::VehicleState& s, std::int64_t state_age_ns,
                              std::int64_t round_trip_ns) {
  // As the live console takes them (hq-ground's ModelFeed): unknown reads as 0.
  const auto ms = [](std::int64_t ns) {
    return 1e-6 * static_cast<double>(std::max<std::int64_t>(ns, 0));
  };
  if (!error_.empty() || telemetry_ == nullptr) return;
  written(
      print_row(
          telemetry_,
          "{},{:.1f},{},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:"
          ".4f},{},{},{},{},{:.3f},{},{:.4f},{:.4f},{:.4f},{:.4f},{},{:.4f},{:.4f},{:.4f},{},0x{:"
          "016x},{},{},{},{},{:.4f},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{},{},{:.3f},{:.4f},{},{}"
          ",{},{},{},{},{:.3f},{:.3f},{},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{:.4f},{},{:.4f},{:.4f}"
          ",{:.4f}\n",
          static_cast<long long>(receipt_ns), 1e-3 * static_cast<double>(latency_ns),
          static_cast<unsigned long long>(s.sequence_number), static_cast<long long>(s.t_ns),
          as_double(s.v_H_mps.x), as_double(s.v_H_mps.y), as_double(s.v_H_mps.z),
          as_double(s.omega_B_radps.x), as_double(s.omega_B_radps.y), as_double(s.omega_B_radps.z),
          as_double(s.roll_rad), as_double(s.pitch_rad), as_double(s.v_obs_H_mps.x),
          as_double(s.v_obs_H_mps.y), as_double(s.v_obs_H_mps.z), to_string(s.mode),
          to_string(s.estimator_health), to_string(s.link_health), s.vehicle_id,
          link::closest_cloud_point_m(s), s.position_valid ? 1 : 0, as_double(s.p_W_m.x),
          as_double(s.p_W_m.y), as_double(s.p_W_m.z), as_double(s.yaw_W_rad), s.truth_valid ? 1 : 0,
          as_double(s.v_truth_H_mps.x), as_double(s.v_truth_H_mps.y), as_double(s.v_truth_H_mps.z),
          s.markers._length, static_cast<unsigned long long>(s.session_id), s.commanding_station_id,
          flight_state_name(s.flight_state), s.motors_armed ? 1 : 0,
          height_source_name(s.height_source), as_double(s.height_m),
          operator_input_name(s.operator_input), as_double(s.v_cmd_flown_H_mps.x),
          as_double(s.v_cmd_flown_H_mps.y), as_double(s.v_cmd_flown_H_mps.z),
          as_double(s.clearance_m), as_double(s.hover_thrust_gain),
          s.hover_thrust_converged ? 1 : 0, static_cast<unsigned>(s.position_invalid_reason),
          as_double(s.position_age_s), as_double(s.position_sigma_m),
          static_cast<unsigned>(s.modes_offered), static_cast<unsigned>(s.marker_mode_off_reason),
          static_cast<unsigned>(s.explore_mode_off_reason), s.marker_target_valid ? 1 : 0,
          static_cast<int>(s.marker_target_id), static_cast<unsigned>(s.explore_phase),
          ms(state_age_ns), ms(round_trip_ns), s.odom_valid ? 1 : 0, as_double(s.p_odom_m.x),
          as_double(s.p_odom_m.y), as_double(s.p_odom_m.z), as_double(s.yaw_odom_rad),
          as_double(s.odom_position_sigma_m), as_double(s.odom_yaw_sigma_rad),
          s.odom_yaw_relative_to_start ? 1 : 0, as_double(s.v_H_sigma_mps.x),
          as_double(s.v_H_sigma_mps.y), as_double(s.v_H_sigma_mps.z)),
      "telemetry.csv");
  for (std::uint32_t i = 0; i < s.obstacle_points_B_m._length; ++i) {
    const hq_msgs_Vector3f& p = s.obstacle_points_B_m._buffer[i];
    written(
        print_row(obstacles_, "{},{},{:.4f},{:.4f},{:.4f}\n", static_cast<long long>(receipt_ns),
                  static_cast<unsigned long long>(s.sequence_number), as_double(p.x),
                  as_double(p.y), as_double(p.z)),
        "obstacles.csv");
  }
  for (std::uint32_t i = 0; i < s.markers._length; ++i) {
    const hq_msgs_MarkerInCamera& m = s.markers._buffer[i];
    written(print_row(markers_, "{},{},{},{:.4f},{:.4f},{:.4f},{:.5f},{:.5f},{:.5f},{:.5f}\n",
                      static_cast<long long>(receipt_ns),
                      static_cast<unsigned long long>(s.sequence_number), static_cast<int>(m.id),
                      as_double(m.p_camera_marker_m.x), as_double(m.p_camera_marker_m.y),
                      as_double(m.p_camera_marker_m.z), as_double(m.q_camera_marker.w),
                      as_double(m.q_camera_marker.x), as_double(m.q_camera_marker.y),
                      as_double(m.q_camera_marker.z)),
            "markers.csv");
  }
}

void TelemetryRecorder::command(std::int64_t t_ns, const haptics::VelocityCommand& command,
                                bool valid) {
  if (!error_.empty() || commands_ == nullptr) return;
  const Eigen::Vector3d v = valid ? command.v_H_mps : Eigen::Vector3d::Zero();
  written(print_row(commands_, "{},{:.4f},{:.4f},{:.4f},{:.4f},{}\n", static_cast<long long>(t_ns),
                    v.x(), v.y(), v.z(), valid ? command.yaw_rate_radps : 0.0, valid ? 1 : 0),
          "commands.csv");
}

void TelemetryRecorder::mode_request(std::int64_t t_ns, hq_msgs_Mode mode) {
  if (!error_.empty() || modes_ == nullptr) return;
  written(print_row(modes_, "{},{}\n", static_cast<long long>(t_ns), to_string(mode)),
          "mode_requests.csv");
  written(std::fflush(modes_), "mode_requests.csv");
}

void TelemetryRecorder::camera(std::int64_t receipt_ns, const link::CameraFrame& frame) {
  if (!error_.empty() || rgb_list_ == nullptr) return;
  const auto write_file = [&](const char* folder, const char* extension,
                              const dds_sequence_octet& bytes, std::FILE* list) {
    char name[64];
    hq::format_into(name, "{}/{:.6f}.{}", folder, 1e-9 * static_cast<double>(receipt_ns),
                    extension);
    path_.assign(directory_).append("/").append(name);
    std::FILE* f = std::fopen(path_.c_str(), "wb");
    const bool complete =
        f != nullptr && std::fwrite(bytes._buffer, 1, bytes._length, f) == bytes._length;
    const int saved_errno = errno;
    const bool closed = f != nullptr && std::fclose(f) == 0;
    if (!complete || !closed) {
      ++frame_write_failures_;
      // No space (or quota) is the recording's end, not one lost frame: say so.
      const int e = complete ? errno : saved_errno;
      if (e == ENOSPC || e == EDQUOT || e == EFBIG) {
        errno = e;
        written(-1, name);
      }
    } else {
      written(print_row(list, "{:.6f} {}\n", 1e-9 * static_cast<double>(receipt_ns), name),
              list == rgb_list_ ? "rgb.txt" : "depth_preview.txt");
    }
  };
  if (frame.rgb_jpeg._length > 0) write_file("rgb", "jpg", frame.rgb_jpeg, rgb_list_);
  if (frame.depth_preview._length > 0) {
    // PNG or JPEG by its magic number (the message allows either).
    const bool png = frame.depth_preview._length > 4 && frame.depth_preview._buffer[0] == 0x89;
    write_file("depth_preview", png ? "png" : "jpg", frame.depth_preview, depth_list_);
  }
}

void TelemetryRecorder::event(std::int64_t receipt_ns, const link::Event& e) {
  // Quotes in the text would break the CSV field; the vehicle's texts have none, a hostile
  // sender's are replaced.
  char text[sizeof e.text];
  hq::format_into(text, "{}", e.text);
  for (char& c : text) {
    if (c == '"') c = '\'';
  }
  if (!error_.empty() || events_ == nullptr) return;
  written(print_row(events_, "{},{},{},{},{},\"{}\"\n", static_cast<long long>(receipt_ns),
                    static_cast<unsigned long long>(e.sequence_number),
                    static_cast<long long>(e.t_ns), static_cast<int>(e.severity), e.code, text),
          "events.csv");
  written(std::fflush(events_), "events.csv");
}

GroundStation::GroundStation(const link::LinkConfig& config, TelemetryRecorder* recorder)
    : config_(config),
      recorder_(recorder),
      participant_(config, security::Role::kStation),
      topics_(participant_),
      command_writer_(participant_, topics_.command, link::command_qos(config, link::End::kWriter)),
      mode_writer_(participant_, topics_.mode_request, link::mode_request_qos()),
      heartbeat_writer_(participant_, topics_.heartbeat, link::heartbeat_qos(config)),
      state_reader_(participant_, topics_.vehicle_state, link::vehicle_state_qos()),
      camera_reader_(participant_, topics_.camera, link::camera_qos()),
      event_reader_(participant_, topics_.event, link::event_qos()),
      heartbeat_reader_(participant_, topics_.heartbeat, link::heartbeat_qos(config)),
      state_condition_(state_reader_),
      event_condition_(event_reader_),
      waitset_(participant_) {
  link::check_config(config_);
  std::random_device device;
  while (session_id_ == 0) session_id_ = (static_cast<std::uint64_t>(device()) << 32U) | device();
  waitset_.attach(state_condition_.handle(), 1);
  waitset_.attach(event_condition_.handle(), 2);
  link::reserve(state_sample_->obstacle_points_B_m, hq_msgs_kMaxObstaclePoints);
  link::reserve(camera_sample_->rgb_jpeg, hq_msgs_kMaxJpegBytes);
  link::reserve(camera_sample_->depth_preview, hq_msgs_kMaxDepthPreviewBytes);
  if (config_.impairment.active()) {  // tests and demos over an emulated slow link
    state_reader_.impair(config_.impairment, 1);
    camera_reader_.impair(config_.impairment, 2);
    event_reader_.impair(config_.impairment, 3);
    heartbeat_reader_.impair(config_.impairment, 4);
  }
}

void GroundStation::send_command(std::int64_t t_ns, const haptics::VelocityCommand& command,
                                 bool valid) {
  link::VelocityCommand c{};
  c.vehicle_id = config_.vehicle_id;
  c.station_id = config_.station_id;
  c.sequence_number = ++command_sequence_;
  c.t_ns = t_ns;
  if (valid) {
    c.v_H_mps = {static_cast<float>(command.v_H_mps.x()), static_cast<float>(command.v_H_mps.y()),
                 static_cast<float>(command.v_H_mps.z())};
    c.yaw_rate_radps = static_cast<float>(command.yaw_rate_radps);
  }
  if (command_writer_.write(c)) {
    ++status_.commands_sent;
  } else {
    ++status_.write_failures;
  }
}

std::optional<hq_msgs_MarkerTask> marker_task_of(std::string_view name) {
  if (name == "hold") return hq_msgs_MARKER_TASK_HOLD;
  if (name == "goto") return hq_msgs_MARKER_TASK_GO_TO;
  if (name == "land") return hq_msgs_MARKER_TASK_LAND;
  return std::nullopt;
}

bool GroundStation::request_mode(std::int64_t t_ns, hq_msgs_Mode mode, const MarkerChoice& marker,
                                 bool take_off) {
  if (status_.vehicle_session == 0) {
    // A request needs the session it is for; the latest one waits for the vehicle.
    const bool told = pending_request_;
    pending_request_ = true;
    pending_mode_ = mode;
    pending_marker_ = marker;
    pending_take_off_ = take_off;
    status_.waiting_for_vehicle = true;
    if (!told) {
      char text[96];
      hq::format_into(text, "mode {}: waiting for vehicle {}", to_string(mode), config_.vehicle_id);
      notice(hq_msgs_SEVERITY_INFO, kGroundEventWaiting, text);
    }
    return false;
  }
  send_mode_request(t_ns, mode, marker, take_off);
  return true;
}

void GroundStation::send_mode_request(std::int64_t t_ns, hq_msgs_Mode mode,
                                      const MarkerChoice& marker, bool take_off) {
  link::ModeRequest r{};
  r.vehicle_id = config_.vehicle_id;
  r.station_id = config_.station_id;
  r.sequence_number = ++mode_sequence_;
  r.t_ns = t_ns;
  r.requested_mode = mode;
  r.marker_task = marker.task;
  r.target_id = marker.target_id;
  r.vehicle_session_id = status_.vehicle_session;
  r.take_off = take_off;
  if (mode_writer_.write(r)) {
    ++status_.mode_requests_sent;
  } else {
    ++status_.write_failures;
  }
}

void GroundStation::send_heartbeat(std::int64_t t_ns) {
  link::Heartbeat h{};
  h.vehicle_id = config_.vehicle_id;
  h.role = hq_msgs_ROLE_GROUND;
  h.sender_id = config_.station_id;
  h.sequence_number = ++heartbeat_sequence_;
  h.t_ns = t_ns;
  h.session_id = session_id_;
  if (heartbeat_writer_.write(h)) {
    ++status_.heartbeats_sent;
  } else {
    ++status_.write_failures;
  }
}

bool GroundStation::poll() {
  bool fresh = false;
  dds_sample_info_t info{};
  while (state_reader_.take(*state_sample_, info)) {
    note_vehicle(state_sample_->vehicle_id);
    if (state_sample_->vehicle_id != config_.vehicle_id) continue;  // another vehicle
    const std::int64_t now = dds_time();
    if (!admit_state(*state_sample_, info.publication_handle, now))
      continue;  // never reaches the loop or the record
    if (status_.have_clock_offset) {
      // The stamp on the ground's clock: vehicle time minus the offset.
      status_.last_state_age_ns =
          monotonic_now_ns() - (state_sample_->t_ns - status_.clock_offset_ns);
      state_age_.add(status_.last_state_age_ns);
    }
    if (observer_ != nullptr) observer_->on_state(now, now - info.source_timestamp, *state_sample_);
    if (recorder_ != nullptr) {
      recorder_->state(now, now - info.source_timestamp, *state_sample_, status_.last_state_age_ns,
                       status_.round_trip_ns);
    }
    status_.state = *state_sample_;
    status_.state.obstacle_points_B_m = {};  // the copy must not alias the sample's buffer
    status_.state_receipt_ns = now;
    status_.last_latency_ns = now - info.source_timestamp;
    status_.have_state = true;
    ++status_.states;
    latency_.add(status_.last_latency_ns);
    fresh = true;
  }
  link::Event event{};
  while (event_reader_.take(event, info)) {
    if (event.vehicle_id != config_.vehicle_id) continue;
    if (status_.vehicle_session == 0) {
      if (early_event_count_ < early_events_.size()) {
        early_events_[early_event_count_++] = event;
      } else {
        ++status_.events_rejected;
      }
      continue;
    }
    if (event.session_id != status_.vehicle_session) {
      // Not the vehicle we follow: forged, or its predecessor's (TRANSIENT_LOCAL history).
      ++status_.events_rejected;
      continue;
    }
    deliver_event(event);
  }
  while (camera_reader_.take(*camera_sample_, info)) {
    if (camera_sample_->vehicle_id != config_.vehicle_id) continue;
    ++status_.camera_frames;
    status_.camera_bytes += camera_sample_->rgb_jpeg._length;
    const std::int64_t now = dds_time();
    if (recorder_ != nullptr) recorder_->camera(now, *camera_sample_);
    if (observer_ != nullptr) observer_->on_camera(now, *camera_sample_);
  }
  link::Heartbeat heartbeat{};
  while (heartbeat_reader_.take(heartbeat, info)) {
    if (heartbeat.vehicle_id == config_.vehicle_id &&
        static_cast<int>(heartbeat.role) == hq_msgs_ROLE_VEHICLE) {
      status_.last_vehicle_heartbeat_ns = dds_time();
      status_.have_vehicle_heartbeat = true;
      if (heartbeat.echo_t_ns != 0) note_echo(heartbeat);
    }
  }
  return fresh;
}

void GroundStation::deliver_event(const link::Event& event) {
  ++status_.events;
  if (event.code == link::kEventCodeIntrusion) {
    ++status_.intrusion_reports;
    hq::format_into(status_.last_intrusion.data(), status_.last_intrusion.size(), "{}", event.text);
  }
  if (event.code == link::kEventCodeVehicleEnded) {
    status_.vehicle_ended = true;
    hq::format_into(status_.vehicle_ended_text.data(), status_.vehicle_ended_text.size(), "{}",
                    event.text);
  }
  hq::format_into(status_.last_event.data(), status_.last_event.size(), "{}", event.text);
  const std::int64_t now = dds_time();
  if (recorder_ != nullptr) recorder_->event(now, event);
  if (observer_ != nullptr) observer_->on_event(now, event);
}

void GroundStation::release_early_events() {
  for (std::size_t i = 0; i < early_event_count_; ++i) {
    if (early_events_[i].session_id == status_.vehicle_session) {
      deliver_event(early_events_[i]);
    } else {
      ++status_.events_rejected;
    }
  }
  early_event_count_ = 0;
}

// What this cannot catch: a forger that copies the live session and sends plausible values with
// the next sequence number. Only the writer's identity tells it apart, and that is DDS
// security's job (a permissions document granting VehicleState to the vehicle's certificate
// only); with security on, such a writer is never matched and nothing here changes.
bool GroundStation::admit_state(const link::VehicleState& s, std::uint64_t writer,
                                std::int64_t receipt_ns) {
  const auto reject = [&](std::uint64_t& counter) {
    ++counter;
    ++status_.states_rejected;  // a sample the haptic loop must not see
    return false;
  };
  if (!link::validate(s).ok) return reject(status_.states_invalid);
  if (!plausible(s).ok) return reject(status_.states_implausible);
  if (s.session_id == 0) return reject(status_.states_wrong_session);  // no vehicle draws 0
  if (s.session_id != status_.vehicle_session) {
    // A session that said goodbye is over: its successor need not wait for it to go quiet.
    const bool live = status_.vehicle_session != 0 && !status_.vehicle_ended &&
                      receipt_ns - session_receipt_ns_ <= kSessionLiveNs;
    if (live) return reject(status_.states_wrong_session);
    // The current session went quiet: a new vehicle process (a restart) took its place.
    const bool restart = status_.vehicle_session != 0;
    status_.vehicle_session = s.session_id;
    status_.vehicle_ended = false;
    status_.vehicle_ended_text[0] = '\0';
    state_sequence_.reset();
    if (restart) {
      ++status_.vehicle_restarts;
      // Nothing is re-sent: what the operator asked of the previous instance may not suit this
      // one (it is on the floor, or somewhere else).
      pending_request_ = false;
      status_.waiting_for_vehicle = false;
      char text[128];
      hq::format_into(text, "vehicle {} restarted (new session 0x{:016x}): request the mode again",
                      config_.vehicle_id, static_cast<unsigned long long>(s.session_id));
      notice(hq_msgs_SEVERITY_WARNING, kGroundEventVehicleRestarted, text);
    } else if (pending_request_) {
      pending_request_ = false;
      status_.waiting_for_vehicle = false;
      send_mode_request(monotonic_now_ns(), pending_mode_, pending_marker_, pending_take_off_);
    }
    release_early_events();
  }
  const link::SequenceCheck sequence = state_sequence_.check(s.sequence_number, writer, receipt_ns);
  switch (sequence.verdict) {
    case link::SequenceVerdict::kNext:
      break;
    case link::SequenceVerdict::kGap:
      status_.state_sequence_gaps += sequence.missing;
      break;
    case link::SequenceVerdict::kBehind:
      // Overtaken on the way (jitter) or replayed: older than what the loop already has. If it
      // was counted missing when the newer one came, it is not; it must not replace the newer.
      ++status_.states_reordered;
      if (status_.state_sequence_gaps > 0) --status_.state_sequence_gaps;
      return false;
    case link::SequenceVerdict::kJump:
      return reject(status_.states_sequence_jump);
    case link::SequenceVerdict::kResync:
      note_resync(s.sequence_number, sequence.abandoned);
      break;
  }
  session_receipt_ns_ = receipt_ns;
  note_control(s);
  return true;
}

void GroundStation::note_resync(std::uint64_t sequence, std::uint64_t abandoned) {
  ++status_.states_resynced;
  char text[128];
  hq::format_into(text,
                  "vehicle {} states resynchronised at sequence {} (was at {}: forged or leapt)",
                  config_.vehicle_id, static_cast<unsigned long long>(sequence),
                  static_cast<unsigned long long>(abandoned));
  notice(hq_msgs_SEVERITY_WARNING, kGroundEventSequenceResync, text);
}

void GroundStation::note_control(const link::VehicleState& s) {
  status_.commanding_station_id = s.commanding_station_id;
  const bool lost = s.commanding_station_id != 0 && s.commanding_station_id != config_.station_id;
  if (lost == status_.control_lost) return;
  status_.control_lost = lost;
  char text[128];
  if (lost) {
    ++status_.control_losses;
    hq::format_into(text, "CONTROL LOST: station {} commands vehicle {}", s.commanding_station_id,
                    config_.vehicle_id);
    notice(hq_msgs_SEVERITY_ERROR, kGroundEventControlLost, text);
  } else {
    hq::format_into(text, "control regained: station {} commands vehicle {}",
                    s.commanding_station_id, config_.vehicle_id);
    notice(hq_msgs_SEVERITY_WARNING, kGroundEventControlRegained, text);
  }
}

void GroundStation::notice(hq_msgs_Severity severity, std::uint32_t code, const char* text) {
  link::Event e{};
  e.vehicle_id = config_.vehicle_id;
  e.t_ns = monotonic_now_ns();
  e.severity = severity;
  e.code = code;
  e.session_id = status_.vehicle_session;
  hq::format_into(e.text, "{}", text);
  hq::format_into(status_.last_event.data(), status_.last_event.size(), "{}", text);
  const std::int64_t now = dds_time();
  if (recorder_ != nullptr) recorder_->event(now, e);
  if (observer_ != nullptr) observer_->on_event(now, e);
  if (log_ != nullptr) {
    fmt::print(log_, "hq-ground: {}\n", text);
    std::fflush(log_);
  }
}

void GroundStation::note_echo(const link::Heartbeat& heartbeat) {
  // NTP with t0 our send (echo_t_ns), t1 = t2 - held the vehicle's receipt, t2 its send
  // (t_ns), t3 our receipt: round trip (t3 - t0) - held, offset ((t1 - t0) + (t2 - t3)) / 2.
  if (heartbeat.session_id != echo_session_) {
    // A restarted vehicle: its clock (CLOCK_MONOTONIC of another boot, or a simulator's time
    // from 0) has nothing to do with its predecessor's. Mixing the two offsets put the state
    // age at +150 s or -7 s; the new session's offset is learnt from its own echoes only.
    echo_session_ = heartbeat.session_id;
    echo_count_ = 0;
    status_.have_clock_offset = false;
    status_.last_state_age_ns = -1;
  }
  const std::int64_t t3 = monotonic_now_ns();
  const std::int64_t round_trip_ns = t3 - heartbeat.echo_t_ns - heartbeat.echo_held_ns;
  if (round_trip_ns < 0 || heartbeat.echo_held_ns < 0) return;  // not our clock's echo
  const std::int64_t t1 = heartbeat.t_ns - heartbeat.echo_held_ns;
  const std::int64_t offset_ns = ((t1 - heartbeat.echo_t_ns) + (heartbeat.t_ns - t3)) / 2;
  status_.round_trip_ns = round_trip_ns;
  round_trip_.add(round_trip_ns);
  echoes_[echo_count_++ % echoes_.size()] = {round_trip_ns, offset_ns};
  const std::size_t n = std::min(echo_count_, echoes_.size());
  const Echo* best = &echoes_[0];
  for (std::size_t i = 1; i < n; ++i) {
    if (echoes_[i].round_trip_ns < best->round_trip_ns) best = &echoes_[i];
  }
  status_.clock_offset_ns = best->offset_ns;
  status_.have_clock_offset = true;
}

double GroundStation::state_loss() const {
  const double missing = static_cast<double>(status_.state_sequence_gaps);
  const double total = missing + static_cast<double>(status_.states);
  return total > 0.0 ? missing / total : 0.0;
}

void GroundStation::note_vehicle(std::uint32_t vehicle_id) {
  auto& ids = status_.vehicle_ids_seen;
  const auto end = ids.begin() + static_cast<std::ptrdiff_t>(status_.vehicle_ids_seen_count);
  if (std::find(ids.begin(), end, vehicle_id) != end) return;
  if (status_.vehicle_ids_seen_count < ids.size())
    ids[status_.vehicle_ids_seen_count++] = vehicle_id;
}

void GroundStation::select_vehicle(std::uint32_t vehicle_id) {
  if (vehicle_id == config_.vehicle_id) return;
  config_.vehicle_id = vehicle_id;
  status_.have_state = false;
  state_sequence_.reset();
  // Another vehicle: its own session, commander and pending requests.
  status_.vehicle_session = 0;
  status_.control_lost = false;
  status_.commanding_station_id = 0;
  pending_request_ = false;
  status_.waiting_for_vehicle = false;
  early_event_count_ = 0;
}

bool GroundStation::poll_until(std::int64_t deadline_ns) {
  std::array<dds_attach_t, 2> triggered{};
  for (;;) {
    if (poll()) return true;
    timespec now{};
    clock_gettime(CLOCK_MONOTONIC, &now);
    const std::int64_t left_ns = deadline_ns - (now.tv_sec * 1'000'000'000LL + now.tv_nsec);
    if (left_ns <= 0) return false;
    if (waitset_.wait(triggered, left_ns) < 0) return false;
  }
}

double GroundStation::state_age_s() const {
  if (!status_.have_state) return std::numeric_limits<double>::infinity();
  return 1e-9 * static_cast<double>(dds_time() - status_.state_receipt_ns);
}

}  // namespace hq::ground
