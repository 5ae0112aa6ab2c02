#include "hq/link_bridge/link_bridge.hpp"

#include "hq/base/format_into.hpp"
#include "hq/base/monotonic_clock.hpp"

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>

namespace hq::link_bridge {
namespace {

std::int64_t period_ns(double rate_hz) {
  return rate_hz > 0.0 ? static_cast<std::int64_t>(std::llround(1e9 / rate_hz)) : 0;
}

hq_msgs_Vector3f to_msg(const Eigen::Vector3d& v) {
  return {static_cast<float>(v.x()), static_cast<float>(v.y()), static_cast<float>(v.z())};
}

// The chain's odom pose and the estimate's velocity sigma; zeros (odom_valid false) for
// anything non-finite, never garbage.
void set_odom_fields(const pipeline::ChainOutput& out, link::VehicleState& s) {
  const pipeline::OdomPoseEstimate& odom = out.odom;
  s.odom_valid = odom.valid && odom.p_odom_m.allFinite() && std::isfinite(odom.yaw_rad) &&
                 std::isfinite(odom.position_sigma_m) && std::isfinite(odom.yaw_sigma_rad);
  s.p_odom_m = s.odom_valid ? to_msg(odom.p_odom_m) : hq_msgs_Vector3f{0.0F, 0.0F, 0.0F};
  s.yaw_odom_rad = s.odom_valid ? static_cast<float>(odom.yaw_rad) : 0.0F;
  s.odom_position_sigma_m =
      s.odom_valid ? static_cast<float>(std::clamp(odom.position_sigma_m, 0.0, 1e6)) : 0.0F;
  s.odom_yaw_sigma_rad =
      s.odom_valid ? static_cast<float>(std::clamp(odom.yaw_sigma_rad, 0.0, 1e6)) : 0.0F;
  s.odom_yaw_relative_to_start = odom.yaw_relative_to_start;
  const Eigen::Vector3d sigma = out.estimate.v_H_covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  s.v_H_sigma_mps = sigma.allFinite() ? to_msg(sigma.cwiseMin(1e6)) : hq_msgs_Vector3f{0, 0, 0};
}
}  // namespace

bool to_marker_task(hq_msgs_MarkerTask value, marker_modes::MarkerTask& task) {
  // Compared as integers: a received enum may hold any value.
  switch (static_cast<int>(value)) {
    case static_cast<int>(hq_msgs_MARKER_TASK_HOLD):
      task = marker_modes::MarkerTask::kHold;
      return true;
    case static_cast<int>(hq_msgs_MARKER_TASK_GO_TO):
      task = marker_modes::MarkerTask::kGoTo;
      return true;
    case static_cast<int>(hq_msgs_MARKER_TASK_LAND):
      task = marker_modes::MarkerTask::kLand;
      return true;
    default:
      return false;
  }
}

namespace {
hq_msgs_FlightState to_link_flight_state(modes::FlightState state) {
  switch (state) {
    case modes::FlightState::kLanded:
      return hq_msgs_FLIGHT_LANDED;
    case modes::FlightState::kTakingOff:
      return hq_msgs_FLIGHT_TAKING_OFF;
    case modes::FlightState::kAirborne:
      return hq_msgs_FLIGHT_AIRBORNE;
    case modes::FlightState::kLanding:
      return hq_msgs_FLIGHT_LANDING;
  }
  return hq_msgs_FLIGHT_LANDED;
}
}  // namespace

Verdict to_mode_request(const link::ModeRequest& request, modes::Mode mode,
                        pipeline::ModeRequest& out) {
  out = {mode, std::nullopt, request.take_off};
  if (static_cast<int>(request.marker_task) == static_cast<int>(hq_msgs_MARKER_TASK_NONE)) {
    return {true, ""};
  }
  marker_modes::MarkerTask task = marker_modes::MarkerTask::kHold;
  if (!to_marker_task(request.marker_task, task)) {
    return {false, "marker_task outside the MarkerTask enum"};
  }
  if (request.target_id < 0) return {false, "marker target_id is negative"};
  out.marker = pipeline::MarkerTarget{task, static_cast<int>(request.target_id)};
  return {true, ""};
}

FailsafeConfig LinkBridge::with_session(FailsafeConfig config, const link::LinkConfig& link) {
  if (config.session_id == 0) {
    // 64 random bits: two vehicle processes (a restart) practically never share a session.
    std::random_device device;
    while (config.session_id == 0) {
      config.session_id = (static_cast<std::uint64_t>(device()) << 32U) | device();
    }
  }
  if (config.stations.empty()) config.stations = link.stations;
  return config;
}

LinkBridge::LinkBridge(const link::LinkConfig& link, const FailsafeConfig& failsafe,
                       const BridgeOptions& options)
    : link_(link),
      options_(options),
      failsafe_(with_session(failsafe, link)),
      participant_(link, security::Role::kVehicle),
      topics_(participant_),
      command_reader_(participant_, topics_.command, link::command_qos(link, link::End::kReader)),
      mode_reader_(participant_, topics_.mode_request, link::mode_request_qos()),
      heartbeat_reader_(participant_, topics_.heartbeat, link::heartbeat_qos(link)),
      writers_(participant_.secured(), link.vehicle_id),
      state_writer_(participant_, topics_.vehicle_state, link::vehicle_state_qos()),
      camera_writer_(participant_, topics_.camera, link::camera_qos()),
      event_writer_(participant_, topics_.event, link::event_qos()),
      heartbeat_writer_(participant_, topics_.heartbeat, link::heartbeat_qos(link)) {
  link::check_config(link_);
  if (!(options_.camera_rate_hz >= 0.0 && options_.camera_rate_hz <= 60.0)) {
    throw InputError("link bridge: camera_rate_hz = " + std::to_string(options_.camera_rate_hz) +
                     ", expected in [0, 60] (0 = no camera stream)");
  }
  if (options_.jpeg_quality < 1 || options_.jpeg_quality > 100) {
    throw InputError("link bridge: jpeg_quality = " + std::to_string(options_.jpeg_quality) +
                     ", expected in [1, 100]");
  }
  if (!(options_.obstacle_cloud_rate_hz >= 0.0 && options_.obstacle_cloud_rate_hz <= 30.0)) {
    throw InputError(
        "link bridge: obstacle_cloud_rate_hz = " + std::to_string(options_.obstacle_cloud_rate_hz) +
        ", expected in [0, 30] (0 = no obstacle cloud)");
  }
  if (options_.max_obstacle_points < 1 ||
      options_.max_obstacle_points > static_cast<int>(hq_msgs_kMaxObstaclePoints)) {
    throw InputError(
        "link bridge: max_obstacle_points = " + std::to_string(options_.max_obstacle_points) +
        ", expected in [1, " + std::to_string(hq_msgs_kMaxObstaclePoints) + "] (the IDL bound)");
  }
  link::reserve(state_->obstacle_points_B_m,
                static_cast<std::uint32_t>(options_.max_obstacle_points));
  cloud_O_m_.resize(static_cast<std::size_t>(options_.max_obstacle_points));
  link::reserve(state_->markers, hq_msgs_kMaxMarkersInState);
  link::reserve(camera_->rgb_jpeg, hq_msgs_kMaxJpegBytes);
  camera_->vehicle_id = link_.vehicle_id;
  state_->vehicle_id = link_.vehicle_id;
  event_->vehicle_id = link_.vehicle_id;
  state_->session_id = session_id();
  event_->session_id = session_id();
  jpeg_params_ = {cv::IMWRITE_JPEG_QUALITY, options_.jpeg_quality};
  jpeg_.reserve(hq_msgs_kMaxJpegBytes);
  if (link_.ros2.enabled) {
    ros2_ = std::make_unique<ros2_bridge::Ros2Bridge>(participant_, link_);
  }
  if (link_.impairment.active()) {  // tests and demos over an emulated slow link
    command_reader_.impair(link_.impairment, 11);
    mode_reader_.impair(link_.impairment, 12);
    heartbeat_reader_.impair(link_.impairment, 13);
  }
}

const FailsafeState& LinkBridge::poll(std::int64_t t_ns,
                                      std::vector<pipeline::ModeRequest>& mode_requests) {
  dds_sample_info_t info{};
  link::VelocityCommand command{};
  while (command_reader_.take(command, info)) {
    if (failsafe_.on_command(t_ns, command, writers_.station_of(command_reader_.handle(), info))
            .accepted) {
      have_native_command_ = true;
      last_native_command_t_ns_ = t_ns;
    }
  }
  if (ros2_ != nullptr) {
    // The ROS 2 station is the weakest: a native station commanding within its lease wins.
    while (ros2_->take_command(t_ns, command)) {
      if (have_native_command_ && t_ns - last_native_command_t_ns_ <= link_.command_lease_ns) {
        ros2_->count_overridden();
        continue;
      }
      failsafe_.on_command(t_ns, command);
    }
  }
  link::Heartbeat heartbeat{};
  while (heartbeat_reader_.take(heartbeat, info)) {
    if (failsafe_
            .on_heartbeat(t_ns, heartbeat, writers_.station_of(heartbeat_reader_.handle(), info))
            .accepted) {
      echo_t_ns_ = heartbeat.t_ns;  // echoed in our next heartbeat: the station's round trip
      echo_receipt_t_ns_ = t_ns;
    }
  }
  take_mode_requests(t_ns, mode_requests);
  if (ros2_ != nullptr) take_ros2_mode_requests(t_ns, mode_requests);

  const FailsafeState& state = failsafe_.update(t_ns);
  if (state.commander_changed) {
    char text[96];
    hq::format_into(text, "station {} commands this vehicle", state.commanding_station_id);
    publish_event(t_ns, hq_msgs_SEVERITY_WARNING, EventCode::kCommanderChanged, text);
  }
  if (state.hold_started) {
    char text[96];
    hq::format_into(text, "no command for {:.0f} ms: holding zero velocity",
                    1e-6 * static_cast<double>(state.command_age_ns));
    publish_event(t_ns, hq_msgs_SEVERITY_WARNING, EventCode::kHold, text);
  }
  // The failsafe's land is the vehicle's own: the operators' dwell and rate limit must not delay
  // it (it is asked for once).
  if (state.request_land) {
    mode_requests.push_back(
        {modes::Mode::kLand, std::nullopt, false, modes::RequestOrigin::kVehicle});
  }
  if (state.land_for_heartbeat) {
    char text[96];
    hq::format_into(text, "no heartbeat from station {} for {:.1f} s: landing",
                    state.commanding_station_id,
                    hq::to_seconds(failsafe_.config().heartbeat_timeout_ns));
    publish_event(t_ns, hq_msgs_SEVERITY_ERROR, EventCode::kHeartbeatLost, text);
  }
  if (state.land_for_hold) {
    char text[96];
    hq::format_into(text, "no command for {:.1f} s (held {:.1f} s): landing",
                    hq::to_seconds(state.command_age_ns),
                    hq::to_seconds(failsafe_.config().hold_to_land_ns));
    publish_event(t_ns, hq_msgs_SEVERITY_ERROR, EventCode::kHoldToLand, text);
  }
  report_rejections(t_ns);

  if (t_ns >= next_heartbeat_ns_) {
    next_heartbeat_ns_ = t_ns + period_ns(options_.heartbeat_rate_hz);
    link::Heartbeat own{};
    own.vehicle_id = link_.vehicle_id;
    own.role = hq_msgs_ROLE_VEHICLE;
    own.sender_id = link_.vehicle_id;
    own.sequence_number = ++heartbeat_sequence_;
    own.t_ns = t_ns;
    own.echo_t_ns = echo_t_ns_;
    own.echo_held_ns = echo_t_ns_ != 0 ? t_ns - echo_receipt_t_ns_ : 0;
    own.session_id = session_id();
    heartbeat_writer_.write(own);
  }
  return state;
}

void LinkBridge::take_mode_requests(std::int64_t t_ns,
                                    std::vector<pipeline::ModeRequest>& mode_requests) {
  dds_sample_info_t info{};
  link::ModeRequest request{};
  while (mode_reader_.take(request, info)) {
    modes::Mode mode = modes::Mode::kHover;
    const Verdict verdict = failsafe_.on_mode_request(
        t_ns, request, mode, writers_.station_of(mode_reader_.handle(), info));
    if (verdict.accepted) {
      pipeline::ModeRequest chain_request;
      const Verdict routed = to_mode_request(request, mode, chain_request);
      if (!routed.accepted) {
        char text[hq_msgs_kMaxEventText + 1];
        hq::format_into(text, "mode {} with marker {} refused: {}", modes::to_string(mode),
                        static_cast<long>(request.target_id), routed.reason);
        publish_event(t_ns, hq_msgs_SEVERITY_WARNING, EventCode::kMarkerTaskRefused, text);
        continue;
      }
      mode_requests.push_back(chain_request);
    } else {
      // Named with the station and sessions: the operator of a station that lost control, or
      // that talks to a previous instance, sees why its request did nothing.
      char text[hq_msgs_kMaxEventText + 1];
      hq::format_into(text, "mode request of station {} (session {:016x}) rejected: {}",
                      request.station_id,
                      static_cast<unsigned long long>(request.vehicle_session_id), verdict.reason);
      publish_event(t_ns, hq_msgs_SEVERITY_WARNING, EventCode::kModeRequestRejected, text);
    }
  }
}

namespace {
// At most `size` - 1 characters of `text`, the unprintable as '?': a refusal quotes what it got.
void quote(const char* text, char* out, std::size_t size) {
  std::size_t n = 0;
  for (; text[n] != '\0' && n + 1 < size; ++n) {
    const auto c = static_cast<unsigned char>(text[n]);
    out[n] = c >= 0x20 && c < 0x7F ? static_cast<char>(c) : '?';
  }
  out[n] = '\0';
}
}  // namespace

void LinkBridge::take_ros2_mode_requests(std::int64_t t_ns,
                                         std::vector<pipeline::ModeRequest>& mode_requests) {
  while (const char* text = ros2_->take_mode_request()) {
    char shown[40];
    quote(text, shown, sizeof shown);
    char reply[hq_msgs_kMaxEventText + 1];
    ros2_bridge::RosModeRequest parsed;
    if (const char* why = ros2_bridge::parse_mode_request(text, parsed)) {
      hq::format_into(reply, "ROS 2 mode request \"{}\" on {} refused: {}", shown,
                      ros2_bridge::ros_topic_name(ros2_->ros_namespace(), "mode_request").c_str(),
                      why);
      answer(t_ns, hq_msgs_SEVERITY_WARNING, EventCode::kModeRequestRejected, reply, true);
      continue;
    }
    // The ground's request, as station link.ros2.station_id of this session: the same gate.
    link::ModeRequest request{};
    request.vehicle_id = link_.vehicle_id;
    request.station_id = link_.ros2.station_id;
    request.sequence_number = ++ros2_mode_sequence_;
    request.t_ns = t_ns;
    request.requested_mode = parsed.mode;
    request.marker_task = parsed.marker_task;
    request.target_id = parsed.target_id;
    request.vehicle_session_id = session_id();
    request.take_off = parsed.take_off;
    modes::Mode mode = modes::Mode::kHover;
    const Verdict verdict = failsafe_.on_mode_request(t_ns, request, mode);
    pipeline::ModeRequest chain_request;
    const Verdict routed =
        verdict.accepted ? to_mode_request(request, mode, chain_request) : verdict;
    if (!routed.accepted) {
      hq::format_into(reply, "ROS 2 mode request \"{}\" (station {}) refused: {}", shown,
                      link_.ros2.station_id, routed.reason);
      answer(t_ns, hq_msgs_SEVERITY_WARNING, EventCode::kModeRequestRejected, reply, true);
      continue;
    }
    chain_request.from_ros2 = true;
    mode_requests.push_back(chain_request);
  }
}

void LinkBridge::answer(std::int64_t t_ns, hq_msgs_Severity severity, EventCode code,
                        const char* text, bool from_ros2) {
  publish_event(t_ns, severity, code, text);
  if (from_ros2 && ros2_ != nullptr) ros2_->publish_mode_status(text);
}

void LinkBridge::report_rejections(std::int64_t t_ns) {
  if (t_ns < next_rejection_report_ns_) return;
  const FailsafeCounters& c = failsafe_.counters();
  const std::uint64_t commands = c.commands_rejected - reported_.commands_rejected;
  const std::uint64_t heartbeats = c.heartbeats_rejected - reported_.heartbeats_rejected;
  const std::uint64_t intrusions = c.intrusions - reported_.intrusions;
  if (commands == 0 && heartbeats == 0 && intrusions == 0) return;
  char text[hq_msgs_kMaxEventText + 1];
  if (intrusions > 0) {
    // An allowed certificate speaking for another station: the operators must know, whatever
    // the fail-safe did with it (refused), and which certificate to revoke.
    const Intrusion& last = failsafe_.last_intrusion();
    char writer[48] = "a certificate of no station";
    if (last.writer_station_id != 0) {
      hq::format_into(writer, "station_{}'s certificate", last.writer_station_id);
    }
    hq::format_into(text,
                    "INTRUSION: {} samples ({} in total) claimed another station, refused; last: a "
                    "{} claiming station {}, written by {}",
                    static_cast<unsigned long long>(intrusions),
                    static_cast<unsigned long long>(c.intrusions), last.kind,
                    last.claimed_station_id, writer);
    publish_event(t_ns, hq_msgs_SEVERITY_ERROR, EventCode::kIntrusion, text);
  }
  if (commands > 0) {
    hq::format_into(text, "rejected {} commands ({} in total), last: {}",
                    static_cast<unsigned long long>(commands),
                    static_cast<unsigned long long>(c.commands_rejected),
                    failsafe_.last_command_rejection());
    publish_event(t_ns, hq_msgs_SEVERITY_WARNING, EventCode::kCommandsRejected, text);
  }
  if (heartbeats > 0) {
    hq::format_into(text, "rejected {} heartbeats ({} in total)",
                    static_cast<unsigned long long>(heartbeats),
                    static_cast<unsigned long long>(c.heartbeats_rejected));
    publish_event(t_ns, hq_msgs_SEVERITY_WARNING, EventCode::kHeartbeatsRejected, text);
  }
  reported_ = c;
  next_rejection_report_ns_ = t_ns + period_ns(1.0 / options_.rejection_report_period_s);
}

void LinkBridge::acknowledge(std::int64_t t_ns, const pipeline::ModeRequest& request,
                             const modes::ModeSwitch& result) {
  char text[hq_msgs_kMaxEventText + 1];
  const char* mode = modes::to_string(request.mode);
  if (request.marker) {
    const char* task = marker_modes::to_string(request.marker->task);
    const int id = request.marker->marker_id;
    if (result.accepted) {
      hq::format_into(text, "mode {} accepted: marker task {} on marker {}", mode, task, id);
      answer(t_ns, hq_msgs_SEVERITY_INFO, EventCode::kMarkerTaskAccepted, text, request.from_ros2);
    } else {
      hq::format_into(text, "mode {} with marker task {} on marker {} refused: {}", mode, task, id,
                      result.reason);
      answer(t_ns, hq_msgs_SEVERITY_WARNING, EventCode::kMarkerTaskRefused, text,
             request.from_ros2);
    }
    return;
  }
  if (result.accepted) {
    hq::format_into(text, "mode {} accepted", mode);
    answer(t_ns, hq_msgs_SEVERITY_INFO, EventCode::kModeAccepted, text, request.from_ros2);
  } else {
    hq::format_into(text, "mode {} refused: {}", mode, result.reason);
    answer(t_ns, hq_msgs_SEVERITY_WARNING, EventCode::kModeRefused, text, request.from_ros2);
  }
}

void LinkBridge::publish_event(std::int64_t t_ns, hq_msgs_Severity severity, EventCode code,
                               const char* text) {
  event_->sequence_number = ++event_sequence_;
  event_->t_ns = t_ns;
  event_->severity = severity;
  event_->code = static_cast<std::uint32_t>(code);
  event_->session_id = session_id();
  hq::format_into(event_->text, "{}", text);
  event_writer_.write(*event_);
}

bool LinkBridge::say_goodbye(std::int64_t t_ns, std::string_view reason,
                             std::int64_t ack_timeout_ns) {
  char text[sizeof event_->text];
  hq::format_into(text, "vehicle ended: {}", reason);
  publish_event(t_ns, hq_msgs_SEVERITY_INFO, EventCode::kVehicleEnded, text);
  return event_writer_.wait_for_acks(std::max<std::int64_t>(ack_timeout_ns, 0));
}

void LinkBridge::publish_state(const pipeline::ChainOutput& out, const StateExtras& extras) {
  const ObstacleCloudSource& cloud = extras.cloud;
  const FailsafeState& link_state = failsafe_.state();
  link::VehicleState& s = *state_;
  s.sequence_number = ++state_sequence_;
  s.t_ns = out.t_ns;
  s.v_H_mps = to_msg(out.estimate.v_H_mps);
  s.omega_B_radps = to_msg(out.estimate.omega_B_radps);
  s.roll_rad = static_cast<float>(out.estimate.roll_rad);
  s.pitch_rad = static_cast<float>(out.estimate.pitch_rad);
  s.v_obs_H_mps = to_msg(out.obstacles.v_obs_H_mps);
  // The command as flown after the seen-space limit, so the ground can show the cut
  // and render it.
  s.v_cmd_flown_H_mps = to_msg(out.v_cmd_flown_H_mps);
  s.mode = to_link_mode(out.mode.mode);
  s.estimator_health = out.safe_hover                                    ? hq_msgs_HEALTH_LOST
                       : (!out.estimate.ok() || extras.vehicle_degraded) ? hq_msgs_HEALTH_DEGRADED
                                                                         : hq_msgs_HEALTH_OK;
  s.link_health = link_state.heartbeat_lost ? hq_msgs_HEALTH_LOST
                  : link_state.hold         ? hq_msgs_HEALTH_DEGRADED
                                            : hq_msgs_HEALTH_OK;
  s.session_id = session_id();
  s.commanding_station_id = link_state.commanding_station_id;
  s.operator_input = operator_input(link_state, out.mode.mode, out.mode.landed);
  // A command the fail-safe lets through may still be cut by the envelope or the seen space.
  if (s.operator_input == hq_msgs_INPUT_FLOWN && out.command_envelope_limited) {
    s.operator_input = hq_msgs_INPUT_LIMITED_ENVELOPE;
  } else if (s.operator_input == hq_msgs_INPUT_FLOWN && out.command_limited) {
    s.operator_input = hq_msgs_INPUT_LIMITED_UNSEEN;
  }
  s.obstacle_points_B_m._length = 0;
  last_cloud_size_ = 0;
  if (cloud.memory != nullptr && options_.obstacle_cloud_rate_hz > 0.0 &&
      out.t_ns >= next_cloud_ns_ && cloud.T_O_B.matrix().allFinite()) {
    next_cloud_ns_ = out.t_ns + period_ns(options_.obstacle_cloud_rate_hz);
    // The map is in O; the IDL field is in B: p_B = T_B_O p_O. The memory strides its map down
    // to the buffer's size; a non-finite point (never expected) is dropped, not sent.
    const Eigen::Isometry3f T_B_O = cloud.T_O_B.inverse().cast<float>();
    const int n = cloud.memory->telemetry_cloud(cloud_O_m_);
    std::uint32_t count = 0;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector3f p_B_m = T_B_O * cloud_O_m_[static_cast<std::size_t>(i)];
      if (!p_B_m.allFinite()) continue;
      s.obstacle_points_B_m._buffer[count++] = {p_B_m.x(), p_B_m.y(), p_B_m.z()};
    }
    s.obstacle_points_B_m._length = count;
    last_cloud_size_ = static_cast<int>(count);
    ++clouds_sent_;
  }
  // Position, markers and truth come from outside the chain's output (the marker stage, the
  // simulator); a non-finite value goes out as absent rather than as garbage.
  s.position_valid =
      extras.position_valid && extras.p_W_m.allFinite() && std::isfinite(extras.yaw_rad);
  s.p_W_m = s.position_valid ? to_msg(extras.p_W_m) : hq_msgs_Vector3f{0.0F, 0.0F, 0.0F};
  s.yaw_W_rad = s.position_valid ? static_cast<float>(extras.yaw_rad) : 0.0F;
  s.position_invalid_reason =
      s.position_valid ? 0 : std::min<std::uint8_t>(extras.position_invalid_reason, 4);
  const auto bounded = [](double x) {
    return std::isfinite(x) ? static_cast<float>(std::clamp(x, 0.0, 1e6)) : 0.0F;
  };
  s.position_age_s = bounded(extras.position_age_s);
  s.position_sigma_m = bounded(extras.position_sigma_m);
  std::uint32_t markers = 0;
  for (const markers::MarkerDetection& d : extras.markers) {
    if (markers == hq_msgs_kMaxMarkersInState) break;
    const Eigen::Quaterniond q(d.T_camera_marker.linear());
    if (!d.T_camera_marker.matrix().allFinite()) continue;
    s.markers._buffer[markers++] = {d.id,
                                    to_msg(d.T_camera_marker.translation()),
                                    {static_cast<float>(q.w()), static_cast<float>(q.x()),
                                     static_cast<float>(q.y()), static_cast<float>(q.z())}};
  }
  s.markers._length = markers;
  s.flight_state = to_link_flight_state(out.flight_state);
  s.motors_armed = extras.motors_armed;
  // validate() rejects NaN: the chain never gives one, and a none source goes out as 0.
  const bool height_ok =
      out.height_source != pipeline::HeightSource::kNone && std::isfinite(out.height_m);
  s.height_source = !height_ok                                            ? hq_msgs_HEIGHT_NONE
                    : out.height_source == pipeline::HeightSource::kDepth ? hq_msgs_HEIGHT_DEPTH
                                                                          : hq_msgs_HEIGHT_ESTIMATE;
  s.height_m = height_ok ? static_cast<float>(out.height_m) : 0.0F;
  s.clearance_m = std::isfinite(out.clearance_m) ? static_cast<float>(out.clearance_m) : -1.0F;
  s.hover_thrust_gain =
      std::isfinite(out.hover_thrust.gain) ? static_cast<float>(out.hover_thrust.gain) : 0.0F;
  s.hover_thrust_converged = out.hover_thrust.converged;
  s.marker_target_valid = extras.marker_target_id >= 0;
  s.marker_target_id = std::max(extras.marker_target_id, 0);
  s.explore_phase = static_cast<std::uint8_t>(std::clamp(extras.explore_phase, 0, 7));
  s.modes_offered = extras.modes_offered & link::kModesOfferedMask;
  s.marker_mode_off_reason = extras.marker_mode_off_reason;
  s.explore_mode_off_reason = extras.explore_mode_off_reason;
  set_odom_fields(out, s);
  s.truth_valid = extras.truth_valid && extras.v_truth_H_mps.allFinite();
  s.v_truth_H_mps =
      s.truth_valid ? to_msg(extras.v_truth_H_mps) : hq_msgs_Vector3f{0.0F, 0.0F, 0.0F};
  state_writer_.write(s);
  if (ros2_ != nullptr) ros2_->publish_state(s);
}

bool LinkBridge::publish_camera(std::int64_t t_ns, const cv::Mat& image_bgr) {
  if (options_.camera_rate_hz <= 0.0 || t_ns < next_camera_ns_ || image_bgr.empty()) return false;
  next_camera_ns_ = t_ns + period_ns(options_.camera_rate_hz);
  if (!cv::imencode(".jpg", image_bgr, jpeg_, jpeg_params_)) return false;
  if (jpeg_.size() > hq_msgs_kMaxJpegBytes) return false;  // quality too high for the bound
  link::CameraFrame& f = *camera_;
  f.sequence_number = ++camera_sent_;
  f.t_ns = t_ns;
  f.width_px = static_cast<std::uint16_t>(image_bgr.cols);
  f.height_px = static_cast<std::uint16_t>(image_bgr.rows);
  std::memcpy(f.rgb_jpeg._buffer, jpeg_.data(), jpeg_.size());
  f.rgb_jpeg._length = static_cast<std::uint32_t>(jpeg_.size());
  f.depth_preview._length = 0;
  const bool sent = camera_writer_.write(f);
  if (ros2_ != nullptr) ros2_->publish_camera(f);  // the same JPEG bytes, no second encoding
  return sent;
}

}  // namespace hq::link_bridge
