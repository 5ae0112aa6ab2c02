// hq-bench-delay-campaign: the haptic loop flown over a delayed, jittery, lossy link with the
// operator's arm closing the loop (delay_campaign.hpp), per round trip, loss and with the
// passivity controller off and on, all in one run beside the no-delay baseline. Simulated time:
// the figures do not depend on the machine's load. Not run by ctest.

#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/haptics/delay_campaign.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <fmt/format.h>
#include <optional>
#include <string>
#include <vector>

namespace {

int run(int argc, char** argv) {
  {
    CLI::App app{"haptic teleoperation over a delayed, lossy link: passivity and transparency"};
    std::string haptics_path = "config/haptics.yaml";
    std::string vehicle_path = "calib/vehicle_core_paper.yaml";
    std::vector<double> round_trips_ms = {0, 100, 300, 600, 1000};
    std::vector<double> losses = {0.0, 0.1};
    double jitter_ms = 30.0;
    double seconds = 12.0;
    std::uint32_t seed = 1;
    app.add_option("--haptics", haptics_path, "haptics config")->check(CLI::ExistingFile);
    app.add_option("--vehicle", vehicle_path, "vehicle file (R_QC)")->check(CLI::ExistingFile);
    app.add_option("--rtt-ms", round_trips_ms, "round trips")->check(CLI::Range(0.0, 5000.0));
    app.add_option("--loss", losses, "loss probabilities")->check(CLI::Range(0.0, 0.9));
    app.add_option("--jitter-ms", jitter_ms, "one-way jitter (uniform +-)")
        ->check(CLI::Range(0.0, 1000.0));
    app.add_option("--seconds", seconds, "flight length")->check(CLI::Range(10.0, 600.0));
    app.add_option("--seed", seed, "link seed");
    double stiff_k = 200.0;
    app.add_option("--stiff-k", stiff_k, "cue stiffness of the stiff law (N/m)")
        ->check(CLI::Range(0.0, 5000.0));
    if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;

    hq::haptics::HapticsConfig shipped = hq::haptics::load_haptics_config(haptics_path);
    const Eigen::Matrix3d R_B_C = hq::load_vehicle_config(vehicle_path).camera.R_B_C();
    // The stiff law: what a user raising the cue's gain for a crisper feel gets. Fade off, so
    // the delayed cue stays on at every delay and the passivity controller is all that acts.
    hq::haptics::HapticsConfig stiff = shipped;
    stiff.feedback.velocity_stiffness_n_per_m = stiff_k;
    stiff.feedback.damping_ns_per_m = 2.0;
    stiff.feedback.stale_after_s = 5.0;
    hq::haptics::campaign::VehicleModel slow_vehicle;
    hq::haptics::campaign::VehicleModel fast_vehicle;
    fast_vehicle.lag_s = 0.15;
    fmt::print(
        "# arm 1 kg / 150 N/m / 5 N s/m, reaction 150 ms, yield 0.5; wall 3 m ahead; {:.0f} s "
        "flights; jitter +-{:.0f} ms on each one-way delay when the round trip is > 0; seed {}\n",
        seconds, jitter_ms, seed);
    const auto campaign = [&](const char* title, const hq::haptics::HapticsConfig& config,
                              const hq::haptics::campaign::VehicleModel& vehicle) {
      fmt::print("## {}: K {:.0f} N/m, B {:.1f} N s/m, fade after {:.2f} s, vehicle lag {:.2f} s\n",
                 title, config.feedback.velocity_stiffness_n_per_m,
                 config.feedback.damping_ns_per_m, config.feedback.stale_after_s, vehicle.lag_s);
      fmt::print(
          "{:>7} {:>5} {:>3} | {:>9} {:>9} {:>9} | {:>7} {:>7} {:>6} | {:>8} {:>8} | {:>9} {:>5}\n",
          "rtt_ms", "loss", "pc", "minE_J", "finalE_J", "dissip_J", "F_rms_N", "Fid_rms", "transp",
          "track", "hand_osc", "clear_m", "coll");
      for (const double rtt_ms : round_trips_ms) {
        for (const double loss : losses) {
          for (const bool pc : {false, true}) {
            hq::haptics::HapticsConfig run_config = config;
            run_config.feedback.passivity_control = pc;
            hq::haptics::campaign::LinkModel link;
            link.round_trip_s = 1e-3 * rtt_ms;
            link.jitter_s = rtt_ms > 0.0 ? 1e-3 * jitter_ms : 0.0;
            link.loss = loss;
            link.seed = seed;
            const hq::haptics::campaign::RunResult r =
                hq::haptics::campaign::run(run_config, R_B_C, link, {}, vehicle, seconds);
            fmt::print(
                "{:7.0f} {:5.2f} {:>3} | {:9.4f} {:9.4f} {:9.4f} | {:7.3f} {:7.3f} {:6.2f} | "
                "{:8.3f} {:8.4f} | {:9.3f} {:5}\n",
                rtt_ms, r.loss_measured, pc ? "on" : "off", r.min_energy_j, r.final_energy_j,
                r.dissipated_j, r.force_rms_n, r.ideal_force_rms_n, r.transparency,
                r.tracking_rms_mps, r.hold_hand_speed_rms_mps, r.min_clearance_m, r.collisions);
          }
        }
      }
    };
    campaign("shipped force law", shipped, slow_vehicle);
    campaign("stiff force law", stiff, fast_vehicle);
    fmt::print(
        "# minE: min over the flight of the device port's energy (J, >= 0 passive); transp: 1 - "
        "rms(F - F_ideal) / rms(F_ideal), F_ideal the law on the true state now; track: rms |v - "
        "v_cmd| (m/s); hand_osc: rms effector speed while the intent holds (m/s)\n");
    return 0;
  }
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-bench-delay-campaign", argc, argv, run); }
