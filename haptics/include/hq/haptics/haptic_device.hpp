#pragma once
/// Haptic devices: 3-DOF end-effector position in, force out, behind one small interface owned
/// by the haptic loop. Backends: simulated (scripted hand), keyboard (terminal raw mode), SDL2
/// joystick/gamepad, Force Dimension (only when CMake found its SDK). All work in D: NED at the
/// resting point of the end effector (x away from the operator, y right, z down), metres, N.
///
/// read() and write_force() run on the haptic thread at 1 kHz: they allocate nothing and never
/// throw. A lost device reads as not connected with a zero position, and says why in status().

#include "hq/base/format_into.hpp"
#include "hq/haptics/haptics_config.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <fmt/format.h>
#include <memory>
#include <string>
#include <utility>

namespace hq::haptics {

/// One reading of the device.
struct DeviceSample {
  Eigen::Vector3d p_D_m = Eigen::Vector3d::Zero();  ///< End effector in D.
  std::uint32_t buttons = 0;                        ///< Bit i = button i held.
};

class HapticDevice {
 public:
  virtual ~HapticDevice() = default;
  HapticDevice() = default;
  HapticDevice(const HapticDevice&) = delete;
  HapticDevice& operator=(const HapticDevice&) = delete;

  /// Reads the end effector at loop time t_ns (CLOCK_MONOTONIC). Returns false, with a zero
  /// sample, when the device is lost or not (yet) connected.
  virtual bool read(std::int64_t t_ns, DeviceSample& out) = 0;
  /// Force on the hand in D, held until the next call. Ignored by devices without actuators.
  virtual void write_force(std::int64_t t_ns, const Eigen::Vector3d& F_D_n) = 0;
  [[nodiscard]] virtual const char* name() const = 0;
  [[nodiscard]] virtual bool connected() const = 0;
  /// Human-readable state or error ("connected", "joystick removed: command zero").
  [[nodiscard]] const char* status() const { return status_.data(); }

 protected:
  /// fmt-style, truncated to the buffer; allocates nothing (a device may say it from the loop).
  template <typename... Args>
  void set_status(fmt::format_string<Args...> format, Args&&... args) {
    hq::format_into(status_.data(), status_.size(), format, std::forward<Args>(args)...);
  }

 private:
  std::array<char, 128> status_{};
};

/// Mass-spring-damper end effector pushed by a scripted hand (SimulatedDeviceConfig); dynamics
/// integrated on the times passed to read(), so runs are reproducible bit for bit.
class SimulatedDevice final : public HapticDevice {
 public:
  /// @throws hq::InputError on a non-positive mass or an unsorted script.
  explicit SimulatedDevice(const SimulatedDeviceConfig& config);
  bool read(std::int64_t t_ns, DeviceSample& out) override;
  void write_force(std::int64_t t_ns, const Eigen::Vector3d& F_D_n) override;
  [[nodiscard]] const char* name() const override { return "sim"; }
  [[nodiscard]] bool connected() const override { return connected_; }

  /// The exact effector velocity (the loop differentiates positions like for any device).
  [[nodiscard]] const Eigen::Vector3d& v_D_mps() const { return v_D_mps_; }
  /// Hand target and buttons at `t_s` seconds after the first read.
  void hand_at(double t_s, Eigen::Vector3d& p_hand_D_m, Eigen::Vector3d& v_hand_D_mps,
               std::uint32_t& buttons, bool& connected) const;

 private:
  void integrate(double t_s);
  SimulatedDeviceConfig config_;
  std::int64_t t0_ns_ = 0;
  bool started_ = false;
  double t_s_ = 0.0;
  bool connected_ = true;
  Eigen::Vector3d p_D_m_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_D_mps_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d F_D_n_ = Eigen::Vector3d::Zero();
};

/// Non-blocking byte input for KeyboardDevice, so tests can feed keys without a terminal.
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  /// Copies up to `capacity` available bytes into `buffer` without blocking. Returns the count,
  /// 0 if none, -1 if the source is closed or failed.
  virtual int read_available(char* buffer, int capacity) = 0;
};

/// A terminal in raw, non-blocking mode (termios); restores the previous mode on destruction.
/// @throws hq::InputError if `fd` is not a terminal or cannot be configured.
std::unique_ptr<ByteSource> open_terminal(int fd);

/// Keys move a virtual end effector in D, step_m per press, clamped to range_m:
///   w / s  or up / down arrows      p_x + / -  (forward / back)
///   d / a  or right / left arrows   p_y + / -  (handle right / left)
///   f / r                           p_z + / -  (handle down / up)
///   space                           back to the resting point
///   1..8                            button 0..7 (pressed for one read)
/// With the paper's eq. 8 and 10 (see teleop_mapping.hpp) 'r' (handle up) descends and 'd'
/// (handle right) yaws left. A closed source reads as device loss.
class KeyboardDevice final : public HapticDevice {
 public:
  KeyboardDevice(const KeyboardConfig& config, std::unique_ptr<ByteSource> input);
  bool read(std::int64_t t_ns, DeviceSample& out) override;
  void write_force(std::int64_t t_ns, const Eigen::Vector3d& F_D_n) override;
  [[nodiscard]] const char* name() const override { return "keyboard"; }
  [[nodiscard]] bool connected() const override { return connected_; }

 private:
  void apply_key(char key);
  KeyboardConfig config_;
  std::unique_ptr<ByteSource> input_;
  Eigen::Vector3d p_D_m_ = Eigen::Vector3d::Zero();
  std::uint32_t pending_buttons_ = 0;
  int escape_state_ = 0;  // 0 none, 1 after ESC, 2 after ESC [
  bool connected_ = true;
};

/// Which backend open_device() opens, and its settings.
struct DeviceOptions {
  HapticsConfig config;  ///< sim, keyboard and joystick sections are used.
  int terminal_fd = 0;   ///< Keyboard input (stdin).
};

/// "sim" | "keyboard" | "joystick" | "forcedim". @throws hq::InputError naming the kind for an
/// unknown kind, a backend not built here, or a device that cannot be opened.
std::unique_ptr<HapticDevice> open_device(const std::string& kind, const DeviceOptions& options);

}  // namespace hq::haptics
