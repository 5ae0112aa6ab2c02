#include "hq/sitl/sitl_autopilot.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <string_view>

namespace hq::sitl {

// The simulator this flight controller flies: its state, IMU and commands.
using sim::AttitudeCommand;
using sim::ImuSample;
using sim::QuadrotorParams;
using sim::TruthState;

namespace {

constexpr double kGravityMps2 = 9.81;
constexpr std::uint8_t kSeverityCritical = 2;
constexpr std::uint8_t kSeverityWarning = 4;
constexpr std::uint8_t kSeverityInfo = 6;
constexpr std::uint8_t kResultTemporarilyRejected = 1;
constexpr std::uint8_t kResultDenied = 2;
constexpr std::uint8_t kResultUnsupported = 3;
constexpr std::uint32_t kPx4MainPosctl = 3;
constexpr std::uint32_t kPx4MainAuto = 4;
constexpr std::uint32_t kPx4AutoSubLand = 6;
/// MAV_CMD_COMPONENT_ARM_DISARM param2 that forces a disarm in the air.
constexpr float kForceDisarmMagic = 21196.0f;
/// HIGHRES_IMU fields_updated: xacc..zacc (bits 0-2), xgyro..zgyro (bits 3-5).
constexpr std::uint16_t kImuAccGyroFields = 0x3F;
/// A 4S battery: full, empty, and how fast the simulation drains it.
constexpr double kBatteryFullV = 16.8;
constexpr double kBatteryEmptyV = 14.0;
constexpr double kDrainIdleVps = 0.0005;
constexpr double kDrainArmedVps = 0.004;

// PX4's names and units for what SitlAutopilotConfig holds (docs.px4.io parameter reference),
// sorted by name as PX4 lists them; ranges within PX4's.
struct SitlParam {
  const char* id;
  double min, max;
  double SitlAutopilotConfig::*seconds_or_value;  // a double member, or
  std::int64_t SitlAutopilotConfig::*ns;          // a nanosecond member shown in seconds
};
constexpr std::array<SitlParam, kSitlParamCount> kParams{{
    {"COM_DISARM_LAND", 0.1, 20.0, nullptr, &SitlAutopilotConfig::landed_disarm_ns},
    {"COM_OBC_LOSS_T", 0.1, 60.0, nullptr, &SitlAutopilotConfig::companion_loss_ns},
    {"COM_OF_LOSS_T", 0.1, 60.0, nullptr, &SitlAutopilotConfig::offboard_loss_ns},
    {"MPC_LAND_SPEED", 0.1, 5.0, &SitlAutopilotConfig::land_speed_mps, nullptr},
    {"MPC_Z_VEL_P_ACC", 0.1, 20.0, &SitlAutopilotConfig::land_speed_gain_per_s, nullptr},
}};

int find_param(const std::array<char, 16>& id) {
  const std::string_view name(id.data(), strnlen(id.data(), id.size()));
  for (std::size_t i = 0; i < kParams.size(); ++i) {
    if (name == kParams[i].id) return static_cast<int>(i);
  }
  return -1;
}

bool for_us(std::uint8_t target_system, std::uint8_t target_component) {
  return (target_system == 0 || target_system == 1) &&
         (target_component == 0 || target_component == mavlink::kMavCompIdAutopilot1);
}

constexpr std::uint8_t kMavEstimatorTypeUnknown = 0;
constexpr std::uint8_t kMavEstimatorTypeVision = 2;

Eigen::Vector3d ned_from_world(const Eigen::Vector3d& v_W) {  // W is NWU
  return {v_W.x(), -v_W.y(), -v_W.z()};
}

Eigen::Matrix3d R_NED_B_of(const TruthState& truth) {  // euler_rad: B (FRD) in NED
  return (Eigen::AngleAxisd(truth.euler_rad.z(), Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(truth.euler_rad.y(), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(truth.euler_rad.x(), Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

bool finite(const mavlink::SetAttitudeTarget& t) {
  return std::isfinite(t.q[0]) && std::isfinite(t.q[1]) && std::isfinite(t.q[2]) &&
         std::isfinite(t.q[3]) && std::isfinite(t.body_yaw_rate_radps) && std::isfinite(t.thrust);
}

const char* mode_name(SitlMode mode) {
  switch (mode) {
    case SitlMode::kPosctl:
      return "POSCTL";
    case SitlMode::kOffboard:
      return "OFFBOARD";
    case SitlMode::kLand:
      return "LAND";
  }
  return "?";
}

}  // namespace

SitlAutopilot::SitlAutopilot(const QuadrotorParams& vehicle, const SitlAutopilotConfig& config)
    : config_(config),
      mass_kg_(vehicle.mass_kg),
      max_thrust_n_(4.0 * vehicle.thrust_coefficient * vehicle.max_rotor_speed_radps *
                    vehicle.max_rotor_speed_radps),
      vision_(config.vision),
      rng_(config.seed) {}

std::uint32_t SitlAutopilot::custom_mode() const {
  switch (mode_) {
    case SitlMode::kOffboard:
      return mavlink::kPx4MainModeOffboard << 16;
    case SitlMode::kLand:
      return kPx4MainAuto << 16 | kPx4AutoSubLand << 24;
    case SitlMode::kPosctl:
      break;
  }
  return kPx4MainPosctl << 16;
}

void SitlAutopilot::statustext(std::uint8_t severity, std::string_view text,
                               MessageSink& out) const {
  mavlink::Statustext s;
  s.severity = severity;
  std::memcpy(s.text.data(), text.data(), std::min(text.size(), s.text.size()));
  out.send(s);
}

void SitlAutopilot::ack(const mavlink::CommandLong& command, std::uint8_t result,
                        std::uint8_t system_id, std::uint8_t component_id, MessageSink& out) const {
  mavlink::CommandAck a;
  a.command = command.command;
  a.result = result;
  a.target_system = system_id;
  a.target_component = component_id;
  out.send(a);
}

void SitlAutopilot::set_mode(SitlMode mode, std::string_view why, MessageSink& out) {
  if (mode == mode_) return;
  mode_ = mode;
  statustext(mode == SitlMode::kLand ? kSeverityCritical : kSeverityInfo, why, out);
  send_heartbeat(out);  // as PX4 does: the new mode is seen at once, not within a second
}

void SitlAutopilot::set_armed(bool armed, std::string_view why, MessageSink& out) {
  if (armed == armed_) return;
  armed_ = armed;
  on_ground_since_ns_ = -1;
  statustext(kSeverityInfo, why, out);
  send_heartbeat(out);
}

void SitlAutopilot::send_heartbeat(MessageSink& out) const {
  mavlink::Heartbeat h;
  h.type = mavlink::kMavTypeQuadrotor;
  h.autopilot = mavlink::kMavAutopilotPx4;
  h.base_mode = mavlink::kMavModeFlagCustomModeEnabled |
                (armed_ ? mavlink::kMavModeFlagSafetyArmed : std::uint8_t{0});
  h.custom_mode = custom_mode();
  h.system_status = armed_ ? mavlink::kMavStateActive : mavlink::kMavStateStandby;
  out.send(h);
}

void SitlAutopilot::on_message(std::int64_t t_ns, std::uint8_t system_id, std::uint8_t component_id,
                               const mavlink::Message& message, const TruthState& truth,
                               MessageSink& out) {
  if (const auto* h = std::get_if<mavlink::Heartbeat>(&message)) {
    if (h->type == mavlink::kMavTypeOnboardController) last_companion_ns_ = t_ns;
    if (h->type == mavlink::kMavTypeGcs) {
      // A GCS that just connected sees the vehicle at once, not within a second.
      if (last_gcs_ns_ < 0) send_heartbeat(out);
      last_gcs_ns_ = t_ns;
      ++stats_.gcs_heartbeats;
    }
  } else if (std::holds_alternative<mavlink::ParamRequestList>(message) ||
             std::holds_alternative<mavlink::ParamRequestRead>(message) ||
             std::holds_alternative<mavlink::ParamSet>(message)) {
    handle_param(message, out);
  } else if (const auto* c = std::get_if<mavlink::CommandLong>(&message)) {
    // As PX4: a command for another system is not ours to ack.
    if (c->target_system != 0 && c->target_system != 1) return;
    handle_command(t_ns, system_id, component_id, *c, truth, out);
  } else if (const auto* s = std::get_if<mavlink::SetAttitudeTarget>(&message)) {
    if ((s->target_system != 0 && s->target_system != 1) || !finite(*s)) {
      ++stats_.setpoints_rejected;
      return;
    }
    handle_setpoint(t_ns, *s);
  } else if (std::holds_alternative<mavlink::VisionSpeedEstimate>(message)) {
    ++stats_.vision_speed_ignored;
    if (!said_vision_speed_ignored_) {
      said_vision_speed_ignored_ = true;
      statustext(kSeverityWarning, "VISION_SPEED_ESTIMATE ignored: send ODOMETRY", out);
    }
  } else if (const auto* o = std::get_if<mavlink::Odometry>(&message)) {
    handle_odometry(*o);
  } else if (const auto* ts = std::get_if<mavlink::Timesync>(&message)) {
    // A request (tc1 = 0) is answered with this FC's clock, ts1 echoed, addressed to the
    // requester (the newer protocol's targets; an old requester ignores them).
    if (ts->tc1_ns != 0) return;
    mavlink::Timesync answer;
    answer.tc1_ns = t_ns;
    answer.ts1_ns = ts->ts1_ns;
    answer.target_system = system_id;
    answer.target_component = component_id;
    ++stats_.timesync_answered;
    out.send(answer);
  }
}

void SitlAutopilot::send_param(int index, MessageSink& out) {
  const SitlParam& p = kParams[static_cast<std::size_t>(index)];
  mavlink::ParamValue v;
  v.param_value = static_cast<float>(p.ns != nullptr ? static_cast<double>(config_.*p.ns) * 1e-9
                                                     : config_.*p.seconds_or_value);
  v.param_count = kParams.size();
  v.param_index = static_cast<std::uint16_t>(index);
  std::memcpy(v.param_id.data(), p.id, std::min(std::strlen(p.id), v.param_id.size()));
  v.param_type = mavlink::kMavParamTypeReal32;
  out.send(v);
  ++stats_.params_sent;
}

void SitlAutopilot::handle_param(const mavlink::Message& message, MessageSink& out) {
  if (const auto* list = std::get_if<mavlink::ParamRequestList>(&message)) {
    if (!for_us(list->target_system, list->target_component)) return;
    for (int i = 0; i < kSitlParamCount; ++i) send_param(i, out);
  } else if (const auto* read = std::get_if<mavlink::ParamRequestRead>(&message)) {
    if (!for_us(read->target_system, read->target_component)) return;
    const int index = read->param_index >= 0 ? read->param_index : find_param(read->param_id);
    if (index < 0 || index >= kSitlParamCount) {
      ++stats_.params_rejected;  // PX4 stays silent; the GCS times out and says so
      return;
    }
    send_param(index, out);
  } else if (const auto* set = std::get_if<mavlink::ParamSet>(&message)) {
    if (!for_us(set->target_system, set->target_component)) return;
    const int index = find_param(set->param_id);
    if (index < 0) {
      ++stats_.params_rejected;
      return;
    }
    // As PX4: the answer is always the parameter's value after the request, so a GCS sees a
    // refused value as not taken.
    const SitlParam& p = kParams[static_cast<std::size_t>(index)];
    const auto value = static_cast<double>(set->param_value);
    if (set->param_type != mavlink::kMavParamTypeReal32 || !std::isfinite(value) || value < p.min ||
        value > p.max) {
      ++stats_.params_rejected;
      statustext(kSeverityWarning, "param set refused: out of range or not REAL32", out);
    } else {
      if (p.ns != nullptr) {
        config_.*p.ns = std::llround(value * 1e9);
      } else {
        config_.*p.seconds_or_value = value;
      }
      ++stats_.params_set;
    }
    send_param(index, out);
  }
}

void SitlAutopilot::handle_odometry(const mavlink::Odometry& o) {
  ++stats_.odometry_received;
  // PX4's receiver: vision estimator types go to EKF2, others (MOCAP, GPS, ...) do not.
  if (o.estimator_type != kMavEstimatorTypeUnknown && o.estimator_type != kMavEstimatorTypeVision &&
      o.estimator_type != mavlink::kMavEstimatorTypeVio) {
    ++stats_.rejected_estimator;
    return;
  }
  const Eigen::Vector3d v(static_cast<double>(o.vx_mps), static_cast<double>(o.vy_mps),
                          static_cast<double>(o.vz_mps));
  if (!v.allFinite()) {
    ++stats_.rejected_nan;
    return;
  }
  Eigen::Matrix3d R_child;  // the velocity's covariance as sent (NaN in [0]: unknown)
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) {
      R_child(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = static_cast<double>(
          o.velocity_covariance[mavlink::upper_triangle_index(std::min(r, c), std::max(r, c))]);
    }
  }
  Eigen::Matrix3d R_NED_child;
  if (o.child_frame_id == mavlink::kMavFrameBodyFrd) {
    R_NED_child = R_NED_B_;
  } else if (o.child_frame_id == mavlink::kMavFrameLocalNed) {
    R_NED_child.setIdentity();
  } else {
    ++stats_.rejected_frame;
    return;
  }
  if (o.quality_pct < config_.min_vision_quality_pct) {
    ++stats_.rejected_quality;
    return;
  }
  const auto t_meas_ns = static_cast<std::int64_t>(o.time_usec) * 1000;
  const Eigen::Vector3d z_NED = R_NED_child * v;
  const Eigen::Matrix3d R_NED = R_NED_child * R_child * R_NED_child.transpose();
  Eigen::Vector3d v_true_NED;
  if (truth_at(t_meas_ns, v_true_NED)) {
    ++stats_.raw_samples;
    stats_.raw_sq_error_sum += (z_NED - v_true_NED).squaredNorm();
  }
  switch (vision_.fuse(t_meas_ns, z_NED, R_NED, o.reset_counter)) {
    case VisionFuse::kFused:
      ++stats_.odometry_fused;
      break;
    case VisionFuse::kReset:
      ++stats_.odometry_fused;
      ++stats_.odometry_resets;
      break;
    case VisionFuse::kRejectedGate:
      ++stats_.rejected_gate;
      break;
    case VisionFuse::kRejectedStamp:
      ++stats_.rejected_stamp;
      break;
  }
}

bool SitlAutopilot::truth_at(std::int64_t t_ns, Eigen::Vector3d& v_NED_mps) const {
  for (std::size_t k = 1; k <= truth_count_; ++k) {
    const std::size_t i = (truth_next_ + kTruthHistory - k) % kTruthHistory;
    if (truth_t_ns_[i] <= t_ns) {
      if (k == 1 && t_ns - truth_t_ns_[i] > 20'000'000) return false;
      v_NED_mps = truth_v_NED_mps_[i];
      return true;
    }
  }
  return false;
}

void SitlAutopilot::handle_setpoint(std::int64_t t_ns, const mavlink::SetAttitudeTarget& t) {
  ++stats_.setpoints;
  last_setpoint_ns_ = t_ns;
  if ((t.type_mask & mavlink::kAttitudeTargetIgnoreAttitude) == 0) {
    // ZYX Euler angles of the body FRD in NED from q = (w, x, y, z).
    const double w = static_cast<double>(t.q[0]), x = static_cast<double>(t.q[1]),
                 y = static_cast<double>(t.q[2]), z = static_cast<double>(t.q[3]);
    const double n = std::sqrt(w * w + x * x + y * y + z * z);
    if (n > 1e-6) {
      const double qw = w / n, qx = x / n, qy = y / n, qz = z / n;
      setpoint_.roll_rad = std::atan2(2.0 * (qw * qx + qy * qz), 1.0 - 2.0 * (qx * qx + qy * qy));
      setpoint_.pitch_rad = std::asin(std::clamp(2.0 * (qw * qy - qz * qx), -1.0, 1.0));
    }
  }
  setpoint_.yaw_rate_radps = (t.type_mask & mavlink::kAttitudeTargetIgnoreBodyYawRate) != 0
                                 ? 0.0
                                 : static_cast<double>(t.body_yaw_rate_radps);
  if ((t.type_mask & mavlink::kAttitudeTargetIgnoreThrust) == 0) {
    setpoint_.thrust_n = std::clamp(static_cast<double>(t.thrust), 0.0, 1.0) * max_thrust_n_;
  }
}

void SitlAutopilot::handle_command(std::int64_t t_ns, std::uint8_t system_id,
                                   std::uint8_t component_id, const mavlink::CommandLong& c,
                                   const TruthState& truth, MessageSink& out) {
  ++stats_.commands;
  if (c.command == mavlink::kMavCmdComponentArmDisarm) {
    if (c.param[0] > 0.5f) {
      if (last_companion_ns_ < 0) {
        statustext(kSeverityWarning, "arming refused: no companion heartbeat yet", out);
        ack(c, kResultTemporarilyRejected, system_id, component_id, out);
        return;
      }
      set_armed(true, "armed", out);
      ack(c, mavlink::kMavResultAccepted, system_id, component_id, out);
      return;
    }
    if (armed_ && !truth.on_ground && c.param[1] != kForceDisarmMagic) {
      statustext(kSeverityWarning, "disarm refused: in the air (param2 21196 forces)", out);
      ack(c, kResultDenied, system_id, component_id, out);
      return;
    }
    set_armed(false, truth.on_ground ? "disarmed" : "disarmed in the air (forced)", out);
    ack(c, mavlink::kMavResultAccepted, system_id, component_id, out);
    return;
  }
  if (c.command == mavlink::kMavCmdDoSetMode) {
    const auto main_mode = static_cast<std::uint32_t>(std::lround(c.param[1]));
    const auto sub_mode = static_cast<std::uint32_t>(std::lround(c.param[2]));
    if ((static_cast<int>(c.param[0]) & mavlink::kMavModeFlagCustomModeEnabled) == 0) {
      ack(c, kResultUnsupported, system_id, component_id, out);
      return;
    }
    if (main_mode == mavlink::kPx4MainModeOffboard) {
      if (last_setpoint_ns_ < 0 || t_ns - last_setpoint_ns_ > config_.setpoint_stream_ns) {
        statustext(kSeverityWarning, "offboard refused: no setpoint stream", out);
        ack(c, kResultTemporarilyRejected, system_id, component_id, out);
        return;
      }
      set_mode(SitlMode::kOffboard, "mode: OFFBOARD", out);
    } else if (main_mode == kPx4MainPosctl) {
      set_mode(SitlMode::kPosctl, "mode: POSCTL", out);
    } else if (main_mode == kPx4MainAuto && sub_mode == kPx4AutoSubLand) {
      set_mode(SitlMode::kLand, "mode: LAND", out);
    } else {
      ack(c, kResultUnsupported, system_id, component_id, out);
      return;
    }
    ack(c, mavlink::kMavResultAccepted, system_id, component_id, out);
    return;
  }
  if (c.command == mavlink::kMavCmdSetMessageInterval) {
    // Accepted as PX4 does; the simulated FC already streams the IMU at the simulator's IMU
    // rate and the attitude at 50 Hz, which is what a companion asks for.
    ack(c, mavlink::kMavResultAccepted, system_id, component_id, out);
    return;
  }
  ack(c, kResultUnsupported, system_id, component_id, out);
}

double SitlAutopilot::estimated_v_up_mps(std::int64_t t_ns, const TruthState& truth,
                                         std::int64_t dt_ns) {
  // The barometer's rate wanders whether or not it is used, as a sensor's error does.
  const double dt_s = static_cast<double>(dt_ns) * 1e-9;
  const double decay = std::exp(-dt_s / config_.baro_rate_correlation_s);
  baro_rate_error_mps_ = decay * baro_rate_error_mps_ + config_.baro_rate_sigma_mps *
                                                            std::sqrt(1.0 - decay * decay) *
                                                            normal_(rng_);
  if (vision_.fresh(t_ns)) return -vision_.v_NED_mps().z();
  return truth.v_N_mps.z() + baro_rate_error_mps_;
}

AttitudeCommand SitlAutopilot::level_command(const TruthState& truth, double v_up_mps,
                                             double v_up_estimate_mps) const {
  // A P loop on the estimated vertical speed, level, no yaw (attitude from the truth).
  const double a_up_mps2 = config_.land_speed_gain_per_s * (v_up_mps - v_up_estimate_mps);
  const double tilt = std::cos(truth.euler_rad.x()) * std::cos(truth.euler_rad.y());
  AttitudeCommand c;
  c.thrust_n =
      std::clamp(mass_kg_ * (kGravityMps2 + a_up_mps2) / std::max(tilt, 0.5), 0.0, max_thrust_n_);
  return c;
}

AttitudeCommand SitlAutopilot::update(std::int64_t t_ns, const TruthState& truth,
                                      MessageSink& out) {
  const std::int64_t dt_ns = last_update_ns_ < 0 ? 0 : t_ns - last_update_ns_;
  last_update_ns_ = t_ns;
  if (armed_) stats_.armed_ns += dt_ns;
  if (mode_ == SitlMode::kOffboard) stats_.offboard_ns += dt_ns;
  battery_v_ -= (armed_ ? kDrainArmedVps : kDrainIdleVps) * static_cast<double>(dt_ns) * 1e-9;

  // PX4's offboard failsafes (COM_OF_LOSS_T, then the link-loss action).
  if (mode_ == SitlMode::kOffboard) {
    const bool setpoints_lost = t_ns - last_setpoint_ns_ > config_.offboard_loss_ns;
    const bool companion_lost = t_ns - last_companion_ns_ >= config_.companion_loss_ns;
    if (setpoints_lost || companion_lost) {
      const SitlMode fallback = armed_ ? SitlMode::kLand : SitlMode::kPosctl;
      set_mode(fallback,
               setpoints_lost
                   ? (armed_ ? "offboard setpoints lost: landing" : "offboard setpoints lost")
                   : (armed_ ? "companion heartbeat lost: landing" : "companion heartbeat lost"),
               out);
    }
  }

  const double v_up_estimate_mps = estimated_v_up_mps(t_ns, truth, dt_ns);
  AttitudeCommand command;  // disarmed: no thrust
  if (armed_) {
    switch (mode_) {
      case SitlMode::kOffboard:
        command = setpoint_;
        break;
      case SitlMode::kLand:
        command = level_command(truth, -config_.land_speed_mps, v_up_estimate_mps);
        if (!truth.on_ground) {
          (vision_.fresh(t_ns) ? stats_.descent_on_vision_ns : stats_.descent_on_baro_ns) += dt_ns;
        }
        if (truth.on_ground) {
          if (on_ground_since_ns_ < 0) on_ground_since_ns_ = t_ns;
          if (t_ns - on_ground_since_ns_ >= config_.landed_disarm_ns) {
            set_armed(false, "landed: disarmed", out);
            command = AttitudeCommand{};
          }
        } else {
          on_ground_since_ns_ = -1;
        }
        break;
      case SitlMode::kPosctl:
        // No sticks: idle on the ground, hold altitude (zero vertical speed) in the air.
        if (!truth.on_ground) command = level_command(truth, 0.0, v_up_estimate_mps);
        break;
    }
  }

  if (t_ns >= next_attitude_ns_) {
    next_attitude_ns_ = t_ns + config_.attitude_period_ns;
    mavlink::Attitude a;
    a.time_boot_ms = static_cast<std::uint32_t>(t_ns / 1'000'000);
    a.roll_rad = static_cast<float>(truth.euler_rad.x());  // euler_rad: B (FRD) in NED
    a.pitch_rad = static_cast<float>(truth.euler_rad.y());
    a.yaw_rad = static_cast<float>(truth.euler_rad.z());
    a.rollspeed_radps = static_cast<float>(truth.omega_B_radps.x());
    a.pitchspeed_radps = static_cast<float>(truth.omega_B_radps.y());
    a.yawspeed_radps = static_cast<float>(truth.omega_B_radps.z());
    out.send(a);
  }
  if (t_ns >= next_status_ns_) {
    next_status_ns_ = t_ns + config_.status_period_ns;
    send_heartbeat(out);
    mavlink::SysStatus s;
    s.voltage_battery_mv = static_cast<std::uint16_t>(std::lround(battery_v_ * 1000.0));
    s.current_battery_ca = static_cast<std::int16_t>(armed_ ? 1200 : 50);
    s.battery_remaining_pct = static_cast<std::int8_t>(std::clamp(
        std::lround(100.0 * (battery_v_ - kBatteryEmptyV) / (kBatteryFullV - kBatteryEmptyV)), 0L,
        100L));
    out.send(s);
  }
  return command;
}

void SitlAutopilot::on_imu(const ImuSample& sample, const TruthState& truth, MessageSink& out) {
  R_NED_B_ = R_NED_B_of(truth);
  const Eigen::Vector3d a_NED_mps2 =
      R_NED_B_ * sample.f_B_mps2 + Eigen::Vector3d(0.0, 0.0, kGravityMps2);
  vision_.predict(sample.t_ns, a_NED_mps2);
  const Eigen::Vector3d v_true_NED = ned_from_world(truth.v_N_mps);
  truth_t_ns_[truth_next_] = sample.t_ns;
  truth_v_NED_mps_[truth_next_] = v_true_NED;
  truth_next_ = (truth_next_ + 1) % kTruthHistory;
  truth_count_ = std::min(truth_count_ + 1, kTruthHistory);
  if (vision_.fresh(sample.t_ns)) {
    ++stats_.fused_samples;
    stats_.fused_sq_error_sum += (vision_.v_NED_mps() - v_true_NED).squaredNorm();
  }
  mavlink::HighresImu m;
  m.time_usec = static_cast<std::uint64_t>(sample.t_ns / 1000);
  m.xacc_mps2 = static_cast<float>(sample.f_B_mps2.x());
  m.yacc_mps2 = static_cast<float>(sample.f_B_mps2.y());
  m.zacc_mps2 = static_cast<float>(sample.f_B_mps2.z());
  m.xgyro_radps = static_cast<float>(sample.omega_B_radps.x());
  m.ygyro_radps = static_cast<float>(sample.omega_B_radps.y());
  m.zgyro_radps = static_cast<float>(sample.omega_B_radps.z());
  m.fields_updated = kImuAccGyroFields;
  out.send(m);
}

std::string_view sitl_mode_name(SitlMode mode) { return mode_name(mode); }

}  // namespace hq::sitl
