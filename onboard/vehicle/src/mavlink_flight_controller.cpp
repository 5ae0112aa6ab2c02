#include "hq/vehicle/mavlink_flight_controller.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <numbers>
#include <optional>
#include <string_view>

namespace hq::vehicle {
namespace {

namespace ml = mavlink;

// A jump of the receipt-minus-stamp offset larger than any plausible transport delay: the FC
// rebooted (its boot clock restarted) or the link stalled; the window starts afresh.
constexpr std::int64_t kOffsetJumpNs = 50'000'000;
// At most this many datagrams or reads per poll(), so a flood cannot hold the loop.
constexpr int kMaxReadsPerPoll = 1000;
// TIMESYNC: the filter averages the first kTimesyncWarmup answers, then follows with weight
// kTimesyncAlpha (a time constant of 20 answers, 2 s at 10 Hz); an answer farther than
// kTimesyncOutlierNs from the offset is dropped, unless kTimesyncResetAfter come in a row
// (the FC rebooted: its clock restarted), which restarts the filter.
constexpr std::uint64_t kTimesyncWarmup = 5;
constexpr double kTimesyncAlpha = 0.05;
constexpr double kTimesyncOutlierNs = 5e6;
constexpr int kTimesyncResetAfter = 5;
// A setpoint gap longer than this integrates no yaw (a stall must not turn the vehicle).
constexpr double kMaxYawStepS = 0.1;

using ml::kMavTypeGcs;
constexpr std::uint32_t kSetModeId = 11;  // SET_MODE, deprecated but still sent by some GCSs
constexpr std::uint8_t kMavSeverityError = 3;
constexpr std::uint8_t kMavSeverityWarning = 4;

// ODOMETRY quality (common.xml: 1 worst .. 100 best): a tracked velocity scores 50..100 with its
// standard deviation (100 at or below kQualitySigmaMps, 50 at twice it and worse), an IMU coast
// 1..49 likewise: it is the FC's own IMU integrated, which PX4 can be told to skip
// (EKF2_EV_QMIN = 50).
constexpr double kQualitySigmaMps = 0.1;

std::int8_t odometry_quality(const VelocityReport& report, const Eigen::Matrix3d& covariance) {
  const double sigma_mps = std::sqrt(std::max(covariance.diagonal().maxCoeff(), 0.0));
  const double score =
      std::clamp(kQualitySigmaMps / std::max(sigma_mps, 1e-9), 0.5, 1.0);  // 0.5 .. 1
  const double quality = report.source == VelocitySource::kOdometry
                             ? 100.0 * score
                             : std::max(1.0, 49.0 * (2.0 * score - 1.0));
  return static_cast<std::int8_t>(std::lround(quality));
}

double wrap_pi(double angle_rad) { return std::remainder(angle_rad, 2.0 * std::numbers::pi); }

const char* command_name(std::uint16_t command) {
  switch (command) {
    case ml::kMavCmdDoSetMode:
      return "MAV_CMD_DO_SET_MODE";
    case ml::kMavCmdComponentArmDisarm:
      return "MAV_CMD_COMPONENT_ARM_DISARM";
    default:
      return "command";
  }
}

const char* autopilot_name(MavlinkFcConfig::Autopilot autopilot) {
  switch (autopilot) {
    case MavlinkFcConfig::Autopilot::kPx4:
      return "PX4";
    case MavlinkFcConfig::Autopilot::kArduPilot:
      return "ArduPilot";
    case MavlinkFcConfig::Autopilot::kAuto:
      break;
  }
  return "unknown autopilot";
}

}  // namespace

void MavlinkFcConfig::validate(const std::string& where) const {
  auto fail = [&](const char* key, const std::string& value, const char* expected) {
    throw InputError(where + key + " = " + value + ", expected " + expected);
  };
  auto text = [](double v) {
    char buf[32];
    hq::format_into(buf, "{:g}", v);
    return std::string(buf);
  };
  if (transport.empty()) fail("transport", "\"\"", "a spec such as udp:127.0.0.1:14540");
  if (!gcs.empty() && gcs.rfind("udp:", 0) != 0 && gcs.rfind("udp-listen:", 0) != 0) {
    fail("gcs", "\"" + gcs + "\"", "\"\" (none), udp:HOST:PORT or udp-listen:[HOST:]PORT");
  }
  if (system_id == 0) fail("system_id", "0", "1..255");
  if (component_id == 0) fail("component_id", "0", "1..255");
  if (!(heartbeat_timeout_s > 0.0 && heartbeat_timeout_s <= 60.0)) {
    fail("heartbeat_timeout_s", text(heartbeat_timeout_s), "> 0 and <= 60");
  }
  if (!(heartbeat_rate_hz > 0.0 && heartbeat_rate_hz <= 50.0)) {
    fail("heartbeat_rate_hz", text(heartbeat_rate_hz), "> 0 and <= 50");
  }
  if (!(max_thrust_n > 0.0 && max_thrust_n <= 1e4)) {
    fail("max_thrust_n", text(max_thrust_n), "> 0 and <= 10000");
  }
  if (!(max_yaw_lead_rad > 0.0 && max_yaw_lead_rad <= std::numbers::pi)) {
    fail("max_yaw_lead_rad", text(max_yaw_lead_rad), "> 0 and <= pi");
  }
  if (!(imu_rate_hz >= 10.0 && imu_rate_hz <= 1000.0)) {
    fail("imu_rate_hz", text(imu_rate_hz), "in [10, 1000]");
  }
  if (!(timesync_rate_hz >= 0.0 && timesync_rate_hz <= 50.0)) {
    fail("timesync_rate_hz", text(timesync_rate_hz), ">= 0 and <= 50");
  }
  if (!(timesync_max_rtt_s > 0.0 && timesync_max_rtt_s <= 1.0)) {
    fail("timesync_max_rtt_s", text(timesync_max_rtt_s), "> 0 and <= 1");
  }
  if (velocity_message != VelocityMessage::kOdometry &&
      velocity_message != VelocityMessage::kVisionSpeedEstimate) {
    fail("velocity_message", std::to_string(static_cast<int>(velocity_message)),
         "odometry or vision_speed_estimate");
  }
}

std::optional<MavlinkFcConfig::VelocityMessage> parse_velocity_message(std::string_view name) {
  if (name == "odometry") return MavlinkFcConfig::VelocityMessage::kOdometry;
  if (name == "vision_speed_estimate")
    return MavlinkFcConfig::VelocityMessage::kVisionSpeedEstimate;
  return std::nullopt;
}

void read_config(config::StrictMap& section, MavlinkFcConfig& out) {
  section.read("transport", out.transport, {});
  section.read("gcs", out.gcs, {});
  int system_id = out.system_id;
  int component_id = out.component_id;
  section.read("system_id", system_id, 1, 255);
  section.read("component_id", component_id, 1, 255);
  out.system_id = static_cast<std::uint8_t>(system_id);
  out.component_id = static_cast<std::uint8_t>(component_id);
  section.read_positive("heartbeat_timeout_s", out.heartbeat_timeout_s, 60.0);
  section.read_positive("heartbeat_rate_hz", out.heartbeat_rate_hz, 50.0);
  section.read_positive("max_thrust_n", out.max_thrust_n, 1e4);
  std::string autopilot = out.autopilot == MavlinkFcConfig::Autopilot::kPx4         ? "px4"
                          : out.autopilot == MavlinkFcConfig::Autopilot::kArduPilot ? "ardupilot"
                                                                                    : "auto";
  section.read("autopilot", autopilot, {"auto", "px4", "ardupilot"});
  out.autopilot = autopilot == "px4"         ? MavlinkFcConfig::Autopilot::kPx4
                  : autopilot == "ardupilot" ? MavlinkFcConfig::Autopilot::kArduPilot
                                             : MavlinkFcConfig::Autopilot::kAuto;
  section.read_positive("max_yaw_lead_rad", out.max_yaw_lead_rad, std::numbers::pi);
  section.read_positive("imu_rate_hz", out.imu_rate_hz, 1000.0);
  std::string velocity_message = out.velocity_message == MavlinkFcConfig::VelocityMessage::kOdometry
                                     ? "odometry"
                                     : "vision_speed_estimate";
  section.read("velocity_message", velocity_message, {"odometry", "vision_speed_estimate"});
  section.read("timesync_rate_hz", out.timesync_rate_hz, 0.0, 50.0);
  section.read_positive("timesync_max_rtt_s", out.timesync_max_rtt_s, 1.0);
  out.velocity_message = *parse_velocity_message(velocity_message);
  section.finish();
  // The key path without a key, e.g. "config/onboard.yaml: mavlink.", for the same messages.
  const std::string path = section.describe("transport");
  out.validate(path.substr(0, path.size() - std::string_view("transport").size()));
}

std::string gcs_transport_spec(const std::string& gcs) {
  const std::string listen = "udp-listen:";
  if (gcs.rfind(listen, 0) == 0 && gcs.find(':', listen.size()) == std::string::npos) {
    return listen + "0.0.0.0:" + gcs.substr(listen.size());
  }
  return gcs;
}

MavlinkFlightController::MavlinkFlightController(const MavlinkFcConfig& config)
    : MavlinkFlightController(config, (config.validate(), ml::open_transport(config.transport))) {}

MavlinkFlightController::MavlinkFlightController(const MavlinkFcConfig& config,
                                                 std::unique_ptr<ml::Transport> transport)
    : config_(config),
      transport_(std::move(transport)),
      encoder_(config.system_id, config.component_id) {
  config_.validate();
  if (!transport_) throw InputError("MavlinkFlightController: no transport");
  if (!config_.gcs.empty()) gcs_ = ml::open_transport(gcs_transport_spec(config_.gcs));
}

void MavlinkFlightController::emit(FcSink& sink, FcSeverity severity, std::size_t length) {
  sink.on_fc_event(severity, std::string_view(text_.data(), std::min(length, text_.size() - 1)));
}

bool MavlinkFlightController::send(const ml::Message& message) {
  const std::size_t n = encoder_.encode(message, tx_);
  const std::span<const std::uint8_t> bytes(tx_.data(), n);
  const bool sent = transport_->send(bytes);
  if (sent) {
    ++counters_.messages_sent;
  } else {
    ++counters_.send_failures;
  }
  if (gcs_) {
    // The FC always gets our frames directly, routed or not; the router decides the GCS's copy.
    ml::RawFrame frame;
    frame.bytes = bytes;
    frame.header.system_id = config_.system_id;
    frame.header.component_id = config_.component_id;
    frame.header.message_id = static_cast<std::uint32_t>(tx_[7] | (tx_[8] << 8) | (tx_[9] << 16));
    frame.crc_checked = true;
    forward(kLinkCompanion, frame);
  }
  return sent;
}

void MavlinkFlightController::forward(std::size_t from, const ml::RawFrame& frame) {
  const ml::LinkMask to = router_.route(from, frame);
  if ((to & ml::link_bit(kLinkGcs)) != 0) {
    // udp-listen before the GCS spoke: nowhere to send, and no error text to write per frame.
    if (gcs_->has_peer() && gcs_->send(frame.bytes)) {
      ++sent_[from][kLinkGcs];
    } else {
      ++gcs_send_failures_;
    }
  }
  if (from != kLinkCompanion && (to & ml::link_bit(kLinkFc)) != 0) {
    if (transport_->send(frame.bytes)) {
      ++sent_[from][kLinkFc];
    } else {
      ++fc_forward_failures_;
    }
  }
}

void MavlinkFlightController::poll_gcs(FcSink& sink) {
  const bool datagrams = gcs_->datagrams();
  auto on_message = [&](const ml::FrameHeader& header, const ml::Message& message) {
    if (const auto* hb = std::get_if<ml::Heartbeat>(&message);
        hb != nullptr && hb->type == kMavTypeGcs && gcs_system_ != header.system_id) {
      gcs_system_ = header.system_id;
      event(sink, FcSeverity::kInfo, "GCS heard: system {}, component {}", header.system_id,
            header.component_id);
    }
    // The pilot keeps authority through the GCS too: the FC obeys, the runtime sees the FC's
    // new mode in its heartbeat and reports it as for the RC; this says who asked.
    if (const auto* cmd = std::get_if<ml::CommandLong>(&message);
        cmd != nullptr &&
        (cmd->command == ml::kMavCmdDoSetMode || cmd->command == ml::kMavCmdComponentArmDisarm)) {
      event(sink, FcSeverity::kWarning,
            "GCS (system {}) sent {} (param1 {:g}, param2 {:g}) to the FC", header.system_id,
            command_name(cmd->command), static_cast<double>(cmd->param[0]),
            static_cast<double>(cmd->param[1]));
    }
  };
  auto on_frame = [&](const ml::RawFrame& frame) {
    if (frame.header.message_id == kSetModeId) {
      event(sink, FcSeverity::kWarning, "GCS (system {}) sent SET_MODE to the FC",
            frame.header.system_id);
    }
    forward(kLinkGcs, frame);
  };
  for (int i = 0; i < kMaxReadsPerPoll; ++i) {
    const std::size_t n = gcs_->receive(rx_);
    if (n == 0) break;
    gcs_parser_.feed(std::span<const std::uint8_t>(rx_.data(), n), on_message, on_frame);
    if (datagrams) gcs_parser_.end_of_datagram();
  }
}

void MavlinkFlightController::poll(std::int64_t t_ns, FcSink& sink) {
  // Our heartbeat first, from the very first poll: a listening SITL learns our address from it.
  const auto period_ns = static_cast<std::int64_t>(1e9 / config_.heartbeat_rate_hz);
  if (!sent_first_heartbeat_ || t_ns - last_heartbeat_sent_ns_ >= period_ns) {
    ml::Heartbeat hb;
    hb.type = ml::kMavTypeOnboardController;
    hb.autopilot = ml::kMavAutopilotInvalid;
    hb.system_status = ml::kMavStateActive;
    send(hb);
    sent_first_heartbeat_ = true;
    last_heartbeat_sent_ns_ = t_ns;
  }

  if (config_.timesync_rate_hz > 0.0 &&
      (last_timesync_sent_ns_ < 0 ||
       static_cast<double>(t_ns - last_timesync_sent_ns_) >= 1e9 / config_.timesync_rate_hz)) {
    ml::Timesync request;
    request.tc1_ns = 0;
    request.ts1_ns = t_ns;
    request.target_system = target_system_;  // 0 (broadcast) until the FC is heard
    request.target_component = target_component_;
    if (send(request)) timesync_pending_ts1_ns_ = t_ns;
    last_timesync_sent_ns_ = t_ns;
  }

  const bool datagrams = transport_->datagrams();
  for (int i = 0; i < kMaxReadsPerPoll; ++i) {
    const std::size_t n = transport_->receive(rx_);
    if (n == 0) break;
    parser_.feed(
        std::span<const std::uint8_t>(rx_.data(), n),
        [&](const ml::FrameHeader& header, const ml::Message& message) {
          handle(t_ns, header, message, sink);
        },
        [&](const ml::RawFrame& frame) {
          if (gcs_) forward(kLinkFc, frame);
        });
    if (datagrams) parser_.end_of_datagram();
  }
  if (gcs_) poll_gcs(sink);

  // State changes, each said once.
  const bool is_connected = connected(t_ns);
  if (is_connected != said_connected_) {
    said_connected_ = is_connected;
    if (is_connected) {
      event(sink, FcSeverity::kInfo, "FC connected: {}, system {}, component {}",
            autopilot_name(autopilot()), target_system_, target_component_);
    } else {
      event(sink, FcSeverity::kError, "FC silent: nothing heard for {:.1f} s",
            static_cast<double>(t_ns - last_heard_ns_) * 1e-9);
    }
  }
  if (armed_ != said_armed_) {
    said_armed_ = armed_;
    event(sink, armed_ ? FcSeverity::kInfo : FcSeverity::kWarning, "FC {}",
          armed_ ? "armed" : "disarmed");
  }
  if (offboard_ != said_offboard_) {
    said_offboard_ = offboard_;
    event(sink, offboard_ ? FcSeverity::kInfo : FcSeverity::kWarning, "FC {}",
          offboard_ ? "entered offboard mode" : "left offboard mode");
  }
  if (is_connected && autopilot() == Autopilot::kArduPilot && !said_ardupilot_odometry_ &&
      config_.velocity_message == MavlinkFcConfig::VelocityMessage::kOdometry) {
    said_ardupilot_odometry_ = true;
    event(sink, FcSeverity::kWarning, "{}",
          "ArduPilot takes ODOMETRY's pose too and HaptiQuad sends none: fly it with "
          "--fc-velocity-message vision_speed_estimate");
  }
  if (pending_no_autopilot_) {
    pending_no_autopilot_ = false;
    event(sink, FcSeverity::kError, "{}",
          "arm/offboard request not sent: autopilot unknown (no FC heartbeat yet)");
  }
}

void MavlinkFlightController::handle(std::int64_t t_ns, const ml::FrameHeader& header,
                                     const ml::Message& message, FcSink& sink) {
  if (header.system_id == config_.system_id && header.component_id == config_.component_id) {
    return;  // our own frames, echoed by a broadcast or a loop
  }
  if (const auto* hb = std::get_if<ml::Heartbeat>(&message)) {
    handle_heartbeat(t_ns, header, *hb);
    return;
  }
  // Data only from the FC once known; before that from anyone (IMU may precede the heartbeat).
  if (have_target_ && header.system_id != target_system_) return;
  if (have_target_) last_heard_ns_ = t_ns;

  if (const auto* ts = std::get_if<ml::Timesync>(&message)) {
    handle_timesync(t_ns, header, *ts);
  } else if (const auto* imu = std::get_if<ml::HighresImu>(&message)) {
    const auto fc_stamp_ns = static_cast<std::int64_t>(imu->time_usec) * 1000;
    update_clock(t_ns, fc_stamp_ns);
    FcImuSample sample;
    sample.t_ns = fc_stamp_ns + clock_offset_ns();
    if (have_imu_ && sample.t_ns <= last_imu_t_ns_) return;  // stamps in order, or not at all
    sample.omega_B_radps = Eigen::Vector3d(imu->xgyro_radps, imu->ygyro_radps, imu->zgyro_radps);
    sample.f_B_mps2 = Eigen::Vector3d(imu->xacc_mps2, imu->yacc_mps2, imu->zacc_mps2);
    if (!sample.omega_B_radps.allFinite() || !sample.f_B_mps2.allFinite()) return;
    have_imu_ = true;
    last_imu_t_ns_ = sample.t_ns;
    ++counters_.imu_samples;
    sink.on_imu(sample);
  } else if (const auto* att = std::get_if<ml::Attitude>(&message)) {
    if (!std::isfinite(att->roll_rad) || !std::isfinite(att->pitch_rad) ||
        !std::isfinite(att->yaw_rad)) {
      return;
    }
    FcAttitude attitude;
    attitude.t_ns =
        have_offset_ ? static_cast<std::int64_t>(att->time_boot_ms) * 1'000'000 + clock_offset_ns()
                     : t_ns;
    attitude.roll_rad = att->roll_rad;
    attitude.pitch_rad = att->pitch_rad;
    attitude.yaw_rad = att->yaw_rad;
    fc_yaw_rad_ = att->yaw_rad;
    have_fc_yaw_ = true;
    sink.on_attitude(attitude);
  } else if (const auto* sys = std::get_if<ml::SysStatus>(&message)) {
    battery_v_ = sys->voltage_battery_mv == UINT16_MAX ? -1.0 : sys->voltage_battery_mv * 1e-3;
    battery_pct_ = sys->battery_remaining_pct < 0 ? -1 : sys->battery_remaining_pct;
  } else if (const auto* st = std::get_if<ml::Statustext>(&message)) {
    const FcSeverity severity = st->severity <= kMavSeverityError     ? FcSeverity::kError
                                : st->severity == kMavSeverityWarning ? FcSeverity::kWarning
                                                                      : FcSeverity::kInfo;
    sink.on_fc_event(severity,
                     std::string_view(st->text.data(), strnlen(st->text.data(), st->text.size())));
  } else if (const auto* ack = std::get_if<ml::CommandAck>(&message)) {
    const bool for_us = ack->target_system == 0 || ack->target_system == config_.system_id;
    if (for_us && ack->result != ml::kMavResultAccepted) {
      event(sink, FcSeverity::kError, "FC refused {} ({}): result {}", command_name(ack->command),
            ack->command, ack->result);
    }
  }
}

void MavlinkFlightController::handle_heartbeat(std::int64_t t_ns, const ml::FrameHeader& header,
                                               const ml::Heartbeat& hb) {
  // Only an autopilot: not a GCS, not another companion computer, not a camera.
  if (hb.autopilot == ml::kMavAutopilotInvalid || hb.type == kMavTypeGcs ||
      hb.type == ml::kMavTypeOnboardController) {
    return;
  }
  if (!have_target_) {
    have_target_ = true;
    target_system_ = header.system_id;
    target_component_ = header.component_id;
  } else if (header.system_id != target_system_ || header.component_id != target_component_) {
    return;
  }
  heard_autopilot_ = hb.autopilot == ml::kMavAutopilotPx4             ? Autopilot::kPx4
                     : hb.autopilot == ml::kMavAutopilotArdupilotMega ? Autopilot::kArduPilot
                                                                      : Autopilot::kAuto;
  armed_ = (hb.base_mode & ml::kMavModeFlagSafetyArmed) != 0;
  switch (autopilot()) {
    case Autopilot::kPx4:
      offboard_ = ((hb.custom_mode >> 16) & 0xFF) == ml::kPx4MainModeOffboard;
      break;
    case Autopilot::kArduPilot:
      offboard_ = hb.custom_mode == ml::kArduCopterModeGuidedNoGps;
      break;
    case Autopilot::kAuto:
      offboard_ = false;
      break;
  }
  last_heartbeat_ns_ = t_ns;
  last_heard_ns_ = t_ns;
  if (!requested_streams_) {
    // ArduPilot streams nothing on a companion's port until asked, and PX4's onboard profile
    // sends HIGHRES_IMU slower than the chain wants: ask for the IMU and attitude rates once.
    requested_streams_ = true;
    send_command(ml::kMavCmdSetMessageInterval, static_cast<float>(ml::HighresImu::kId),
                 static_cast<float>(1e6 / config_.imu_rate_hz));
    send_command(ml::kMavCmdSetMessageInterval, static_cast<float>(ml::Attitude::kId),
                 static_cast<float>(1e6 / 50.0));
  }
}

void MavlinkFlightController::update_clock(std::int64_t t_ns, std::int64_t fc_stamp_ns) {
  const std::int64_t offset = t_ns - fc_stamp_ns;
  if (have_offset_ && std::llabs(offset - offset_ns_) > kOffsetJumpNs) {
    offsets_count_ = 0;  // the FC rebooted (or the link stalled): forget the old clock
    offsets_next_ = 0;
  }
  offsets_ns_[offsets_next_] = offset;
  offsets_next_ = (offsets_next_ + 1) % kOffsetWindow;
  offsets_count_ = std::min(offsets_count_ + 1, kOffsetWindow);
  offset_ns_ = *std::min_element(offsets_ns_.begin(),
                                 offsets_ns_.begin() + static_cast<std::ptrdiff_t>(offsets_count_));
  have_offset_ = true;
}

void MavlinkFlightController::handle_timesync(std::int64_t t_ns, const ml::FrameHeader& header,
                                              const ml::Timesync& ts) {
  const bool for_us =
      (ts.target_system == 0 && ts.target_component == 0) ||
      (ts.target_system == config_.system_id && ts.target_component == config_.component_id);
  if (!for_us) return;
  if (ts.tc1_ns == 0) {
    // The FC's own request (PX4 sends them too): answered with our clock, ts1 echoed.
    ml::Timesync answer;
    answer.tc1_ns = t_ns;
    answer.ts1_ns = ts.ts1_ns;
    answer.target_system = header.system_id;
    answer.target_component = header.component_id;
    send(answer);
    return;
  }
  // An answer to our last request only (an older protocol's answer has no targets; the echoed
  // stamp tells it is ours).
  if (ts.ts1_ns != timesync_pending_ts1_ns_) return;
  timesync_pending_ts1_ns_ = -1;
  const std::int64_t rtt_ns = t_ns - ts.ts1_ns;
  if (rtt_ns < 0 || static_cast<double>(rtt_ns) > config_.timesync_max_rtt_s * 1e9) {
    ++counters_.timesync_rejected;
    return;
  }
  // Our clock at the answer's moment, the middle of the round trip, minus the FC's.
  const double sample_ns = 0.5 * (static_cast<double>(ts.ts1_ns) + static_cast<double>(t_ns)) -
                           static_cast<double>(ts.tc1_ns);
  const std::uint64_t n = counters_.timesync_samples;
  if (n >= kTimesyncWarmup && std::abs(sample_ns - timesync_offset_ns_) > kTimesyncOutlierNs) {
    ++counters_.timesync_rejected;
    if (++timesync_far_in_a_row_ < kTimesyncResetAfter) return;
    counters_.timesync_samples = 0;  // the FC's clock jumped: start again
    timesync_variance_ns2_ = 0.0;
  }
  timesync_far_in_a_row_ = 0;
  const std::uint64_t k = counters_.timesync_samples;
  const double weight = k < kTimesyncWarmup ? 1.0 / static_cast<double>(k + 1) : kTimesyncAlpha;
  const double deviation_ns = sample_ns - (k == 0 ? sample_ns : timesync_offset_ns_);
  timesync_offset_ns_ = k == 0 ? sample_ns : timesync_offset_ns_ + weight * deviation_ns;
  timesync_variance_ns2_ += weight * (deviation_ns * deviation_ns - timesync_variance_ns2_);
  ++counters_.timesync_samples;
  counters_.timesync_rtt_ns = rtt_ns;
  counters_.timesync_offset_ns = std::llround(timesync_offset_ns_);
  counters_.timesync_jitter_ns = std::sqrt(timesync_variance_ns2_);
  counters_.clock_from_timesync = counters_.timesync_samples >= kTimesyncWarmup;
  if (counters_.clock_from_timesync) have_offset_ = true;
}

std::int64_t MavlinkFlightController::clock_offset_ns() const {
  return counters_.clock_from_timesync ? counters_.timesync_offset_ns : offset_ns_;
}

std::int64_t MavlinkFlightController::fc_time_ns(std::int64_t t_ns) const {
  return have_offset_ ? std::max<std::int64_t>(0, t_ns - clock_offset_ns()) : 0;
}

bool MavlinkFlightController::connected(std::int64_t t_ns) const {
  // Any message from the FC counts, not only its 1 Hz heartbeat: a 1 s timeout on a 1 Hz
  // heartbeat alone would raise false alarms on every late one.
  return last_heartbeat_ns_ >= 0 &&
         static_cast<double>(t_ns - last_heard_ns_) <= config_.heartbeat_timeout_s * 1e9;
}

MavlinkFcConfig::Autopilot MavlinkFlightController::autopilot() const {
  return config_.autopilot != Autopilot::kAuto ? config_.autopilot : heard_autopilot_;
}

void MavlinkFlightController::send_setpoint(std::int64_t t_ns,
                                            const control::AttitudeSetpoint& setpoint) {
  if (!std::isfinite(setpoint.thrust_n) || !std::isfinite(setpoint.roll_rad) ||
      !std::isfinite(setpoint.pitch_rad) || !std::isfinite(setpoint.yaw_rate_radps) ||
      !have_target_) {
    ++counters_.send_failures;
    return;
  }
  // The commanded yaw: held at the FC's own yaw until it flies our setpoints, then integrated
  // from the commanded rate, never leading the FC's yaw by more than max_yaw_lead_rad.
  const bool flying_ours = armed_ && offboard_;
  if (!flying_ours || !yaw_integrating_) {
    yaw_target_rad_ = have_fc_yaw_ ? fc_yaw_rad_ : 0.0;
  } else {
    const double dt_s =
        std::clamp(static_cast<double>(t_ns - last_setpoint_ns_) * 1e-9, 0.0, kMaxYawStepS);
    yaw_target_rad_ += setpoint.yaw_rate_radps * dt_s;
  }
  yaw_integrating_ = flying_ours;
  last_setpoint_ns_ = t_ns;
  if (have_fc_yaw_) {
    const double lead = std::clamp(wrap_pi(yaw_target_rad_ - fc_yaw_rad_),
                                   -config_.max_yaw_lead_rad, config_.max_yaw_lead_rad);
    yaw_target_rad_ = fc_yaw_rad_ + lead;
  }
  yaw_target_rad_ = wrap_pi(yaw_target_rad_);

  const Eigen::Quaterniond q_NED_B =
      Eigen::AngleAxisd(yaw_target_rad_, Eigen::Vector3d::UnitZ()) *
      Eigen::AngleAxisd(setpoint.pitch_rad, Eigen::Vector3d::UnitY()) *
      Eigen::AngleAxisd(setpoint.roll_rad, Eigen::Vector3d::UnitX());
  ml::SetAttitudeTarget target;
  target.time_boot_ms = static_cast<std::uint32_t>(fc_time_ns(t_ns) / 1'000'000);
  target.q = {static_cast<float>(q_NED_B.w()), static_cast<float>(q_NED_B.x()),
              static_cast<float>(q_NED_B.y()), static_cast<float>(q_NED_B.z())};
  target.body_roll_rate_radps = 0.0f;
  target.body_pitch_rate_radps = 0.0f;
  target.body_yaw_rate_radps = static_cast<float>(setpoint.yaw_rate_radps);
  target.thrust =
      static_cast<float>(std::clamp(setpoint.thrust_n / config_.max_thrust_n, 0.0, 1.0));
  target.target_system = target_system_;
  target.target_component = target_component_;
  target.type_mask = ml::kAttitudeTargetIgnoreBodyRollRate | ml::kAttitudeTargetIgnoreBodyPitchRate;
  if (send(target)) ++counters_.setpoints_sent;
}

void MavlinkFlightController::send_velocity(const VelocityReport& report) {
  const Eigen::Matrix3d& covariance_H = report.covariance_H_m2ps2;
  if (!report.v_H_mps.allFinite() || !covariance_H.allFinite() || !std::isfinite(report.roll_rad) ||
      !std::isfinite(report.pitch_rad) || covariance_H.diagonal().minCoeff() < 0.0) {
    ++counters_.send_failures;
    return;
  }
  const auto usec = static_cast<std::uint64_t>(fc_time_ns(report.t_ns) / 1000);
  if (config_.velocity_message == MavlinkFcConfig::VelocityMessage::kVisionSpeedEstimate) {
    // H is the yaw-only frame of the body: NED = Rz(yaw) H.
    const Eigen::Matrix3d R_NED_H =
        Eigen::AngleAxisd(have_fc_yaw_ ? fc_yaw_rad_ : 0.0, Eigen::Vector3d::UnitZ())
            .toRotationMatrix();
    const Eigen::Vector3d v_NED_mps = R_NED_H * report.v_H_mps;
    const Eigen::Matrix3d covariance_NED = R_NED_H * covariance_H * R_NED_H.transpose();
    ml::VisionSpeedEstimate estimate;
    estimate.usec = usec;
    estimate.x_mps = static_cast<float>(v_NED_mps.x());
    estimate.y_mps = static_cast<float>(v_NED_mps.y());
    estimate.z_mps = static_cast<float>(v_NED_mps.z());
    for (Eigen::Index r = 0; r < 3; ++r) {
      for (Eigen::Index c = 0; c < 3; ++c) {
        estimate.covariance[static_cast<std::size_t>(3 * r + c)] =
            static_cast<float>(covariance_NED(r, c));
      }
    }
    estimate.reset_counter = report.reset_counter;
    if (send(estimate)) ++counters_.velocity_reports_sent;
    return;
  }
  // v_H = R_H_B v_B with R_H_B = Ry(pitch) Rx(roll) (eq. 5 of the core paper): the body FRD
  // velocity EKF2 rotates with its own attitude (VELOCITY_FRAME_BODY_FRD).
  const Eigen::Matrix3d R_H_B = (Eigen::AngleAxisd(report.pitch_rad, Eigen::Vector3d::UnitY()) *
                                 Eigen::AngleAxisd(report.roll_rad, Eigen::Vector3d::UnitX()))
                                    .toRotationMatrix();
  const Eigen::Vector3d v_B_mps = R_H_B.transpose() * report.v_H_mps;
  const Eigen::Matrix3d covariance_B = R_H_B.transpose() * covariance_H * R_H_B;
  constexpr float kUnknown = std::numeric_limits<float>::quiet_NaN();
  ml::Odometry odometry;
  odometry.time_usec = usec;
  // A velocity-only source: no pose (NaN position, orientation and pose covariance), which PX4's
  // receiver leaves unset while it still takes the velocity.
  odometry.x_m = odometry.y_m = odometry.z_m = kUnknown;
  odometry.q.fill(kUnknown);
  odometry.pose_covariance.fill(kUnknown);
  odometry.vx_mps = static_cast<float>(v_B_mps.x());
  odometry.vy_mps = static_cast<float>(v_B_mps.y());
  odometry.vz_mps = static_cast<float>(v_B_mps.z());
  odometry.rollspeed_radps = odometry.pitchspeed_radps = odometry.yawspeed_radps = kUnknown;
  odometry.velocity_covariance.fill(kUnknown);  // the rates' rows and columns: unknown
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = r; c < 3; ++c) {
      odometry.velocity_covariance[ml::upper_triangle_index(r, c)] = static_cast<float>(
          covariance_B(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)));
    }
  }
  odometry.frame_id = ml::kMavFrameLocalFrd;
  odometry.child_frame_id = ml::kMavFrameBodyFrd;
  odometry.reset_counter = report.reset_counter;
  odometry.estimator_type = ml::kMavEstimatorTypeVio;
  odometry.quality_pct = odometry_quality(report, covariance_B);
  if (send(odometry)) ++counters_.velocity_reports_sent;
}

void MavlinkFlightController::send_command(std::uint16_t command, float param1, float param2) {
  ml::CommandLong cmd;
  cmd.command = command;
  cmd.param[0] = param1;
  cmd.param[1] = param2;
  cmd.target_system = target_system_;
  cmd.target_component = target_component_;
  send(cmd);
}

void MavlinkFlightController::request_arm_offboard(std::int64_t /*t_ns*/) {
  const Autopilot ap = autopilot();
  if (ap == Autopilot::kAuto || !have_target_) {
    ++counters_.send_failures;
    pending_no_autopilot_ = true;
    return;
  }
  // MAV_CMD_DO_SET_MODE: param1 = MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, param2 = the custom main
  // mode (PX4 OFFBOARD 6; ArduCopter GUIDED_NOGPS 20).
  const float mode = ap == Autopilot::kPx4 ? static_cast<float>(ml::kPx4MainModeOffboard)
                                           : static_cast<float>(ml::kArduCopterModeGuidedNoGps);
  send_command(ml::kMavCmdDoSetMode, static_cast<float>(ml::kMavModeFlagCustomModeEnabled), mode);
  send_command(ml::kMavCmdComponentArmDisarm, 1.0f, 0.0f);
}

void MavlinkFlightController::request_disarm(std::int64_t /*t_ns*/) {
  if (!have_target_) {
    ++counters_.send_failures;
    return;
  }
  send_command(ml::kMavCmdComponentArmDisarm, 0.0f, 0.0f);
}

FcStatus MavlinkFlightController::status(std::int64_t t_ns) const {
  FcStatus s;
  s.connected = connected(t_ns);
  s.armed = armed_;
  s.offboard = offboard_;
  s.heartbeat_age_ns = last_heard_ns_ >= 0 ? t_ns - last_heard_ns_ : -1;
  s.battery_v = battery_v_;
  s.battery_pct = battery_pct_;
  return s;
}

FcCounters MavlinkFlightController::counters() const {
  FcCounters c = counters_;
  c.messages_received = parser_.counters().frames;
  c.frames_dropped = parser_.counters().dropped();
  return c;
}

std::string MavlinkFlightController::describe() const {
  return "MAVLink " + transport_->describe() + " (" + autopilot_name(autopilot()) + ", system " +
         std::to_string(have_target_ ? target_system_ : config_.system_id) + ")" +
         (gcs_ ? ", routed to a GCS " + gcs_->describe() : "");
}

std::optional<GcsRouting> MavlinkFlightController::gcs_routing() const {
  if (!gcs_) return std::nullopt;
  GcsRouting r;
  r.spec = config_.gcs;
  r.peer = gcs_->peer();
  r.gcs_system = gcs_system_;
  r.fc_to_gcs = sent_[kLinkFc][kLinkGcs];
  r.gcs_to_fc = sent_[kLinkGcs][kLinkFc];
  r.companion_to_gcs = sent_[kLinkCompanion][kLinkGcs];
  r.gcs_send_failures = gcs_send_failures_;
  r.fc_send_failures = fc_forward_failures_;
  r.router = router_.counters();
  r.gcs_parser = gcs_parser_.counters();
  return r;
}

}  // namespace hq::vehicle
