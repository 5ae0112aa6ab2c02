#include "hq/ground/ground_station.hpp"

#include "hq/base/error.hpp"

#include <sys/stat.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>

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
    case hq_msgs_MODE_TELEOP: return "teleop";
    case hq_msgs_MODE_HOVER: return "hover";
    case hq_msgs_MODE_LAND: return "land";
    case hq_msgs_MODE_MARKER: return "marker";
    case hq_msgs_MODE_EXPLORE: return "explore";
    default: return "invalid";
  }
}

const char* to_string(hq_msgs_Health health) {
  switch (static_cast<int>(health)) {
    case hq_msgs_HEALTH_OK: return "ok";
    case hq_msgs_HEALTH_DEGRADED: return "degraded";
    case hq_msgs_HEALTH_LOST: return "lost";
    default: return "invalid";
  }
}

void LatencyStats::add(std::int64_t latency_ns) {
  const std::int64_t bin = std::clamp<std::int64_t>(latency_ns / 10'000, 0,
                                                    static_cast<std::int64_t>(bins_.size()) - 1);
  ++bins_[static_cast<std::size_t>(bin)];
  ++count_;
}

double LatencyStats::quantile_ms(double q) const {
  if (count_ == 0) return 0.0;
  const auto target = static_cast<std::int64_t>(std::ceil(q * static_cast<double>(count_)));
  std::int64_t seen = 0;
  for (std::size_t i = 0; i < bins_.size(); ++i) {
    seen += bins_[i];
    if (seen >= std::max<std::int64_t>(target, 1)) return 0.01 * static_cast<double>(i + 1);
  }
  return 0.01 * static_cast<double>(bins_.size());
}

TelemetryRecorder::TelemetryRecorder(const std::string& directory) {
  if (mkdir(directory.c_str(), 0755) != 0 && errno != EEXIST) {
    throw InputError("--record " + directory + ": cannot create directory: " +
                     std::strerror(errno));
  }
  const std::string telemetry = directory + "/telemetry.csv";
  const std::string events = directory + "/events.csv";
  telemetry_ = std::fopen(telemetry.c_str(), "w");
  if (!telemetry_) throw InputError(telemetry + ": cannot open for writing");
  events_ = std::fopen(events.c_str(), "w");
  if (!events_) {
    std::fclose(telemetry_);
    throw InputError(events + ": cannot open for writing");
  }
  std::fprintf(telemetry_,
               "receipt_ns,latency_us,sequence,t_ns,v_H_x_mps,v_H_y_mps,v_H_z_mps,"
               "omega_x_radps,omega_y_radps,omega_z_radps,roll_rad,pitch_rad,v_obs_x_mps,"
               "v_obs_y_mps,v_obs_z_mps,mode,estimator_health,link_health\n");
  std::fprintf(events_, "receipt_ns,sequence,t_ns,severity,code,text\n");
}

TelemetryRecorder::~TelemetryRecorder() {
  std::fclose(telemetry_);
  std::fclose(events_);
}

void TelemetryRecorder::state(std::int64_t receipt_ns, std::int64_t latency_ns,
                              const link::VehicleState& s) {
  std::fprintf(telemetry_,
               "%lld,%.1f,%llu,%lld,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%s,%s,"
               "%s\n",
               static_cast<long long>(receipt_ns), 1e-3 * static_cast<double>(latency_ns),
               static_cast<unsigned long long>(s.sequence_number), static_cast<long long>(s.t_ns),
               s.v_H_mps.x, s.v_H_mps.y, s.v_H_mps.z, s.omega_body_radps.x,
               s.omega_body_radps.y, s.omega_body_radps.z, s.roll_rad, s.pitch_rad,
               s.v_obs_H_mps.x, s.v_obs_H_mps.y, s.v_obs_H_mps.z, to_string(s.mode),
               to_string(s.estimator_health), to_string(s.link_health));
}

void TelemetryRecorder::event(std::int64_t receipt_ns, const link::Event& e) {
  // Quotes in the text would break the CSV field; the vehicle's texts have none, a hostile
  // sender's are replaced.
  char text[sizeof e.text];
  std::snprintf(text, sizeof text, "%s", e.text);
  for (char& c : text) {
    if (c == '"') c = '\'';
  }
  std::fprintf(events_, "%lld,%llu,%lld,%d,%u,\"%s\"\n", static_cast<long long>(receipt_ns),
               static_cast<unsigned long long>(e.sequence_number), static_cast<long long>(e.t_ns),
               static_cast<int>(e.severity), e.code, text);
  std::fflush(events_);
}

GroundStation::GroundStation(const link::LinkConfig& config, TelemetryRecorder* recorder)
    : config_(config),
      recorder_(recorder),
      participant_(config.domain_id),
      command_topic_(participant_),
      mode_topic_(participant_),
      heartbeat_topic_(participant_),
      state_topic_(participant_),
      camera_topic_(participant_),
      event_topic_(participant_),
      command_writer_(participant_, command_topic_, link::command_qos(config, link::End::kWriter)),
      mode_writer_(participant_, mode_topic_, link::mode_request_qos()),
      heartbeat_writer_(participant_, heartbeat_topic_, link::heartbeat_qos(config)),
      state_reader_(participant_, state_topic_, link::vehicle_state_qos()),
      camera_reader_(participant_, camera_topic_, link::camera_qos()),
      event_reader_(participant_, event_topic_, link::event_qos()),
      heartbeat_reader_(participant_, heartbeat_topic_, link::heartbeat_qos(config)),
      state_condition_(state_reader_),
      event_condition_(event_reader_),
      waitset_(participant_) {
  link::check_config(config_);
  waitset_.attach(state_condition_.handle(), 1);
  waitset_.attach(event_condition_.handle(), 2);
  link::reserve(state_sample_->obstacle_points_body_m, hq_msgs_kMaxObstaclePoints);
  link::reserve(camera_sample_->rgb_jpeg, hq_msgs_kMaxJpegBytes);
  link::reserve(camera_sample_->depth_preview, hq_msgs_kMaxDepthPreviewBytes);
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

void GroundStation::request_mode(std::int64_t t_ns, hq_msgs_Mode mode) {
  link::ModeRequest r{};
  r.vehicle_id = config_.vehicle_id;
  r.station_id = config_.station_id;
  r.sequence_number = ++mode_sequence_;
  r.t_ns = t_ns;
  r.requested_mode = mode;
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
    if (state_sample_->vehicle_id != config_.vehicle_id || !link::validate(*state_sample_).ok) {
      continue;  // another vehicle, or a sample the haptic loop must not see
    }
    const std::int64_t now = dds_time();
    status_.state = *state_sample_;
    status_.state.obstacle_points_body_m = {};  // the copy must not alias the sample's buffer
    status_.state_receipt_ns = now;
    status_.last_latency_ns = now - info.source_timestamp;
    status_.have_state = true;
    ++status_.states;
    latency_.add(status_.last_latency_ns);
    if (recorder_ != nullptr) recorder_->state(now, status_.last_latency_ns, status_.state);
    fresh = true;
  }
  link::Event event{};
  while (event_reader_.take(event, info)) {
    if (event.vehicle_id != config_.vehicle_id) continue;
    ++status_.events;
    std::snprintf(status_.last_event.data(), status_.last_event.size(), "%s", event.text);
    if (recorder_ != nullptr) recorder_->event(dds_time(), event);
  }
  while (camera_reader_.take(*camera_sample_, info)) {
    if (camera_sample_->vehicle_id != config_.vehicle_id) continue;
    ++status_.camera_frames;
    status_.camera_bytes += camera_sample_->rgb_jpeg._length;
  }
  link::Heartbeat heartbeat{};
  while (heartbeat_reader_.take(heartbeat, info)) {
    if (heartbeat.vehicle_id == config_.vehicle_id &&
        static_cast<int>(heartbeat.role) == hq_msgs_ROLE_VEHICLE) {
      status_.last_vehicle_heartbeat_ns = dds_time();
      status_.have_vehicle_heartbeat = true;
    }
  }
  return fresh;
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
