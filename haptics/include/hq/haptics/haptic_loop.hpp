#pragma once
/// The 1 kHz haptic loop: read the device, map it to a velocity command (eq. 6-10), compute the
/// force cue, cap it last, write it, on absolute CLOCK_MONOTONIC deadlines in a thread of its own.
///
/// Other threads (the ground's DDS side) exchange data with it through two small
/// mutex-protected snapshots: set_vehicle_estimate() in, latest() out. Critical sections are a
/// struct copy, so the loop never waits long; tick() allocates nothing.

#include "hq/haptics/haptic_device.hpp"
#include "hq/haptics/haptics_config.hpp"
#include "hq/haptics/passivity_controller.hpp"
#include "hq/haptics/passivity_observer.hpp"
#include "hq/haptics/teleop_mapping.hpp"

#include <Eigen/Core>

#include <array>
#include <atomic>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace hq::haptics {

/// CLOCK_MONOTONIC now, the clock of every t_ns on the haptic side.
std::int64_t monotonic_now_ns();

/// Histogram of timing errors, 0.5 us bins up to 20 ms, sized once; add() allocates nothing.
class JitterStats {
 public:
  JitterStats();
  /// Records |error_ns| (a late wake-up or a period error).
  void add(std::int64_t error_ns);
  /// Quantile q in [0, 1] in microseconds (bin upper edge); 0 with no samples.
  [[nodiscard]] double quantile_us(double q) const;
  [[nodiscard]] double max_us() const { return 1e-3 * static_cast<double>(max_ns_); }
  [[nodiscard]] std::int64_t count() const { return count_; }
  void reset();

 private:
  std::vector<std::uint32_t> bins_;
  std::int64_t count_ = 0;
  std::int64_t max_ns_ = 0;
};

/// What start() obtained from the OS.
struct RealtimeGrant {
  bool fifo = false;           ///< SCHED_FIFO granted to the loop thread.
  int priority = 0;            ///< Its priority when granted.
  bool memory_locked = false;  ///< mlockall succeeded.
  std::string summary;         ///< One line for the operator, e.g. the refusal and its errno.
};

/// Latest output of the loop.
struct LoopOutput {
  std::int64_t t_ns = 0;
  std::uint64_t tick = 0;
  VelocityCommand command;  ///< Zero whenever the device is lost or its reading unusable.
  bool command_valid = false;
  Eigen::Vector3d p_D_m = Eigen::Vector3d::Zero();
  /// Force commanded to the device: |F_D_n| <= max_force_n, finite, the cap applied last.
  Eigen::Vector3d F_D_n = Eigen::Vector3d::Zero();
  bool force_saturated = false;             ///< The cap scaled this tick's force down.
  std::uint64_t force_saturated_ticks = 0;  ///< Ticks the cap scaled the force down.
  /// Ticks some term of the force was NaN or infinite: zero force commanded, status says so.
  std::uint64_t force_nonfinite_ticks = 0;
  std::uint32_t buttons = 0;
  bool device_connected = false;
  double cue_weight = 0.0;                ///< 0 when the vehicle state is stale.
  double passivity_energy_j = 0;          ///< PassivityObserver::energy_j() at this tick.
  double channel_energy_j = 0;            ///< PassivityController::energy_j() of the device port.
  double passivity_damping_ns_per_m = 0;  ///< The controller's damper at this tick.
  std::array<char, 128> status{};         ///< Device status, or why the command is zero.
};

struct LoopTimingReport {
  JitterStats period;  ///< |actual period - nominal|.
  JitterStats wake;    ///< Wake-up time - deadline.
  std::int64_t missed_deadlines = 0;
};

class HapticLoop {
 public:
  /// @param device  used only from the loop thread once started; must outlive the loop.
  /// @param R_B_C  R_QC (optical), for eq. 9. @throws hq::InputError via TeleopMapping.
  HapticLoop(HapticDevice& device, const HapticsConfig& config, const Eigen::Matrix3d& R_B_C);
  ~HapticLoop();
  HapticLoop(const HapticLoop&) = delete;
  HapticLoop& operator=(const HapticLoop&) = delete;

  /// Starts the thread; asks for SCHED_FIFO and mlockall as configured (mlockall only where
  /// RLIMIT_MEMLOCK is unlimited or CAP_IPC_LOCK held, since MCL_FUTURE under a finite limit makes
  /// later allocations fail) and prints a warning on stderr naming what was refused. Returns what
  /// was granted. @throws hq::InputError if the thread cannot be created.
  RealtimeGrant start();
  /// Stops and joins the thread (idempotent).
  void stop();

  /// One loop period at time t_ns: the whole per-tick path, callable without the thread for
  /// deterministic runs. Allocates nothing. Not to be called while the thread runs.
  void tick(std::int64_t t_ns);

  /// From any thread: the latest vehicle estimate (t_ns on monotonic_now_ns()'s clock).
  void set_vehicle_estimate(const VehicleEstimate& estimate);
  /// From any thread: the latest output.
  [[nodiscard]] LoopOutput latest() const;
  /// Timing of the threaded run. @pre the loop is stopped (or never started).
  [[nodiscard]] const LoopTimingReport& timing() const { return timing_; }
  [[nodiscard]] const PassivityObserver& passivity() const { return observer_; }
  /// The passivity controller on the device port. @pre the loop is stopped (or never started).
  [[nodiscard]] const PassivityController& passivity_controller() const { return controller_; }
  [[nodiscard]] const TeleopMapping& mapping() const { return mapping_; }

 private:
  void run();

  HapticDevice& device_;
  HapticsConfig config_;
  TeleopMapping mapping_;
  ForceFeedback feedback_;
  PassivityObserver observer_;
  PassivityController controller_;
  std::int64_t period_ns_;

  // Loop-thread state.
  std::int64_t last_t_ns_ = 0;
  bool have_last_ = false;
  Eigen::Vector3d last_p_D_m_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d p_dot_D_mps_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d last_F_D_n_ = Eigen::Vector3d::Zero();
  std::uint64_t tick_count_ = 0;
  std::uint64_t force_saturated_ticks_ = 0;
  std::uint64_t force_nonfinite_ticks_ = 0;
  LoopTimingReport timing_;

  mutable std::mutex estimate_mutex_;
  VehicleEstimate estimate_;
  mutable std::mutex output_mutex_;
  LoopOutput output_;

  std::atomic<bool> running_{false};
  std::thread thread_;
};

}  // namespace hq::haptics
