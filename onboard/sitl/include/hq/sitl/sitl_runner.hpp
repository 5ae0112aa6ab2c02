#pragma once
/// hq-sim --sitl: the simulator as a separate process, as PX4 SITL runs. It owns the world,
/// physics, IMU and RGB-D renderer, paces them to real time (CLOCK_MONOTONIC), plays the flight
/// controller over MAVLink (SitlAutopilot) and publishes every rendered frame into a shared-memory
/// frame channel with the host-clock stamp of its exposure.

#include "hq/sim/simulator.hpp"
#include "hq/sitl/sitl_autopilot.hpp"

#include <atomic>
#include <cstdint>
#include <string>

namespace hq::sitl {

struct SitlOptions {
  std::string mavlink_spec = "udp-listen:14560";  ///< hq::mavlink::open_transport spec.
  std::string channel = "sitl";                   ///< Frame channel /hq-<channel>.
  double duration_s = 0.0;                        ///< Simulated seconds; 0: until stopped.
  std::int64_t tick_ns = 2'000'000;               ///< FC loop and pacing step (500 Hz).
  bool status_lines = true;                       ///< A status line on stderr every second.
  SitlAutopilotConfig autopilot;
};

/// Opens the frame channel and the MAVLink transport (hq::InputError when the channel is owned
/// by a live hq-sim or the port is in use), runs until `stop` or the duration, prints the
/// summary on stdout and returns the exit status (0). The channel is unlinked on return.
int run_sitl(sim::Simulator& sim, const SitlOptions& options, const std::atomic<bool>& stop);

}  // namespace hq::sitl
