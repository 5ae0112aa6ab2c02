#include "hq/link_bridge/link_operator_port.hpp"

#include "hq/base/monotonic_clock.hpp"

#include <algorithm>
#include <cstring>
#include <fmt/format.h>

namespace hq::link_bridge {

LinkOperatorPort::LinkOperatorPort(LinkBridge& bridge, const pipeline::OnboardChain& chain,
                                   const Eigen::Isometry3d& T_B_C, std::FILE* log)
    : bridge_(bridge), chain_(chain), T_C_B_(T_B_C.inverse()), log_(log) {}

modes::OperatorCommand LinkOperatorPort::poll(std::int64_t t_ns,
                                              std::vector<pipeline::ModeRequest>& requests) {
  const FailsafeState& state = bridge_.poll(t_ns, requests);
  if (log_ != nullptr && state.hold_started) {
    fmt::print(log_, "hq-onboard: t {:.3f} s: fail-safe hold, command age {:.1f} ms\n",
               hq::to_seconds(t_ns), 1e-6 * static_cast<double>(state.command_age_ns));
  }
  if (log_ != nullptr && state.land_for_heartbeat) {
    fmt::print(log_, "hq-onboard: t {:.3f} s: fail-safe land, heartbeat age {:.1f} ms\n",
               hq::to_seconds(t_ns), 1e-6 * static_cast<double>(state.heartbeat_age_ns));
  }
  if (log_ != nullptr && state.land_for_hold) {
    fmt::print(log_, "hq-onboard: t {:.3f} s: fail-safe land after hold, command age {:.1f} ms\n",
               hq::to_seconds(t_ns), 1e-6 * static_cast<double>(state.command_age_ns));
  }
  if (log_ != nullptr && state.commander_changed) {
    fmt::print(log_, "hq-onboard: t {:.3f} s: commanded by station {}\n", hq::to_seconds(t_ns),
               state.commanding_station_id);
  }
  return state.command;
}

void LinkOperatorPort::on_mode_result(std::int64_t t_ns, const pipeline::ModeRequest& request,
                                      const modes::ModeSwitch& result) {
  bridge_.acknowledge(t_ns, request, result);
}

void LinkOperatorPort::on_output(const pipeline::ChainOutput& out,
                                 const vehicle::VehicleStatus& status) {
  StateExtras extras;
  if (chain_.config().memory.enabled) {
    // The memory's world is the odometry origin O.
    if (const auto T_O_C = chain_.memory().T_O_C()) {
      extras.cloud.memory = &chain_.memory();
      extras.cloud.T_O_B = *T_O_C * T_C_B_;
    }
  }
  if (const marker_modes::MarkerStage* markers = chain_.markers()) {
    const marker_modes::MarkerNavigation& navigation = markers->navigation();
    // The filter's own checks (markers.navigation.position_*): what the console shows is what
    // the marker and explore modes would fly on.
    const navigation::PositionCheck check = navigation.position_check(out.t_ns);
    extras.position_valid = check.valid;
    extras.position_invalid_reason = static_cast<std::uint8_t>(check.reason);
    extras.position_age_s = check.age_s;
    extras.position_sigma_m = check.sigma_horizontal_m;
    extras.p_W_m = navigation.p_W_m();
    extras.yaw_rad = navigation.yaw_rad();
    extras.markers = navigation.detections();
  }
  if (status.truth) {
    extras.truth_valid = true;
    extras.v_truth_H_mps = status.truth->v_H_mps;
  }
  // The marker and explore modes exist only with the marker stage (OnboardChain registers them
  // with it): the console greys their buttons and says why before the operator asks.
  const bool marker_stage_on = chain_.markers() != nullptr;
  extras.modes_offered = marker_stage_on ? link::kModesOfferedMask : link::kModesWithoutMarkerStage;
  if (!marker_stage_on) {
    extras.marker_mode_off_reason = link::kModeOffMarkerStageDisabled;
    extras.explore_mode_off_reason = link::kModeOffMarkerStageDisabled;
  }
  if (const marker_modes::MarkerStage* stage = chain_.markers()) {
    // What the console shows beside the mode: the marker flown to, the exploration's phase.
    const modes::Mode mode = out.mode.mode;
    if (mode == modes::Mode::kMarker || mode == modes::Mode::kExplore) {
      extras.marker_target_id = stage->marker_mode().marker_id();
    }
    if (mode == modes::Mode::kExplore) {
      extras.explore_phase = static_cast<int>(stage->explore().phase()) + 1;
    }
  }
  extras.vehicle_degraded = status.degraded();
  // Spinning: the chain off the floor (landed is motors idle, thrust 0) and, when a flight
  // controller reports, it armed (the simulator's always is; a real one may be disarmed).
  extras.motors_armed =
      out.flight_state != modes::FlightState::kLanded && (!status.fc.connected || status.fc.armed);
  bridge_.publish_state(out, extras);
}

void LinkOperatorPort::on_frame(const sources::RgbdFrame& frame) {
  bridge_.publish_camera(frame.t_ns, frame.bgr.empty() ? frame.gray : frame.bgr);
}

void LinkOperatorPort::on_event(std::int64_t t_ns, vehicle::FcSeverity severity,
                                std::string_view text) {
  char buffer[hq_msgs_kMaxEventText + 1];
  const std::size_t n = std::min(text.size(), sizeof buffer - 1);
  std::memcpy(buffer, text.data(), n);
  buffer[n] = '\0';
  const hq_msgs_Severity link_severity =
      severity == vehicle::FcSeverity::kError     ? hq_msgs_SEVERITY_ERROR
      : severity == vehicle::FcSeverity::kWarning ? hq_msgs_SEVERITY_WARNING
                                                  : hq_msgs_SEVERITY_INFO;
  bridge_.publish_event(t_ns, link_severity, EventCode::kVehicle, buffer);
  if (log_ != nullptr) {
    fmt::print(log_, "hq-onboard: t {:.3f} s: {}\n", hq::to_seconds(t_ns), buffer);
  }
}

}  // namespace hq::link_bridge
