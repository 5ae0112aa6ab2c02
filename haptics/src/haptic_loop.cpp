#include "hq/haptics/haptic_loop.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/base/log.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/base/quantile.hpp"
#include "hq/haptics/force_limit.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <system_error>
#include <time.h>

namespace hq::haptics {
namespace {

constexpr std::int64_t kBinNs = 500;
constexpr std::int64_t kHistogramRangeNs = 20'000'000;

void copy_status(const char* text, std::array<char, 128>& out) {
  hq::format_into(out.data(), out.size(), "{}", text);
}

/// RLIMIT_MEMLOCK in KiB, -1 when unlimited.
std::int64_t memlock_limit_kib() {
  rlimit limit{};
  if (getrlimit(RLIMIT_MEMLOCK, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return -1;
  return static_cast<std::int64_t>(limit.rlim_cur / 1024);
}

/// CAP_IPC_LOCK (bit 14) in the effective set, read from /proc/self/status.
bool has_ipc_lock_capability() {
  constexpr unsigned long long kCapIpcLock = 1ull << 14;
  std::FILE* file = std::fopen("/proc/self/status", "r");
  if (file == nullptr) return false;
  char line[256];
  unsigned long long effective = 0;
  while (std::fgets(line, sizeof(line), file) != nullptr) {
    if (std::sscanf(line, "CapEff: %llx", &effective) == 1) break;
  }
  std::fclose(file);
  return (effective & kCapIpcLock) != 0;
}

}  // namespace

std::int64_t monotonic_now_ns() { return hq::monotonic_now_ns(); }

JitterStats::JitterStats() : bins_(kHistogramRangeNs / kBinNs + 1, 0) {}

void JitterStats::add(std::int64_t error_ns) {
  const std::int64_t magnitude_ns = error_ns < 0 ? -error_ns : error_ns;
  const std::size_t bin = static_cast<std::size_t>(
      std::min<std::int64_t>(magnitude_ns / kBinNs, static_cast<std::int64_t>(bins_.size()) - 1));
  ++bins_[bin];
  ++count_;
  max_ns_ = std::max(max_ns_, magnitude_ns);
}

double JitterStats::quantile_us(double q) const {
  if (count_ == 0) return 0.0;
  const std::size_t b = histogram_quantile_bin(bins_, count_, q);
  // The last bin holds everything beyond the range: report the true maximum there.
  if (b + 1 >= bins_.size()) return max_us();
  return 1e-3 * static_cast<double>((static_cast<std::int64_t>(b) + 1) * kBinNs);
}

void JitterStats::reset() {
  std::fill(bins_.begin(), bins_.end(), 0);
  count_ = 0;
  max_ns_ = 0;
}

HapticLoop::HapticLoop(HapticDevice& device, const HapticsConfig& config,
                       const Eigen::Matrix3d& R_B_C)
    : device_(device),
      config_(config),
      mapping_(config.mapping, R_B_C),
      feedback_(config.feedback, mapping_),
      controller_(config.feedback.passivity_max_damping_ns_per_m,
                  config.feedback.passivity_control),
      period_ns_(static_cast<std::int64_t>(std::llround(1e9 / config.loop.rate_hz))) {
  copy_status("haptic loop not started", output_.status);
}

HapticLoop::~HapticLoop() { stop(); }

void HapticLoop::set_vehicle_estimate(const VehicleEstimate& estimate) {
  const std::lock_guard<std::mutex> lock(estimate_mutex_);
  estimate_ = estimate;
}

LoopOutput HapticLoop::latest() const {
  const std::lock_guard<std::mutex> lock(output_mutex_);
  return output_;
}

void HapticLoop::tick(std::int64_t t_ns) {
  LoopOutput out;
  out.t_ns = t_ns;
  out.tick = ++tick_count_;
  DeviceSample sample;
  const bool read_ok = device_.read(t_ns, sample);
  out.device_connected = read_ok;
  const double dt_s = have_last_ ? hq::to_seconds(t_ns - last_t_ns_) : hq::to_seconds(period_ns_);

  if (!read_ok || !sample.p_D_m.allFinite() || !(dt_s > 0.0)) {
    // Device lost or reading unusable: zero command and no force until it comes back.
    copy_status(read_ok ? "end-effector position is not finite: command zero" : device_.status(),
                out.status);
    have_last_ = false;
    p_dot_D_mps_.setZero();
    last_F_D_n_.setZero();
    device_.write_force(t_ns, last_F_D_n_);
  } else {
    const Eigen::Vector3d& p_D_m = sample.p_D_m;
    Eigen::Vector3d v_step_D_mps = Eigen::Vector3d::Zero();
    if (have_last_) {
      v_step_D_mps = (p_D_m - last_p_D_m_) / dt_s;
      // First-order low-pass on the differentiated position: encoder steps would otherwise
      // turn the damping term into noise.
      const double tau_s = 1.0 / (2.0 * std::numbers::pi * config_.feedback.velocity_filter_hz);
      p_dot_D_mps_ += (dt_s / (dt_s + tau_s)) * (v_step_D_mps - p_dot_D_mps_);
      // The force held over the last interval did exactly -F.dp of work on the system.
      observer_.update(last_F_D_n_, v_step_D_mps, dt_s);
    }
    const MappedCommand mapped = mapping_.map(p_D_m);
    VehicleEstimate estimate;
    {
      const std::lock_guard<std::mutex> lock(estimate_mutex_);
      estimate = estimate_;
    }
    const FeedbackForce force =
        feedback_.compute(t_ns, p_D_m, p_dot_D_mps_, mapped.command, estimate);
    // The cue carries the link's delay and the law's saturation scales the centring spring in
    // time: either can make the device port active, so the controller guards the whole force,
    // with the velocity of the interval just measured. It sees the law's force already
    // saturated: against an unsaturated law (160 N from a forged state) the cap below would
    // scale its damper to nothing.
    const Eigen::Vector3d F_damper_D_n = controller_.damping_force(force.F_D_n, v_step_D_mps, dt_s);
    // The cap comes last: whatever was added before it, the hand never gets more.
    const LimitedForce limited =
        limit_force(force.F_D_n + F_damper_D_n, config_.feedback.max_force_n);
    controller_.hold(limited.F_D_n);
    device_.write_force(t_ns, limited.F_D_n);
    last_F_D_n_ = limited.F_D_n;
    last_p_D_m_ = p_D_m;
    have_last_ = true;
    if (limited.saturated) ++force_saturated_ticks_;
    if (!limited.finite) ++force_nonfinite_ticks_;

    out.command = mapped.command;
    out.command_valid = mapped.valid;
    out.p_D_m = p_D_m;
    out.F_D_n = limited.F_D_n;
    out.force_saturated = limited.saturated;
    out.buttons = sample.buttons;
    out.cue_weight = force.cue_weight;
    copy_status(limited.finite ? device_.status() : "force not finite: zero force", out.status);
  }
  last_t_ns_ = t_ns;
  out.passivity_energy_j = observer_.energy_j();
  out.channel_energy_j = controller_.energy_j();
  out.passivity_damping_ns_per_m = controller_.damping_ns_per_m();
  out.force_saturated_ticks = force_saturated_ticks_;
  out.force_nonfinite_ticks = force_nonfinite_ticks_;
  const std::lock_guard<std::mutex> lock(output_mutex_);
  output_ = out;
}

RealtimeGrant HapticLoop::start() {
  RealtimeGrant grant;
  if (running_.exchange(true)) return grant;
  timing_.period.reset();
  timing_.wake.reset();
  timing_.missed_deadlines = 0;
  try {
    thread_ = std::thread([this] { run(); });
  } catch (const std::system_error& e) {
    running_.store(false);
    throw InputError(std::string("haptic loop: cannot start its thread: ") + e.what());
  }
  char text[256];
  std::string refused;
  if (config_.loop.lock_memory) {
    // MCL_FUTURE under a finite RLIMIT_MEMLOCK makes later allocations (thread stacks, the DDS
    // side's buffers) fail once the limit is reached, so lock only when the limit cannot bite.
    const std::int64_t limit_kib = memlock_limit_kib();
    if (limit_kib >= 0 && !has_ipc_lock_capability()) {
      hq::format_into(text, "mlockall not attempted (RLIMIT_MEMLOCK {} KiB, no CAP_IPC_LOCK); ",
                      static_cast<long long>(limit_kib));
      refused += text;
    } else if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
      grant.memory_locked = true;
    } else {
      hq::format_into(text, "mlockall refused ({}); ", std::strerror(errno));
      refused += text;
    }
  }
  if (config_.loop.realtime) {
    sched_param parameter{};
    parameter.sched_priority = config_.loop.realtime_priority;
    const int error = pthread_setschedparam(thread_.native_handle(), SCHED_FIFO, &parameter);
    if (error == 0) {
      grant.fifo = true;
      grant.priority = config_.loop.realtime_priority;
    } else {
      hq::format_into(text, "SCHED_FIFO {} refused ({}); ", config_.loop.realtime_priority,
                      std::strerror(error));
      refused += text;
    }
  }
  hq::format_into(text, "haptic loop {:.0f} Hz: {}, {}", config_.loop.rate_hz,
                  grant.fifo ? ("SCHED_FIFO " + std::to_string(grant.priority)).c_str()
                             : "normal scheduling (SCHED_OTHER)",
                  grant.memory_locked ? "memory locked" : "memory not locked");
  grant.summary = text;
  if (!refused.empty()) {
    grant.summary += " -- " + refused +
                     "timing will jitter under load (needs root or CAP_SYS_NICE / CAP_IPC_LOCK, "
                     "or rtprio and memlock limits)";
    hq::log::warn("warning: {}\n", grant.summary.c_str());
  }
  return grant;
}

void HapticLoop::stop() {
  if (!running_.exchange(false)) return;
  if (thread_.joinable()) thread_.join();
}

void HapticLoop::run() {
  // Normal threads get 50 us of timer slack, added to every wake-up; the loop wants none.
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  std::int64_t deadline_ns = monotonic_now_ns() + period_ns_;
  std::int64_t previous_wake_ns = 0;
  while (running_.load(std::memory_order_relaxed)) {
    hq::sleep_until_monotonic_ns(deadline_ns);
    const std::int64_t wake_ns = monotonic_now_ns();
    timing_.wake.add(wake_ns - deadline_ns);
    if (previous_wake_ns != 0) timing_.period.add(wake_ns - previous_wake_ns - period_ns_);
    previous_wake_ns = wake_ns;
    tick(wake_ns);
    deadline_ns += period_ns_;
    // Overran one or more periods: skip them on the same phase rather than bursting to catch up.
    const std::int64_t now_ns = monotonic_now_ns();
    if (deadline_ns <= now_ns) {
      const std::int64_t missed = (now_ns - deadline_ns) / period_ns_ + 1;
      timing_.missed_deadlines += missed;
      deadline_ns += missed * period_ns_;
    }
  }
}

}  // namespace hq::haptics
