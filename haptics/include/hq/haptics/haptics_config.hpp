#pragma once
/// Configuration of the operator's haptic side: the eq. 6-10 mapping of the core paper (§3.3),
/// the force feedback, the 1 kHz loop and the simulated and keyboard devices. One file,
/// config/haptics.yaml, read strictly: every key checked, unknown keys rejected, `_deg` keys
/// converted to radians once.

#include <Eigen/Core>

#include <cstdint>
#include <string>
#include <vector>

namespace YAML {
class Node;
}

namespace hq::haptics {

/// Eq. 6-10: end-effector displacement in D (NED, metres) -> velocity command in H.
struct MappingConfig {
  double velocity_gain_mps_per_m = 10.0;  ///< k_v of eq. 6-8.
  double yaw_gain_radps_per_m = 20.0;     ///< k_psi of eq. 10.
  double dead_band_m = 0.003;             ///< Per axis, removed before the gains.
  double max_horizontal_speed_mps = 1.0;  ///< |v_H xy| saturates here.
  double max_vertical_speed_mps = 0.5;    ///< |v_H z| saturates here.
  double max_yaw_rate_radps = 0.7854;     ///< |yaw rate| saturates here (YAML: _degps).
};

/// Force on the operator's hand, in D: centring spring, Franchi et al. 2012b velocity-error cue,
/// damping, saturation and fade-out on stale vehicle state.
struct FeedbackConfig {
  double centring_stiffness_n_per_m = 60.0;  ///< Spring to the resting point of D.
  double velocity_stiffness_n_per_m = 80.0;  ///< K on the velocity error mapped back to D.
  double yaw_stiffness_n_per_m = 40.0;       ///< K on the yaw-rate error mapped back to D.
  double damping_ns_per_m = 6.0;             ///< B of -B p_dot.
  double max_force_n = 8.0;                  ///< |F| saturates here (law and device cap).
  double stale_after_s = 0.1;                ///< Estimate older than this starts the fade.
  double fade_s = 0.5;                       ///< Cue weight goes 1 -> 0 over this time.
  double velocity_filter_hz = 60.0;          ///< Low-pass on the differentiated p for p_dot.
  /// Time-domain passivity controller on the delayed cue (PassivityController): on by default.
  bool passivity_control = true;
  double passivity_max_damping_ns_per_m = 60.0;  ///< Cap on its variable damper.
};

/// The haptic thread.
struct LoopConfig {
  double rate_hz = 1000.0;
  bool realtime = true;        ///< Try SCHED_FIFO for the loop thread.
  int realtime_priority = 80;  ///< SCHED_FIFO priority when granted.
  bool lock_memory = true;     ///< Try mlockall(MCL_CURRENT | MCL_FUTURE).
};

/// One keyframe of the simulated operator's hand.
struct HandKeyframe {
  double t_s = 0.0;                                 ///< From the device's first read.
  Eigen::Vector3d p_D_m = Eigen::Vector3d::Zero();  ///< Hand target in D.
  std::uint32_t buttons = 0;                        ///< Held from this keyframe on.
  bool connected = true;                            ///< False simulates device loss.
};

/// A mass-spring-damper end effector pushed by a scripted hand.
struct SimulatedDeviceConfig {
  double mass_kg = 0.2;                   ///< Effective end-effector mass.
  double hand_stiffness_n_per_m = 200.0;  ///< Grip spring between hand target and effector.
  double hand_damping_ns_per_m = 2.0;     ///< Grip damping.
  double device_damping_ns_per_m = 0.5;   ///< Mechanism friction.
  double workspace_m = 0.08;              ///< Effector is clamped to |p_i| <= this.
  std::vector<HandKeyframe> script;       ///< Sorted by t_s; positions linearly interpolated.
};

/// Keys move a virtual end effector in D.
struct KeyboardConfig {
  double step_m = 0.005;  ///< Displacement per key press.
  double range_m = 0.05;  ///< |p_i| clamp.
};

/// Joystick and gamepad axes in [-1, 1] scale to a virtual end effector in D.
struct JoystickConfig {
  double range_m = 0.05;             ///< Full deflection.
  int index = 0;                     ///< SDL device index opened first.
  double rumble_full_scale_n = 8.0;  ///< |F| that plays as full-strength rumble.
};

struct HapticsConfig {
  MappingConfig mapping;
  FeedbackConfig feedback;
  LoopConfig loop;
  SimulatedDeviceConfig sim;
  KeyboardConfig keyboard;
  JoystickConfig joystick;
};

/// Reads a haptics mapping node (sections mapping, feedback, loop, sim, keyboard, joystick; each
/// optional, keys inside optional with the defaults above; sim.script a list of
/// {t_s, p_m: [x, y, z], buttons, connected}). `where` names the file in messages. Throws
/// hq::InputError naming file, key, value and expectation.
void read_config(const YAML::Node& root, const std::string& where, HapticsConfig& out);

/// Loads and validates config/haptics.yaml or another file of that layout.
HapticsConfig load_haptics_config(const std::string& path);

}  // namespace hq::haptics
