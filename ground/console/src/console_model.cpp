#include "hq/console/console_model.hpp"

#include "hq/base/format_into.hpp"
#include "hq/console/position_status.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

namespace hq::console {

namespace {

// Copies a ring of `total` items ever written, capacity ring.size(), oldest first into `out`.
template <typename T>
std::size_t copy_ring(const std::vector<T>& ring, std::uint64_t total, std::vector<T>& out) {
  const std::size_t capacity = ring.size();
  const std::size_t count = static_cast<std::size_t>(std::min<std::uint64_t>(total, capacity));
  const std::size_t first = static_cast<std::size_t>((total - count) % capacity);
  for (std::size_t i = 0; i < count; ++i) out[i] = ring[(first + i) % capacity];
  return count;
}

}  // namespace

ConsoleModel::ConsoleModel(const Capacity& capacity)
    : capacity_(capacity),
      plot_(std::max<std::size_t>(capacity.plot, 1)),
      track_(std::max<std::size_t>(capacity.track, 1)),
      previous_track_(track_.size()),
      cloud_W_(capacity.cloud),
      events_(std::max<std::size_t>(capacity.events, 1)),
      jpeg_(capacity.jpeg_bytes),
      depth_(capacity.depth_bytes) {}

double ConsoleModel::seconds(std::int64_t t_ns) {
  if (!have_t0_) {
    t0_ns_ = t_ns;
    have_t0_ = true;
  }
  return 1e-9 * static_cast<double>(t_ns - t0_ns_);
}

void ConsoleModel::on_state(std::int64_t t_ns, double latency_ms,
                            const std::array<float, 3>& v_H_mps,
                            const std::array<float, 3>& omega_B_radps, float roll_rad,
                            float pitch_rad, const std::array<float, 3>& v_obs_H_mps,
                            const char* mode, const char* estimator_health, const char* link_health,
                            const float* cloud_B_m, std::size_t cloud_points,
                            const StateExtras& extras) {
  const std::lock_guard<std::mutex> lock(mutex_);
  const double t_s = seconds(t_ns);
  const bool position = extras.position_valid && std::isfinite(extras.p_W_m[0]) &&
                        std::isfinite(extras.p_W_m[1]) && std::isfinite(extras.yaw_W_rad);
  position_lost_ = !position && position_lost(extras.position_invalid_reason);
  position_invalid_reason_ = position ? 0 : extras.position_invalid_reason;
  position_age_s_ = std::isfinite(extras.position_age_s) ? extras.position_age_s : 0.0F;
  position_sigma_m_ = std::isfinite(extras.position_sigma_m) ? extras.position_sigma_m : 0.0F;
  if (position_lost_) {
    // The vehicle's pose is invalid: neither followed nor dead-reckoned from (it may be far
    // off); the last valid position stays, greyed, with the reason.
  } else if (position) {
    // The vehicle's own estimate replaces the dead reckoning, which carries on from it when
    // the position drops out again.
    x_W_m_ = extras.p_W_m[0];
    y_W_m_ = extras.p_W_m[1];
    yaw_W_rad_ = extras.yaw_W_rad;
    ++position_states_;
  } else if (have_state_ && t_ns > last_state_ns_) {
    // Dead reckoning for the top view (see the header): yaw from the gyro's z rate, then
    // v_W = R_z(yaw) v_H. A gap of more than a second is not bridged.
    const double dt_s = std::min(1e-9 * static_cast<double>(t_ns - last_state_ns_), 1.0);
    if (std::isfinite(omega_B_radps[2])) {
      yaw_W_rad_ += static_cast<double>(omega_B_radps[2]) * dt_s;
    }
    const double c = std::cos(yaw_W_rad_);
    const double s = std::sin(yaw_W_rad_);
    if (std::isfinite(v_H_mps[0]) && std::isfinite(v_H_mps[1])) {
      const auto vx = static_cast<double>(v_H_mps[0]);
      const auto vy = static_cast<double>(v_H_mps[1]);
      x_W_m_ += (c * vx - s * vy) * dt_s;
      y_W_m_ += (s * vx + c * vy) * dt_s;
    }
  }
  if (sessions_ == 0) sessions_ = 1;
  have_state_ = true;
  last_state_ns_ = t_ns;
  PlotSample& p = plot_[plot_total_ % plot_.size()];
  p.t_s = static_cast<float>(t_s);
  p.v_est_H_mps = v_H_mps;
  p.v_cmd_H_mps = command_;
  p.v_obs_H_mps = v_obs_H_mps;
  p.yaw_rate_cmd_radps = yaw_rate_command_;
  p.yaw_rate_meas_radps = omega_B_radps[2];
  p.latency_ms = static_cast<float>(latency_ms);
  p.state_age_ms = extras.state_age_ms;
  p.round_trip_ms = extras.round_trip_ms;
  p.truth_valid = extras.truth_valid;
  p.v_truth_H_mps = extras.truth_valid ? extras.v_truth_H_mps : std::array<float, 3>{};
  have_truth_ = have_truth_ || extras.truth_valid;
  position_from_vehicle_ = position;
  marker_count_ = extras.markers != nullptr ? std::min(extras.marker_count, markers_.size()) : 0;
  std::copy_n(extras.markers, marker_count_, markers_.begin());
  marker_detections_ += marker_count_;
  latest_ = p;
  ++plot_total_;
  if (!position_lost_) {
    track_[track_total_ % track_.size()] = {static_cast<float>(x_W_m_), static_cast<float>(y_W_m_)};
    ++track_total_;
  }
  mode_ = mode;
  estimator_health_ = estimator_health;
  track_flight(t_s, extras.flight_state);
  flight_state_ = extras.flight_state;
  motors_armed_ = extras.motors_armed;
  height_valid_ = extras.height_valid && std::isfinite(extras.height_m);
  height_m_ = height_valid_ ? extras.height_m : 0.0F;
  height_source_ = extras.height_source;
  operator_input_ = extras.operator_input;
  clearance_m_ = std::isfinite(extras.clearance_m) ? extras.clearance_m : -1.0F;
  hover_thrust_gain_ = std::isfinite(extras.hover_thrust_gain) ? extras.hover_thrust_gain : 0.0F;
  hover_thrust_converged_ = extras.hover_thrust_converged && hover_thrust_gain_ > 0.0F;
  marker_target_id_ = extras.marker_target_id;
  explore_phase_ = extras.explore_phase != nullptr ? extras.explore_phase : "";
  modes_offered_ = extras.modes_offered;
  marker_mode_off_ = extras.marker_mode_off != nullptr ? extras.marker_mode_off : "";
  explore_mode_off_ = extras.explore_mode_off != nullptr ? extras.explore_mode_off : "";
  link_health_ = link_health;
  roll_rad_ = roll_rad;
  pitch_rad_ = pitch_rad;
  if (cloud_B_m != nullptr && cloud_points > 0) {
    // Body FRD to W about the vertical only (roll and pitch are small in the top view).
    const double c = std::cos(yaw_W_rad_);
    const double s = std::sin(yaw_W_rad_);
    cloud_count_ = std::min(cloud_points, cloud_W_.size());
    for (std::size_t i = 0; i < cloud_count_; ++i) {
      const double x = cloud_B_m[3 * i];
      const double y = cloud_B_m[3 * i + 1];
      cloud_W_[i] = {static_cast<float>(x_W_m_ + c * x - s * y),
                     static_cast<float>(y_W_m_ + s * x + c * y)};
    }
  }
  // The cloud rides on one state a second (BridgeOptions::obstacle_cloud_rate_hz); the states
  // between carry none, and the cloud, already placed in W, stands until the next one.
}

void ConsoleModel::on_command(std::int64_t t_ns, const std::array<float, 3>& v_H_mps,
                              float yaw_rate_radps) {
  const std::lock_guard<std::mutex> lock(mutex_);
  seconds(t_ns);
  command_ = v_H_mps;
  yaw_rate_command_ = yaw_rate_radps;
}

void ConsoleModel::on_event(std::int64_t t_ns, int severity, const char* text) {
  const std::lock_guard<std::mutex> lock(mutex_);
  add_event(seconds(t_ns), severity, text);
}

void ConsoleModel::add_event(double t_s, int severity, const char* text) {
  EventLine& e = events_[events_total_ % events_.size()];
  e.t_s = t_s;
  e.severity = severity;
  hq::format_into(e.text.data(), e.text.size(), "{}", text);
  ++events_total_;
}

// The flight timer runs from the first state off the ground to the next one on it, the
// touchdown, which the events say with the flight's length (the vehicle's own "landed" event
// is about the FC's setpoints, and a replay seeks past it).
void ConsoleModel::track_flight(double t_s, const char* flight_state) {
  if (std::strcmp(flight_state, "-") == 0) return;  // a state that does not say
  const bool landed = std::strcmp(flight_state, "landed") == 0;
  last_state_s_ = t_s;
  if (!landed && take_off_s_ < 0) take_off_s_ = t_s;
  if (landed && take_off_s_ >= 0) {
    last_flight_s_ = t_s - take_off_s_;
    take_off_s_ = -1;
    const int s = static_cast<int>(last_flight_s_);
    char text[64];
    hq::format_into(text, "touchdown: landed after {:02}:{:02} of flight", s / 60, s % 60);
    add_event(t_s, 0, text);
  }
}

void ConsoleModel::on_camera(std::int64_t t_ns, const std::uint8_t* jpeg, std::size_t jpeg_size,
                             const std::uint8_t* depth, std::size_t depth_size,
                             std::int64_t exposure_ns, std::int64_t receipt_ns) {
  const std::lock_guard<std::mutex> lock(mutex_);
  seconds(t_ns);
  jpeg_size_ = std::min(jpeg_size, jpeg_.size());
  if (jpeg_size_ > 0) std::memcpy(jpeg_.data(), jpeg, jpeg_size_);
  depth_size_ = depth != nullptr ? std::min(depth_size, depth_.size()) : 0;
  if (depth_size_ > 0) std::memcpy(depth_.data(), depth, depth_size_);
  camera_exposure_ns_ = exposure_ns;
  camera_receipt_ns_ = receipt_ns;
  ++camera_sequence_;
}

void ConsoleModel::on_haptics(const HapticState& haptics) {
  const std::lock_guard<std::mutex> lock(mutex_);
  haptics_ = haptics;
}

void ConsoleModel::on_link(const LinkHealth& link) {
  const std::lock_guard<std::mutex> lock(mutex_);
  link_ = link;
}

void ConsoleModel::set_source(const std::string& text) {
  const std::lock_guard<std::mutex> lock(mutex_);
  hq::format_into(source_.data(), source_.size(), "{}", text);
}

void ConsoleModel::on_replay(const ReplayStatus& replay) {
  const std::lock_guard<std::mutex> lock(mutex_);
  replay_ = replay;
}

void ConsoleModel::reset() {
  const std::lock_guard<std::mutex> lock(mutex_);
  have_t0_ = false;
  t0_ns_ = 0;
  last_state_ns_ = 0;
  plot_total_ = 0;
  track_total_ = 0;
  previous_track_count_ = 0;
  sessions_ = 0;
  cloud_count_ = 0;
  events_total_ = 0;
  jpeg_size_ = 0;
  depth_size_ = 0;
  camera_exposure_ns_ = -1;
  camera_receipt_ns_ = -1;
  command_ = {};
  yaw_rate_command_ = 0;
  yaw_W_rad_ = 0;
  x_W_m_ = 0;
  y_W_m_ = 0;
  position_from_vehicle_ = false;
  position_states_ = 0;
  position_lost_ = false;
  position_invalid_reason_ = 0;
  have_truth_ = false;
  marker_count_ = 0;
  marker_detections_ = 0;
  have_state_ = false;
  mode_ = "-";
  estimator_health_ = "-";
  link_health_ = "-";
  // A seek to before the first state shows no state's fields, as a live console before one.
  flight_state_ = "-";
  motors_armed_ = false;
  height_valid_ = false;
  height_m_ = 0;
  height_source_ = "-";
  operator_input_ = "";
  clearance_m_ = -1;
  hover_thrust_gain_ = 0;
  hover_thrust_converged_ = false;
  roll_rad_ = 0;
  pitch_rad_ = 0;
  latest_ = PlotSample{};
  link_ = LinkHealth{};
  take_off_s_ = -1;
  last_flight_s_ = -1;
  marker_target_id_ = -1;
  explore_phase_ = "";
  modes_offered_ = 0;
  marker_mode_off_ = "";
  explore_mode_off_ = "";
}

void ConsoleModel::start_new_track() {
  const std::lock_guard<std::mutex> lock(mutex_);
  // The old session's trail stays on the top view, greyed; a restart before any state of the
  // new session has nothing of its own to keep.
  if (track_total_ > 0) previous_track_count_ = copy_ring(track_, track_total_, previous_track_);
  ++sessions_;
  track_total_ = 0;
  cloud_count_ = 0;
  yaw_W_rad_ = 0;
  x_W_m_ = 0;
  y_W_m_ = 0;
  position_from_vehicle_ = false;
  marker_count_ = 0;
  have_state_ = false;  // no dead-reckoning step across the restart
  // The plots: another vehicle's clock and link; its first state is t = 0 of a fresh axis.
  plot_total_ = 0;
  latest_ = PlotSample{};
  have_truth_ = false;
  command_ = {};
  yaw_rate_command_ = 0;
  have_t0_ = false;
}

Snapshot ConsoleModel::make_snapshot() const {
  Snapshot s;
  s.plot.resize(plot_.size());
  s.track.resize(track_.size());
  s.previous_track.resize(previous_track_.size());
  s.cloud_W.resize(cloud_W_.size());
  s.events.resize(events_.size());
  s.jpeg.resize(jpeg_.size());
  s.depth.resize(depth_.size());
  return s;
}

void ConsoleModel::snapshot(Snapshot& out) const {
  const std::lock_guard<std::mutex> lock(mutex_);
  out.plot_count = copy_ring(plot_, plot_total_, out.plot);
  out.plot_total = plot_total_;
  out.track_count = copy_ring(track_, track_total_, out.track);
  out.previous_track_count = previous_track_count_;
  std::copy_n(previous_track_.begin(), previous_track_count_, out.previous_track.begin());
  out.sessions = sessions_;
  out.cloud_count = cloud_count_;
  std::copy_n(cloud_W_.begin(), cloud_count_, out.cloud_W.begin());
  out.event_count = copy_ring(events_, events_total_, out.events);
  if (out.camera_sequence != camera_sequence_) {
    std::copy_n(jpeg_.begin(), jpeg_size_, out.jpeg.begin());
    out.jpeg_size = jpeg_size_;
    std::copy_n(depth_.begin(), depth_size_, out.depth.begin());
    out.depth_size = depth_size_;
    out.camera_sequence = camera_sequence_;
    out.camera_exposure_ns = camera_exposure_ns_;
    out.camera_receipt_ns = camera_receipt_ns_;
  }
  out.have_state = have_state_;
  out.mode = mode_;
  out.estimator_health = estimator_health_;
  out.link_health = link_health_;
  out.flight_state = flight_state_;
  out.marker_target_id = marker_target_id_;
  out.explore_phase = explore_phase_;
  out.modes_offered = modes_offered_;
  out.marker_mode_off = marker_mode_off_;
  out.explore_mode_off = explore_mode_off_;
  out.flight_time_s = take_off_s_ >= 0 ? last_state_s_ - take_off_s_ : last_flight_s_;
  out.airborne = take_off_s_ >= 0;
  out.motors_armed = motors_armed_;
  out.height_valid = height_valid_;
  out.height_m = height_m_;
  out.height_source = height_source_;
  out.operator_input = operator_input_;
  out.clearance_m = clearance_m_;
  out.hover_thrust_gain = hover_thrust_gain_;
  out.hover_thrust_converged = hover_thrust_converged_;
  out.roll_rad = roll_rad_;
  out.pitch_rad = pitch_rad_;
  out.yaw_W_rad = static_cast<float>(yaw_W_rad_);
  out.position_W = {static_cast<float>(x_W_m_), static_cast<float>(y_W_m_)};
  out.position_from_vehicle = position_from_vehicle_;
  out.position_states = position_states_;
  out.position_lost = position_lost_;
  out.position_invalid_reason = position_invalid_reason_;
  out.position_age_s = position_age_s_;
  out.position_sigma_m = position_sigma_m_;
  out.have_truth = have_truth_;
  out.markers = markers_;
  out.marker_count = marker_count_;
  out.marker_detections = marker_detections_;
  out.latest = latest_;
  out.haptics = haptics_;
  out.link = link_;
  out.source = source_;
  out.replay = replay_;
}

bool control_banner(const LinkHealth& link, char* out, std::size_t size) {
  if (size == 0) return false;
  out[0] = '\0';
  if (!link.control_lost) return false;
  hq::format_into(out, size,
                  "CONTROL LOST: station {} commands vehicle {}; this station ({}) does not: its "
                  "hand and mode requests are ignored",
                  link.commanding_station, link.selected_vehicle, link.own_station);
  return true;
}

bool vehicle_ended_banner(const LinkHealth& link, char* out, std::size_t size) {
  if (size == 0) return false;
  out[0] = '\0';
  if (!link.vehicle_ended) return false;
  // The vehicle's text starts with "vehicle ended: " and says why and how it was left.
  hq::format_into(
      out, size, "vehicle {}: {}", link.selected_vehicle,
      link.vehicle_ended_text[0] != '\0' ? link.vehicle_ended_text.data() : "vehicle ended");
  return true;
}

bool intrusion_banner(const LinkHealth& link, char* out, std::size_t size) {
  if (size == 0) return false;
  out[0] = '\0';
  if (link.intrusion_reports == 0) return false;
  // The vehicle's text starts with "INTRUSION:" and ends naming the certificate to revoke.
  hq::format_into(out, size, "vehicle {}, report {}: {}", link.selected_vehicle,
                  link.intrusion_reports, link.last_intrusion.data());
  return true;
}

LinkLossMonitor::Change LinkLossMonitor::update(double state_age_s) {
  Change change = Change::kNone;
  if (state_age_s < 0) {
    previous_age_s_ = state_age_s;
    return change;
  }
  if (!lost_ && state_age_s > lost_after_s_) {
    lost_ = true;
    ++losses_;
    change = Change::kLost;
  } else if (lost_ && (state_age_s <= lost_after_s_ || state_age_s < previous_age_s_)) {
    // A fresh state (the age fell back) ends the loss.
    lost_ = false;
    change = Change::kRegained;
  }
  if (lost_) {
    last_loss_s_ = state_age_s;
    longest_s_ = std::max(longest_s_, state_age_s);
  }
  previous_age_s_ = state_age_s;
  return change;
}

}  // namespace hq::console
