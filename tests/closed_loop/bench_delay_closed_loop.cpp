// hq-bench-delay-closed-loop: the shipped haptic loop with the operator's arm flying the real
// closed loop (simulator + on-board chain, room world) over a delayed, jittery, lossy link, per
// round trip, with the passivity controller off and on, in one run beside the no-delay flight.
// Simulated time. Not run by ctest (hq_delay_closed_loop_test keeps a small variant).

#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"

#include "delayed_operator.hpp"
#include <CLI/CLI.hpp>

#include <cstdio>
#include <fmt/format.h>
#include <optional>
#include <vector>

namespace {

int run(int argc, char** argv) {
  CLI::App app{"the closed loop flown with haptics over a delayed, lossy link"};
  std::vector<double> round_trips_ms = {0, 100, 300, 600, 1000};
  double loss = 0.05;
  double jitter_ms = 30.0;
  double end_s = 20.0;
  std::uint32_t seed = 1;
  app.add_option("--rtt-ms", round_trips_ms, "round trips")->check(CLI::Range(0.0, 5000.0));
  app.add_option("--loss", loss, "loss probability when the round trip is > 0")
      ->check(CLI::Range(0.0, 0.9));
  app.add_option("--jitter-ms", jitter_ms, "one-way jitter (uniform +-)")
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--seconds", end_s, "flight length")->check(CLI::Range(19.0, 600.0));
  app.add_option("--seed", seed, "link seed");
  double stiff_k = 200.0;
  app.add_option("--stiff-k", stiff_k, "cue stiffness of the stiff law (N/m), 0: shipped only")
      ->check(CLI::Range(0.0, 5000.0));
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  const hq::haptics::HapticsConfig shipped =
      hq::haptics::load_haptics_config("config/haptics.yaml");
  // The stiff law: a crisper cue that never fades, so only the passivity controller acts.
  hq::haptics::HapticsConfig stiff = shipped;
  stiff.feedback.velocity_stiffness_n_per_m = stiff_k;
  stiff.feedback.damping_ns_per_m = 2.0;
  stiff.feedback.stale_after_s = 5.0;
  fmt::print(
      "# room world, 320x240, {:.0f} s: climb, push towards the wall along the camera heading, "
      "pull back; jitter +-{:.0f} ms and loss {:.2f} when the round trip is > 0\n",
      end_s, jitter_ms, loss);
  const auto campaign = [&](const char* title, const hq::haptics::HapticsConfig& config) {
    fmt::print("## {}: K {:.0f} N/m, B {:.1f} N s/m, fade after {:.2f} s\n", title,
               config.feedback.velocity_stiffness_n_per_m, config.feedback.damping_ns_per_m,
               config.feedback.stale_after_s);
    fmt::print("{:>7} {:>3} | {:>9} {:>9} | {:>7} {:>8} | {:>9} {:>9} {:>6} {:>6}\n", "rtt_ms",
               "pc", "minE_J", "dissip_J", "F_rms_N", "track", "clear_m", "coll_tick", "alt_m",
               "lossS");
    for (const double rtt_ms : round_trips_ms) {
      for (const bool pc : {false, true}) {
        hq::haptics::HapticsConfig run_config = config;
        run_config.feedback.passivity_control = pc;
        hq::haptics::campaign::LinkModel link;
        link.round_trip_s = 1e-3 * rtt_ms;
        link.jitter_s = rtt_ms > 0.0 ? 1e-3 * jitter_ms : 0.0;
        link.loss = rtt_ms > 0.0 ? loss : 0.0;
        link.seed = seed;
        const hq::closed_loop::delay::FlightResult r =
            hq::closed_loop::delay::fly(run_config, link, end_s);
        fmt::print(
            "{:7.0f} {:>3} | {:9.4f} {:9.4f} | {:7.3f} {:8.3f} | {:9.3f} {:9} {:6.2f} {:6.3f}\n",
            rtt_ms, pc ? "on" : "off", r.min_energy_j, r.dissipated_j, r.force_rms_n,
            r.tracking_rms_mps, r.min_clearance_m, r.collision_ticks, r.max_altitude_m,
            r.state_loss);
        std::fflush(stdout);
      }
    }
  };
  campaign("shipped force law", shipped);
  if (stiff_k > 0.0) campaign("stiff force law", stiff);
  fmt::print(
      "# minE: least device-port energy (J, >= 0 passive); track: rms |v_est - v_cmd| (m/s); "
      "clear_m: least clearance; coll_tick: control ticks in collision; lossS: states lost\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return hq::run_tool("hq-bench-delay-closed-loop", argc, argv, run);
}
