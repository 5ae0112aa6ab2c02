#pragma once
// hq-onboard's run modes, one file each: replay and live cameras (frame_source_runs.cpp), the
// simulator with a script or over the DDS link (sim_runs.cpp); hq_onboard.cpp parses the
// command line and picks one.

#include "hq/link/config.hpp"
#include "hq/pipeline/onboard_chain.hpp"

#include <atomic>
#include <chrono>
#include <cstdint>
#include <string>

namespace hq::onboard_app {

class SteadyClock final : public hq::pipeline::Clock {
 public:
  std::int64_t now_ns() const override {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
};

struct Options {
  std::string source_kind;
  std::string sequence_dir;
  std::string camera_path;
  std::string config_path = "config/onboard.yaml";
  std::string vehicle_path = "calib/vehicle_core_paper.yaml";
  std::string csv_path;
  std::string world_path;
  std::string script_path;
  std::string sim_config_path = "onboard/sim/config/sim.yaml";
  std::string resolution = "320x240";
  long long seed = -1;
  bool link = false;
  double duration_s = 60.0;
  std::string link_config_path;
  hq::link::LinkOverrides link_overrides;
  double command_timeout_ms = 200.0;
  double heartbeat_timeout_ms = 2000.0;
  double camera_rate_hz = 10.0;
  std::string link_log_path;
  std::string save_map_path;
};

/// Set by SIGINT/SIGTERM; runs that last (sim --link, cameras) stop cleanly when it is.
extern std::atomic<bool> g_stop;
void request_stop(int signal);

/// One live status line on stderr (overwritten in place).
void print_status(const pipeline::ChainOutput& out, int frames);

int run_replay(const Options& o);
int run_live(const Options& o);
int run_sim(const Options& o);
int run_sim_link(const Options& o);

}  // namespace hq::onboard_app
