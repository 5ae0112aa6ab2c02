// hq-bench-haptic-loop: the 1 kHz haptic loop with the simulated device for --seconds, beside a
// bare 1 kHz clock_nanosleep loop run at the same time under the same scheduling (the floor:
// what this machine's timer and scheduler give with nothing to do). A third thread plays the
// ground's DDS side, reading commands and feeding vehicle estimates at 100 Hz. Not run by ctest.

#include "hq/base/monotonic_clock.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/haptics/haptic_loop.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <CLI/CLI.hpp>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <fmt/format.h>
#include <optional>
#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>
#include <thread>
#include <time.h>

namespace {

using hq::haptics::JitterStats;
using hq::haptics::monotonic_now_ns;

struct BareLoop {
  JitterStats period;
  JitterStats wake;
  std::int64_t missed = 0;
};

void run_bare_loop(std::int64_t period_ns, const std::atomic<bool>& running, BareLoop& out) {
  prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);  // as HapticLoop does
  std::int64_t deadline_ns = monotonic_now_ns() + period_ns;
  std::int64_t previous_ns = 0;
  while (running.load(std::memory_order_relaxed)) {
    hq::sleep_until_monotonic_ns(deadline_ns);
    const std::int64_t wake_ns = monotonic_now_ns();
    out.wake.add(wake_ns - deadline_ns);
    if (previous_ns != 0) out.period.add(wake_ns - previous_ns - period_ns);
    previous_ns = wake_ns;
    deadline_ns += period_ns;
    if (deadline_ns <= wake_ns) {
      const std::int64_t missed = (wake_ns - deadline_ns) / period_ns + 1;
      out.missed += missed;
      deadline_ns += missed * period_ns;
    }
  }
}

double ratio(double a, double b) { return b > 0.0 ? a / b : 0.0; }

void print_row(const char* name, const JitterStats& loop, const JitterStats& floor) {
  fmt::print(
      "{:<22} {:9.1f} {:9.1f} {:9.1f} | {:9.1f} {:9.1f} {:9.1f} | {:6.2f} {:6.2f} {:6.2f}\n", name,
      loop.quantile_us(0.5), loop.quantile_us(0.99), loop.max_us(), floor.quantile_us(0.5),
      floor.quantile_us(0.99), floor.max_us(), ratio(loop.quantile_us(0.5), floor.quantile_us(0.5)),
      ratio(loop.quantile_us(0.99), floor.quantile_us(0.99)), ratio(loop.max_us(), floor.max_us()));
}

int run(int argc, char** argv) {
  CLI::App app{"Haptic loop period jitter beside a bare clock_nanosleep loop"};
  double seconds = 60.0;
  std::string config_path = "config/haptics.yaml";
  std::string vehicle_path = "calib/vehicle_core_paper.yaml";
  app.add_option("--seconds", seconds, "Duration of the run")->check(CLI::Range(0.5, 3600.0));
  app.add_option("--config", config_path, "Haptics config");
  app.add_option("--vehicle", vehicle_path, "Vehicle file (camera mount for eq. 9)");
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;

  const hq::haptics::HapticsConfig config = hq::haptics::load_haptics_config(config_path);
  const hq::VehicleConfig vehicle = hq::load_vehicle_config(vehicle_path);
  hq::haptics::SimulatedDevice device(config.sim);
  hq::haptics::HapticLoop loop(device, config, vehicle.camera.R_B_C());

  const hq::haptics::RealtimeGrant grant = loop.start();
  std::atomic<bool> running{true};
  BareLoop bare;
  const auto period_ns = static_cast<std::int64_t>(1e9 / config.loop.rate_hz);
  std::thread bare_thread([&] { run_bare_loop(period_ns, running, bare); });
  if (grant.fifo) {
    sched_param parameter{};
    parameter.sched_priority = grant.priority;
    pthread_setschedparam(bare_thread.native_handle(), SCHED_FIFO, &parameter);
  }
  // The ground's DDS side: 100 Hz, reads the command, feeds back a lagging vehicle estimate.
  std::thread feeder([&] {
    hq::haptics::VehicleEstimate estimate;
    estimate.valid = true;
    while (running.load()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      const hq::haptics::LoopOutput out = loop.latest();
      estimate.v_H_mps += 0.03 * (out.command.v_H_mps - estimate.v_H_mps);
      estimate.yaw_rate_radps += 0.03 * (out.command.yaw_rate_radps - estimate.yaw_rate_radps);
      estimate.t_ns = monotonic_now_ns();
      loop.set_vehicle_estimate(estimate);
    }
  });

  fmt::print("hq-bench-haptic-loop: {:.0f} Hz for {:.1f} s, device sim\n{}\n", config.loop.rate_hz,
             seconds, grant.summary);
  std::fflush(stdout);
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  const hq::haptics::LoopOutput last = loop.latest();
  loop.stop();
  running.store(false);
  bare_thread.join();
  feeder.join();

  const hq::haptics::LoopTimingReport& timing = loop.timing();
  fmt::print("\n{:<22} {:>29} | {:>29} | {:>20}\n", "", "haptic loop (us)",
             "bare nanosleep floor (us)", "ratio");
  fmt::print("{:<22} {:>9} {:>9} {:>9} | {:>9} {:>9} {:>9} | {:>6} {:>6} {:>6}\n", "", "p50", "p99",
             "max", "p50", "p99", "max", "p50", "p99", "max");
  print_row("|period - nominal|", timing.period, bare.period);
  print_row("wake - deadline", timing.wake, bare.wake);
  fmt::print("\nperiods: loop {}, floor {}; missed deadlines: loop {}, floor {}\n",
             timing.period.count(), bare.period.count(), timing.missed_deadlines, bare.missed);
  fmt::print("real-time: {}\n", grant.fifo ? "SCHED_FIFO granted" : "NOT granted (SCHED_OTHER)");
  fmt::print("last tick {}: passivity E {:.4f} J, status \"{}\"\n", last.tick,
             last.passivity_energy_j, last.status.data());
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-bench-haptic-loop", argc, argv, run); }
