#pragma once
// Teleoperation over a delayed, jittery, lossy link, closed by an operator model: shared by
// hq-bench-delay-campaign (the full campaign) and hq_haptics_test (a small variant).
//
// Every piece on the operator's side is the shipped one: HapticLoop (eq. 6-10 mapping, force
// law with its stamped fade, passivity controller) ticked at 1 kHz. Around it:
//   - the operator's arm holding the end effector: mass-spring-damper pulled towards the
//     operator's intent, which yields to the force felt a reaction time ago (voluntary response,
//     on top of the arm's instantaneous impedance);
//   - the link: commands up at 100 Hz and vehicle states down at 30 Hz, each sample delayed by
//     half the round trip plus uniform jitter (so reordered), dropped with probability `loss`,
//     seeded; the receiver keeps the newest stamp;
//   - the vehicle, horizontal only: velocity follows the received command plus the obstacle
//     repulsion with a first-order lag (the velocity controller), a wall ahead along the camera
//     heading, the on-board fail-safe (no command for 200 ms: hold zero). This is a stand-in for
//     the simulator, cheap enough for the whole campaign in one run; the force law sees only the
//     velocity estimate, as with the real chain.
// Simulated time throughout: results do not depend on the machine's load.

#include "hq/base/monotonic_clock.hpp"
#include "hq/haptics/haptic_device.hpp"
#include "hq/haptics/haptic_loop.hpp"
#include "hq/haptics/teleop_mapping.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>

namespace hq::haptics::campaign {

struct LinkModel {
  double round_trip_s = 0.0;
  double jitter_s = 0.0;  ///< Uniform in [-jitter, +jitter] on each one-way delay.
  double loss = 0.0;      ///< Probability that a sample is dropped.
  std::uint32_t seed = 1;
};

struct ArmModel {
  double mass_kg = 1.0;  ///< Hand and forearm on the effector.
  double stiffness_n_per_m = 150.0;
  double damping_ns_per_m = 5.0;
  double reaction_s = 0.15;  ///< Voluntary reaction time.
  double yield = 0.5;        ///< Fraction of the felt force the intent gives way to.
};

struct VehicleModel {
  double lag_s = 0.3;                    ///< Velocity controller time constant.
  double wall_distance_m = 3.0;          ///< Start to wall, along the camera heading.
  double radius_m = 0.25;                ///< Closer than this to the wall: a collision.
  double influence_distance_m = 1.2;     ///< obstacles.influence_distance_m.
  double max_repulsive_speed_mps = 0.8;  ///< obstacles.max_repulsive_speed_mps.
  double command_timeout_s = 0.2;        ///< Fail-safe hold.
  double noise_mps = 0.02;               ///< Estimate noise.
};

struct RunResult {
  double min_energy_j = 0.0;  ///< Device port E (passivity observer), min over the run.
  double final_energy_j = 0.0;
  double dissipated_j = 0.0;             ///< By the passivity controller.
  double force_rms_n = 0.0;              ///< |F| felt.
  double ideal_force_rms_n = 0.0;        ///< |F| the law gives with the vehicle's true state, now.
  double transparency = 0.0;             ///< 1 - rms(F - F_ideal) / rms(F_ideal).
  double tracking_rms_mps = 0.0;         ///< |v_vehicle - v_cmd as sent|.
  double hold_hand_speed_rms_mps = 0.0;  ///< Effector speed while the intent is constant.
  double min_clearance_m = 0.0;
  int collisions = 0;
  double loss_measured = 0.0;  ///< Fraction of state samples lost.
};

/// The operator's intent in D at t_s: where the hand would go with no force on it.
using IntentFn = Eigen::Vector3d (*)(double t_s);

/// The arm: a device whose effector is the operator's hand.
class OperatorArm final : public HapticDevice {
 public:
  explicit OperatorArm(const ArmModel& arm, IntentFn intent = &wall_intent)
      : arm_(arm), intent_(intent) {
    set_status("operator arm");
  }

  bool read(std::int64_t t_ns, DeviceSample& out) override {
    if (!started_) {
      started_ = true;
      t_s_ = 0.0;
      t0_ns_ = t_ns;
    }
    const double t_s = hq::to_seconds(t_ns - t0_ns_);
    while (t_s_ + 1e-4 <= t_s) step(1e-4);  // 10 kHz arm integration between loop ticks
    out.p_D_m = p_D_m_;
    out.buttons = 0;
    return true;
  }
  void write_force(std::int64_t /*t_ns*/, const Eigen::Vector3d& F_D_n) override {
    F_D_n_ = F_D_n;
    felt_[head_ % felt_.size()] = F_D_n;
    ++head_;
  }
  [[nodiscard]] const char* name() const override { return "operator arm"; }
  [[nodiscard]] bool connected() const override { return true; }

  /// The operator's intent along D x: forward to 8 cm (against the centring spring the hand
  /// settles near 6 cm, 0.6 m/s), hold towards the wall, pull back, release.
  [[nodiscard]] static Eigen::Vector3d wall_intent(double t_s) {
    double x = 0.0;
    if (t_s < 1.0) {
      x = 0.0;
    } else if (t_s < 1.5) {
      x = 0.08 * (t_s - 1.0) / 0.5;
    } else if (t_s < 8.0) {
      x = 0.08;
    } else if (t_s < 8.4) {
      x = 0.08 - 0.11 * (t_s - 8.0) / 0.4;  // pull back past the centre
    } else if (t_s < 9.0) {
      x = -0.03 + 0.03 * (t_s - 8.4) / 0.6;
    }
    return {x, 0.0, 0.0};
  }
  [[nodiscard]] const Eigen::Vector3d& v_D_mps() const { return v_D_mps_; }
  [[nodiscard]] const Eigen::Vector3d& p_D_m() const { return p_D_m_; }

 private:
  void step(double dt_s) {
    t_s_ += dt_s;
    // The force felt reaction_s ago, from the 1 kHz history of write_force().
    const auto lag_ticks = static_cast<std::uint64_t>(std::lround(arm_.reaction_s * 1e3));
    Eigen::Vector3d felt = Eigen::Vector3d::Zero();
    if (head_ > lag_ticks) felt = felt_[(head_ - 1 - lag_ticks) % felt_.size()];
    const Eigen::Vector3d intent = intent_(t_s_);
    const Eigen::Vector3d target = intent + arm_.yield * felt / arm_.stiffness_n_per_m;
    const Eigen::Vector3d a =
        (arm_.stiffness_n_per_m * (target - p_D_m_) - arm_.damping_ns_per_m * v_D_mps_ + F_D_n_) /
        arm_.mass_kg;
    v_D_mps_ += a * dt_s;
    p_D_m_ += v_D_mps_ * dt_s;
  }

  ArmModel arm_;
  IntentFn intent_;
  bool started_ = false;
  std::int64_t t0_ns_ = 0;
  double t_s_ = 0.0;
  Eigen::Vector3d p_D_m_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_D_mps_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d F_D_n_ = Eigen::Vector3d::Zero();
  std::array<Eigen::Vector3d, 2048> felt_{};
  std::uint64_t head_ = 0;
};

/// One direction of the link: samples with a send stamp, released at their arrival time; the
/// receiver keeps the newest stamp (a reordered older sample is dropped on arrival).
template <typename Payload>
class DelayLine {
 public:
  DelayLine(const LinkModel& link, std::uint32_t seed)
      : link_(link), rng_(seed), jitter_(-1.0, 1.0), uniform_(0.0, 1.0) {}

  void send(std::int64_t t_ns, const Payload& payload) {
    ++sent_;
    if (uniform_(rng_) < link_.loss) {
      ++lost_;
      return;
    }
    const double delay_s = std::max(0.0, 0.5 * link_.round_trip_s + link_.jitter_s * jitter_(rng_));
    Pending& slot = pending_[write_ % pending_.size()];
    ++write_;
    slot.arrive_ns = t_ns + static_cast<std::int64_t>(std::llround(1e9 * delay_s));
    slot.sent_ns = t_ns;
    slot.payload = payload;
    slot.live = true;
  }
  /// Delivers what arrived by t_ns; true if `newest` changed.
  bool receive(std::int64_t t_ns) {
    bool changed = false;
    for (Pending& slot : pending_) {
      if (!slot.live || slot.arrive_ns > t_ns) continue;
      slot.live = false;
      if (have_ && slot.sent_ns <= newest_sent_ns_) continue;
      newest_ = slot.payload;
      newest_sent_ns_ = slot.sent_ns;
      newest_arrived_ns_ = t_ns;
      have_ = true;
      changed = true;
    }
    return changed;
  }
  [[nodiscard]] bool have() const { return have_; }
  [[nodiscard]] const Payload& newest() const { return newest_; }
  [[nodiscard]] std::int64_t newest_sent_ns() const { return newest_sent_ns_; }
  [[nodiscard]] std::int64_t newest_arrived_ns() const { return newest_arrived_ns_; }
  [[nodiscard]] double loss_fraction() const {
    return sent_ > 0 ? static_cast<double>(lost_) / static_cast<double>(sent_) : 0.0;
  }

 private:
  struct Pending {
    std::int64_t arrive_ns = 0;
    std::int64_t sent_ns = 0;
    Payload payload{};
    bool live = false;
  };
  LinkModel link_;
  std::mt19937 rng_;
  std::uniform_real_distribution<double> jitter_;
  std::uniform_real_distribution<double> uniform_;
  std::array<Pending, 256> pending_{};  // > 1.1 s of 100 Hz samples in flight
  std::uint64_t write_ = 0;
  bool have_ = false;
  Payload newest_{};
  std::int64_t newest_sent_ns_ = 0;
  std::int64_t newest_arrived_ns_ = 0;
  std::uint64_t sent_ = 0;
  std::uint64_t lost_ = 0;
};

/// One flight of `seconds` (>= 10: the intent script lasts 9 s).
inline RunResult run(HapticsConfig config, const Eigen::Matrix3d& R_B_C, const LinkModel& link,
                     const ArmModel& arm = {}, const VehicleModel& vehicle = {},
                     double seconds = 12.0) {
  config.loop.realtime = false;
  config.loop.lock_memory = false;
  OperatorArm device(arm);
  HapticLoop loop(device, config, R_B_C);
  const TeleopMapping mapping(config.mapping, R_B_C);
  HapticsConfig ideal_config = config;
  ideal_config.feedback.stale_after_s = 1e3;
  const ForceFeedback ideal(ideal_config.feedback, mapping);
  const Eigen::Vector2d heading_H(std::cos(mapping.alpha_rad()), std::sin(mapping.alpha_rad()));

  DelayLine<VelocityCommand> up(link, link.seed * 2 + 1);
  DelayLine<Eigen::Vector2d> down(link, link.seed * 2 + 2);
  std::mt19937 noise_rng(link.seed + 17);
  std::normal_distribution<double> noise(0.0, vehicle.noise_mps);

  Eigen::Vector2d p_H_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d v_H_mps = Eigen::Vector2d::Zero();
  RunResult result;
  result.min_clearance_m = vehicle.wall_distance_m;
  bool in_collision = false;
  double force_sq = 0.0, ideal_sq = 0.0, error_sq = 0.0, track_sq = 0.0, hold_sq = 0.0;
  int n = 0, n_hold = 0;
  const std::int64_t t0_ns = 1'000'000'000;
  const std::int64_t dt_ns = 1'000'000;
  const double dt_s = 1e-3;
  const int ticks = static_cast<int>(seconds * 1e3);
  for (int k = 0; k < ticks; ++k) {
    const std::int64_t t_ns = t0_ns + k * dt_ns;
    const double t_s = hq::to_seconds(t_ns - t0_ns);
    // Ground: the newest state that has arrived, stamped with the vehicle's time of it (one
    // clock in simulation), so the force law's fade sees its true age.
    if (down.receive(t_ns)) {
      VehicleEstimate estimate;
      estimate.t_ns = down.newest_sent_ns();
      estimate.valid = true;
      estimate.v_H_mps = Eigen::Vector3d(down.newest().x(), down.newest().y(), 0.0);
      loop.set_vehicle_estimate(estimate);
    }
    loop.tick(t_ns);
    const LoopOutput out = loop.latest();
    if (k % 10 == 0) up.send(t_ns, out.command);

    // Vehicle.
    up.receive(t_ns);
    Eigen::Vector2d v_cmd_H = Eigen::Vector2d::Zero();
    if (up.have() && hq::to_seconds(t_ns - up.newest_arrived_ns()) <= vehicle.command_timeout_s) {
      v_cmd_H = up.newest().v_H_mps.head<2>();
    }
    const double distance_m = vehicle.wall_distance_m - heading_H.dot(p_H_m);
    Eigen::Vector2d v_obs_H = Eigen::Vector2d::Zero();
    if (distance_m < vehicle.influence_distance_m) {
      v_obs_H = -heading_H * vehicle.max_repulsive_speed_mps *
                std::min(1.0, 1.0 - distance_m / vehicle.influence_distance_m);
    }
    v_H_mps += (dt_s / (vehicle.lag_s + dt_s)) * (v_cmd_H + v_obs_H - v_H_mps);
    p_H_m += v_H_mps * dt_s;
    const double clearance_m = vehicle.wall_distance_m - heading_H.dot(p_H_m);
    result.min_clearance_m = std::min(result.min_clearance_m, clearance_m);
    const bool colliding = clearance_m < vehicle.radius_m;
    if (colliding && !in_collision) ++result.collisions;
    in_collision = colliding;
    if (k % 33 == 0) {
      down.send(t_ns, v_H_mps + Eigen::Vector2d(noise(noise_rng), noise(noise_rng)));
    }

    // Metrics: the force felt beside the law's force on the vehicle's true state, now.
    VehicleEstimate truth;
    truth.t_ns = t_ns;
    truth.valid = true;
    truth.v_H_mps = Eigen::Vector3d(v_H_mps.x(), v_H_mps.y(), 0.0);
    const FeedbackForce F_ideal =
        ideal.compute(t_ns, device.p_D_m(), device.v_D_mps(), out.command, truth);
    force_sq += out.F_D_n.squaredNorm();
    ideal_sq += F_ideal.F_D_n.squaredNorm();
    error_sq += (out.F_D_n - F_ideal.F_D_n).squaredNorm();
    track_sq += (v_H_mps - out.command.v_H_mps.head<2>()).squaredNorm();
    ++n;
    if (t_s > 2.5 && t_s < 8.0) {
      hold_sq += device.v_D_mps().squaredNorm();
      ++n_hold;
    }
  }
  result.min_energy_j = loop.passivity().min_energy_j();
  result.final_energy_j = loop.passivity().energy_j();
  result.dissipated_j = loop.passivity_controller().dissipated_j();
  result.force_rms_n = std::sqrt(force_sq / n);
  result.ideal_force_rms_n = std::sqrt(ideal_sq / n);
  result.transparency = ideal_sq > 0.0 ? 1.0 - std::sqrt(error_sq / ideal_sq) : 1.0;
  result.tracking_rms_mps = std::sqrt(track_sq / n);
  result.hold_hand_speed_rms_mps = n_hold > 0 ? std::sqrt(hold_sq / n_hold) : 0.0;
  result.loss_measured = down.loss_fraction();
  return result;
}

}  // namespace hq::haptics::campaign
