#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/haptics/haptic_device.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace hq::haptics {
namespace {
// Integration substep: the grip spring (200 N/m on 0.2 kg, 5 Hz) is resolved 300 times finer.
constexpr double kMaxSubstepS = 1e-4;
}  // namespace

SimulatedDevice::SimulatedDevice(const SimulatedDeviceConfig& config) : config_(config) {
  if (!(config.mass_kg > 0.0) || !(config.workspace_m > 0.0)) {
    std::ostringstream message;
    message << "sim device: mass_kg = " << config.mass_kg
            << ", workspace_m = " << config.workspace_m << ", expected both > 0";
    throw InputError(message.str());
  }
  for (std::size_t i = 1; i < config.script.size(); ++i) {
    if (!(config.script[i].t_s > config.script[i - 1].t_s)) {
      std::ostringstream message;
      message << "sim device: script[" << i << "].t_s = " << config.script[i].t_s << ", expected > "
              << config.script[i - 1].t_s << " (keyframes sorted by time)";
      throw InputError(message.str());
    }
  }
  set_status("sim: scripted hand, {} keyframes", config.script.size());
}

void SimulatedDevice::hand_at(double t_s, Eigen::Vector3d& p_hand_D_m,
                              Eigen::Vector3d& v_hand_D_mps, std::uint32_t& buttons,
                              bool& connected) const {
  p_hand_D_m.setZero();
  v_hand_D_mps.setZero();
  buttons = 0;
  connected = true;
  const auto& script = config_.script;
  if (script.empty()) return;
  if (t_s <= script.front().t_s) {
    p_hand_D_m = script.front().p_D_m;
    return;
  }
  // Scripts are a few dozen keyframes: a linear scan is cheaper than anything clever.
  std::size_t k = 0;
  while (k + 1 < script.size() && script[k + 1].t_s <= t_s) ++k;
  buttons = script[k].buttons;
  connected = script[k].connected;
  if (k + 1 == script.size()) {
    p_hand_D_m = script[k].p_D_m;
    return;
  }
  const double span_s = script[k + 1].t_s - script[k].t_s;
  const double fraction = (t_s - script[k].t_s) / span_s;
  v_hand_D_mps = (script[k + 1].p_D_m - script[k].p_D_m) / span_s;
  p_hand_D_m = script[k].p_D_m + fraction * (script[k + 1].p_D_m - script[k].p_D_m);
}

void SimulatedDevice::integrate(double t_s) {
  if (!(t_s > t_s_)) return;
  const int steps = static_cast<int>(std::ceil((t_s - t_s_) / kMaxSubstepS));
  const double dt_s = (t_s - t_s_) / steps;
  Eigen::Vector3d p_hand = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_hand = Eigen::Vector3d::Zero();
  std::uint32_t buttons = 0;
  bool connected = true;
  for (int i = 1; i <= steps; ++i) {
    hand_at(t_s_ + i * dt_s, p_hand, v_hand, buttons, connected);
    // A powerless (lost) device applies no force; the hand still moves the mechanism.
    const Eigen::Vector3d F_device = connected_ ? F_D_n_ : Eigen::Vector3d::Zero();
    const Eigen::Vector3d F_total = F_device + config_.hand_stiffness_n_per_m * (p_hand - p_D_m_) +
                                    config_.hand_damping_ns_per_m * (v_hand - v_D_mps_) -
                                    config_.device_damping_ns_per_m * v_D_mps_;
    v_D_mps_ += (dt_s / config_.mass_kg) * F_total;  // semi-implicit Euler
    p_D_m_ += dt_s * v_D_mps_;
    for (int a = 0; a < 3; ++a) {
      if (std::abs(p_D_m_[a]) > config_.workspace_m) {
        p_D_m_[a] = std::copysign(config_.workspace_m, p_D_m_[a]);
        v_D_mps_[a] = 0.0;  // mechanical stop
      }
    }
  }
  t_s_ = t_s;
}

bool SimulatedDevice::read(std::int64_t t_ns, DeviceSample& out) {
  if (!started_) {
    started_ = true;
    t0_ns_ = t_ns;
  }
  integrate(hq::to_seconds(t_ns - t0_ns_));
  Eigen::Vector3d p_hand = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_hand = Eigen::Vector3d::Zero();
  std::uint32_t buttons = 0;
  bool connected = true;
  hand_at(t_s_, p_hand, v_hand, buttons, connected);
  if (connected != connected_) {
    connected_ = connected;
    if (connected) {
      set_status("sim: reconnected");
    } else {
      set_status("sim: device lost (scripted at t = {:.3f} s): command zero", t_s_);
    }
  }
  if (!connected_) {
    out = DeviceSample{};
    return false;
  }
  out.p_D_m = p_D_m_;
  out.buttons = buttons;
  return true;
}

void SimulatedDevice::write_force(std::int64_t /*t_ns*/, const Eigen::Vector3d& F_D_n) {
  F_D_n_ = F_D_n.allFinite() ? F_D_n : Eigen::Vector3d::Zero();
}

}  // namespace hq::haptics
