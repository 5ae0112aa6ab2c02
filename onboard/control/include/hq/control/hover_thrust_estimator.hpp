#pragma once
/// Learns, in flight, how much thrust the flight controller really produces for the thrust the
/// chain commands, as PX4's hover thrust estimator (mc_hover_thrust_estimator) learns its hover
/// throttle. The velocity controller commands thrust in newtons for the mass it believes in;
/// the flight controller turns that into a throttle with `--fc-max-thrust-n`. If either is off
/// (a heavier battery, a payload, worn props, a guessed maximum thrust), the vehicle's weight is
/// fought by the velocity loop's integrator alone. This estimator measures the gain between the
/// two directly and the runtime divides every commanded thrust by it.
///
/// Model: the accelerometer's specific force along the body's z axis is the rotors' thrust over
/// the true mass (FRD: f_z = -T / m_true; drag along z is small at indoor speeds). With the
/// believed mass m and the commanded thrust u (N):
///     y = -f_z m = k u,     k = (T / u) (m / m_true)
/// k = 1 when the vehicle is as believed. y and u are low-passed alike (the motors lag the
/// command and the frame vibrates), then k is a one-state Kalman filter with a slow random
/// walk (the battery sags), updated at a fixed rate, its innovations gated at n sigma. It is
/// fed only while the vehicle is airborne: on the floor the ground, not the rotors, carries
/// the weight.
///
/// Pure: time and samples in, estimate out; allocates nothing.

#include <cstdint>
#include <string>

namespace hq::config {
class StrictMap;
}  // namespace hq::config

namespace hq::control {

struct HoverThrustConfig {
  bool enabled = true;
  /// Both the commanded thrust and the measured specific force are low-passed with this time
  /// constant, longer than the motors' lag and the attitude loop's (PX4 multirotors: 20-50 ms).
  double filter_time_constant_s = 0.1;
  /// One Kalman update per period (the IMU runs at 200+ Hz; neighbouring samples are not
  /// independent after the low-pass).
  double update_period_s = 0.02;
  /// 1 sigma of the gain before any measurement: a maximum thrust or mass 30 % off is 1 sigma.
  double initial_sigma = 0.3;
  /// The gain's random walk (1/sqrt(s)): a battery sagging 10 % over a 10 min flight is far
  /// inside it; a payload dropped is followed in seconds.
  double random_walk_per_sqrt_s = 0.01;
  /// 1 sigma of the filtered specific force's error (m/s^2): vibration left after the
  /// low-pass, vertical drag, the thrust-to-force lag in manoeuvres.
  double specific_force_sigma_mps2 = 0.8;
  /// Innovations beyond this many sigma are not fused (a bump, a ground effect, a gust).
  double gate_sigma = 3.0;
  /// The gain stays within these bounds: beyond them the vehicle cannot be what its config
  /// says, and the estimate is not to be flown on.
  double min_gain = 0.5;
  double max_gain = 2.0;
  /// Converged: 1 sigma below this (and at least min_updates fused).
  double converged_sigma = 0.03;
  int min_updates = 25;
  /// No updates while the commanded thrust is below this fraction of m g (the rotors barely
  /// carry the vehicle: take-off ramps, free fall, a stall; the model is poor there).
  double min_thrust_ratio = 0.5;

  /// Throws hq::InputError naming the key after `where`, e.g. "hover_thrust.initial_sigma".
  void validate(const std::string& where = "hover_thrust.") const;
};

/// Reads the `hover_thrust:` section strictly (every key above), then validate().
void read_config(config::StrictMap& section, HoverThrustConfig& out);

struct HoverThrustEstimate {
  double gain = 1.0;   ///< k: actual over commanded thrust (mass-corrected).
  double sigma = 0.3;  ///< Its 1 sigma.
  bool converged = false;
  std::uint64_t updates = 0;   ///< Measurements fused.
  std::uint64_t rejected = 0;  ///< Measurements outside the gate.
  std::uint64_t clamped = 0;   ///< Updates that hit min_gain/max_gain.
  /// Times a second of rejected innovations reset the gain's variance (the vehicle changed).
  std::uint64_t relearned = 0;
};

class HoverThrustEstimator {
 public:
  /// mass_kg: the mass the velocity controller believes in (its thrusts are for this mass).
  HoverThrustEstimator(const HoverThrustConfig& config, double mass_kg);

  /// The thrust commanded at t_ns (N, before the gain is applied: what the flight controller
  /// will be asked for is commanded_n / gain()).
  void on_command(std::int64_t t_ns, double sent_thrust_n);
  /// One accelerometer sample: the specific force along the body's z axis (FRD, m/s^2; about
  /// -9.81 in a hover). airborne: the vehicle is flying, not on the floor nor taking off.
  void on_specific_force(std::int64_t t_ns, double f_z_mps2, bool airborne);

  /// The thrust to send for a commanded one: commanded / gain, or unchanged when disabled.
  [[nodiscard]] double corrected_thrust_n(double commanded_n) const;
  [[nodiscard]] const HoverThrustEstimate& estimate() const { return estimate_; }
  /// The commanded thrust that hovers the vehicle (N): m g / gain.
  [[nodiscard]] double hover_thrust_n() const;
  /// Forgets the filtered signals (a gap in the IMU, a landing); the gain is kept.
  void restart_filters();

 private:
  void update(double y_n, double u_n, double dt_s);

  HoverThrustConfig config_;
  double mass_kg_;
  HoverThrustEstimate estimate_;
  double variance_;
  double sent_thrust_n_ = 0.0;
  bool have_command_ = false;
  // Low-passed y = -f_z m and u, and when they were last advanced.
  double y_filtered_n_ = 0.0;
  double u_filtered_n_ = 0.0;
  std::int64_t filter_t_ns_ = -1;
  double airborne_s_ = 0.0;  ///< Airborne time since the filters restarted.
  std::int64_t last_update_ns_ = -1;
  double rejected_s_ = 0.0;  ///< Time since the last fused innovation, while rejecting.
};

}  // namespace hq::control
