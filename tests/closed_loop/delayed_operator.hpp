#pragma once
// The operator's side flown over a delayed, jittery, lossy link into the real closed loop: the
// shipped HapticLoop (mapping, stamped force law, passivity controller) with the operator's arm
// closing the loop (haptics/campaign/include/hq/haptics/delay_campaign.hpp), its commands delayed
// up to the vehicle, the chain's estimates delayed back down. Shared by hq-bench-delay-closed-loop
// and hq_delay_closed_loop_test. Simulated time throughout.

#include "hq/closed_loop/closed_loop.hpp"
#include "hq/haptics/delay_campaign.hpp"
#include "hq/haptics/haptics_config.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/world.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace hq::closed_loop::delay {

/// Room world: take off, then push forward along the camera heading (45 deg right of the body's
/// x) past a pillar and a box towards the wall, pull back, let go.
inline Eigen::Vector3d room_intent(double t_s) {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  if (t_s >= 1.0 && t_s < 3.5) p.z() = 0.05;  // handle down: climb (eq. 8)
  if (t_s >= 5.0 && t_s < 17.0) p.x() = std::min(0.08, 0.08 * (t_s - 5.0) / 0.5);
  if (t_s >= 17.0 && t_s < 18.0) p.x() = -0.03;
  return p;
}

struct State {
  Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();
  double yaw_rate_radps = 0.0;
};

class DelayedHapticOperator final : public OperatorSource {
 public:
  DelayedHapticOperator(const haptics::HapticsConfig& config, const Eigen::Matrix3d& R_B_C,
                        const haptics::campaign::LinkModel& link)
      : arm_(haptics::campaign::ArmModel{}, &room_intent),
        loop_(arm_, with_no_realtime(config), R_B_C),
        up_(link, link.seed * 2 + 1),
        down_(link, link.seed * 2 + 2) {}

  modes::OperatorCommand poll(std::int64_t t_ns, std::vector<modes::Mode>& requests) override {
    if (!started_) {
      started_ = true;
      requests.push_back(modes::Mode::kTeleop);
      next_tick_ns_ = t_ns;
    }
    // The ground: 1 kHz haptic loop up to now, commands up at 100 Hz, states in as they land.
    while (next_tick_ns_ <= t_ns) {
      if (down_.receive(next_tick_ns_)) {
        haptics::VehicleEstimate estimate;
        estimate.t_ns = down_.newest_sent_ns();  // the vehicle's stamp: the law ages it
        estimate.valid = true;
        estimate.v_H_mps = down_.newest().v_H_mps;
        estimate.yaw_rate_radps = down_.newest().yaw_rate_radps;
        loop_.set_vehicle_estimate(estimate);
      }
      loop_.tick(next_tick_ns_);
      const haptics::LoopOutput out = loop_.latest();
      force_sq_ += out.F_D_n.squaredNorm();
      ++ticks_;
      if (ticks_ % 10 == 0) up_.send(next_tick_ns_, out.command);
      last_sent_ = out.command;
      next_tick_ns_ += 1'000'000;
    }
    // The vehicle: the newest command that has arrived, zero after 200 ms without one.
    up_.receive(t_ns);
    modes::OperatorCommand command;
    command.t_ns = t_ns;
    if (up_.have() && t_ns - up_.newest_arrived_ns() <= 200'000'000) {
      command.v_H_mps = up_.newest().v_H_mps;
      command.yaw_rate_radps = up_.newest().yaw_rate_radps;
    }
    return command;
  }

  void on_output(const pipeline::ChainOutput& out, const sim::TruthState& truth) override {
    State s;
    s.v_H_mps = out.estimate.v_H_mps;
    s.yaw_rate_radps = out.estimate.omega_B_radps.z();  // as hq-ground reads the state
    if (s.v_H_mps.allFinite() && std::isfinite(s.yaw_rate_radps)) down_.send(out.t_ns, s);
    (void)truth;
    // Tracking: what the vehicle does against what the operator sends now.
    track_sq_ += (s.v_H_mps - last_sent_.v_H_mps).squaredNorm();
    ++outputs_;
  }

  [[nodiscard]] const haptics::HapticLoop& loop() const { return loop_; }
  [[nodiscard]] double force_rms_n() const {
    return std::sqrt(force_sq_ / static_cast<double>(std::max(ticks_, 1L)));
  }
  [[nodiscard]] double tracking_rms_mps() const {
    return std::sqrt(track_sq_ / static_cast<double>(std::max(outputs_, 1L)));
  }
  [[nodiscard]] double state_loss() const { return down_.loss_fraction(); }

 private:
  static haptics::HapticsConfig with_no_realtime(haptics::HapticsConfig config) {
    config.loop.realtime = false;
    config.loop.lock_memory = false;
    return config;
  }
  haptics::campaign::OperatorArm arm_;
  haptics::HapticLoop loop_;
  haptics::campaign::DelayLine<haptics::VelocityCommand> up_;
  haptics::campaign::DelayLine<State> down_;
  haptics::VelocityCommand last_sent_;
  bool started_ = false;
  std::int64_t next_tick_ns_ = 0;
  double force_sq_ = 0.0;
  double track_sq_ = 0.0;
  long ticks_ = 0;
  long outputs_ = 0;
};

struct FlightResult {
  double min_energy_j = 0.0;
  double dissipated_j = 0.0;
  double force_rms_n = 0.0;
  double tracking_rms_mps = 0.0;
  double min_clearance_m = 0.0;
  int collision_ticks = 0;
  double max_altitude_m = 0.0;
  double state_loss = 0.0;
};

/// One room flight of `end_s` seconds at 320x240.
inline FlightResult fly(const haptics::HapticsConfig& haptics_config,
                        const haptics::campaign::LinkModel& link, double end_s = 20.0) {
  const sim::World world = sim::load_world("onboard/sim/worlds/room.yaml");
  sim::SimConfig sim_config = sim::load_sim_config("onboard/sim/config/sim.yaml");
  sim::set_resolution(sim_config, "320x240", "delay flight");
  const pipeline::OnboardConfig onboard = pipeline::load_onboard_config("config/onboard.yaml");
  const VehicleConfig vehicle = load_vehicle_config("calib/vehicle_core_paper.yaml");
  OperatorScript script;
  script.end_s = end_s;
  DelayedHapticOperator source(haptics_config, vehicle.camera.R_B_C(), link);
  ClosedLoopOptions options;
  options.operator_source = &source;
  ClosedLoop loop(sim_config, world, onboard, vehicle,
                  OperatorPlayer(script, vehicle.camera.heading_rad()), options);
  loop.run();
  FlightResult r;
  r.min_energy_j = source.loop().passivity().min_energy_j();
  r.dissipated_j = source.loop().passivity_controller().dissipated_j();
  r.force_rms_n = source.force_rms_n();
  r.tracking_rms_mps = source.tracking_rms_mps();
  r.min_clearance_m = loop.min_clearance_m();
  r.collision_ticks = loop.collision_ticks();
  r.state_loss = source.state_loss();
  for (const FlightSample& s : loop.samples()) {
    r.max_altitude_m = std::max(r.max_altitude_m, s.p_N_m.z());
  }
  return r;
}

}  // namespace hq::closed_loop::delay
