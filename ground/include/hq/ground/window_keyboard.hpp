#pragma once
/// Keyboard flying from the operator console's window: a HapticDevice whose end effector is
/// moved by the keys held in the window (hq::console::FlightKeys), so the keyboard goes through
/// the same haptic loop, TeleopMapping (eq. 6-10) and link as any device. `hq-ground --device
/// keyboard` uses it when the window is open; --headless keeps the terminal's raw-mode keyboard.
///
/// A held key deflects the effector to range_m on its axis, a released key lets it return to
/// the resting point; either way it moves at most range_m per kSlewTime_s, so a key press gives
/// a ramp rather than a velocity step. Signs follow the paper's eq. 8 and 10 with D and H NED:
/// forward is +p_x, a climb is +p_z (v_z = -k_v p_z), a yaw to the right is -p_y
/// (yaw_rate = -k_psi p_y).

#include "hq/console/flight_keys.hpp"
#include "hq/haptics/haptic_device.hpp"
#include "hq/haptics/haptics_config.hpp"

#include <Eigen/Core>

#include <cstdint>

namespace hq::ground {

/// The displacement in D that the keys `held` (bits of console::FlightKey) ask for, each axis
/// 0 or +-range_m; opposite keys cancel.
Eigen::Vector3d key_target_D_m(std::uint32_t held, const haptics::KeyboardConfig& config);

class WindowKeyboardDevice final : public haptics::HapticDevice {
 public:
  static constexpr double kSlewTime_s = 0.2;  ///< Rest to full deflection.

  /// `keys` is not owned and must outlive the device.
  WindowKeyboardDevice(const haptics::KeyboardConfig& config, const console::FlightKeys& keys);
  bool read(std::int64_t t_ns, haptics::DeviceSample& out) override;
  void write_force(std::int64_t t_ns, const Eigen::Vector3d& F_D_n) override;
  [[nodiscard]] const char* name() const override { return "keyboard (window)"; }
  [[nodiscard]] bool connected() const override { return connected_; }

 private:
  haptics::KeyboardConfig config_;
  const console::FlightKeys& keys_;
  Eigen::Vector3d p_D_m_ = Eigen::Vector3d::Zero();
  std::int64_t last_t_ns_ = 0;
  bool have_last_ = false;
  bool connected_ = false;
  bool was_open_ = false;
};

}  // namespace hq::ground
