#include "hq/ground/window_keyboard.hpp"

#include "hq/base/error.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace hq::ground {

Eigen::Vector3d key_target_D_m(std::uint32_t held, const haptics::KeyboardConfig& config) {
  const auto axis = [held](std::uint32_t plus, std::uint32_t minus) {
    return ((held & plus) != 0 ? 1.0 : 0.0) - ((held & minus) != 0 ? 1.0 : 0.0);
  };
  // Eq. 6-8: forward is +p_x; eq. 8 as printed, v_z = -k_v p_z: a climb is +p_z; eq. 10,
  // yaw_rate = -k_psi p_y: a yaw to the right (NED +) is -p_y.
  return config.range_m * Eigen::Vector3d(axis(console::kKeyForward, console::kKeyBack),
                                          axis(console::kKeyYawLeft, console::kKeyYawRight),
                                          axis(console::kKeyClimb, console::kKeyDescend));
}

WindowKeyboardDevice::WindowKeyboardDevice(const haptics::KeyboardConfig& config,
                                           const console::FlightKeys& keys)
    : config_(config), keys_(keys) {
  if (!(config_.range_m > 0.0) || !std::isfinite(config_.range_m)) {
    throw InputError("keyboard (window) device: keyboard.range_m = " +
                     std::to_string(config_.range_m) + ", expected > 0");
  }
  set_status("waiting for the console window");
}

bool WindowKeyboardDevice::read(std::int64_t t_ns, haptics::DeviceSample& out) {
  out = haptics::DeviceSample{};
  const bool open = keys_.window_open();
  if (!open) {
    // Before the window opens, and for good once it closed: no operator, zero command.
    p_D_m_.setZero();
    have_last_ = false;
    if (connected_ || was_open_) set_status("console window closed: command zero");
    connected_ = false;
    return false;
  }
  if (!was_open_) {
    was_open_ = true;
    set_status("W/S fwd/back, Q/E or A/D yaw, PgUp/PgDn climb/descend (window focus)");
  }
  connected_ = true;
  const Eigen::Vector3d target = key_target_D_m(keys_.held(), config_);
  const double dt_s =
      have_last_ ? std::max(1e-9 * static_cast<double>(t_ns - last_t_ns_), 0.0) : 0.0;
  last_t_ns_ = t_ns;
  have_last_ = true;
  const double max_step_m = config_.range_m * dt_s / kSlewTime_s;
  p_D_m_ += (target - p_D_m_).cwiseMax(-max_step_m).cwiseMin(max_step_m);
  out.p_D_m = p_D_m_;
  return true;
}

void WindowKeyboardDevice::write_force(std::int64_t /*t_ns*/, const Eigen::Vector3d& /*F_D_n*/) {}

}  // namespace hq::ground
