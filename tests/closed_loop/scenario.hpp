#pragma once
// Shared set-up of the closed-loop tests: the default configs from the repository, a script
// built in code, and an airborne start for the campaigns.

#include "hq/closed_loop/closed_loop.hpp"
#include "hq/closed_loop/operator_script.hpp"
#include "hq/control/vehicle_config.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/world.hpp"

#include <memory>
#include <utility>
#include <vector>

namespace hq::closed_loop::testing {

struct Scenario {
  sim::SimConfig sim = sim::load_sim_config("onboard/sim/config/sim.yaml");
  sim::World world;
  pipeline::OnboardConfig onboard = pipeline::load_onboard_config("config/onboard.yaml");
  control::VehicleConfig vehicle = control::load_vehicle_config("calib/vehicle_core_paper.yaml");
  OperatorScript script;
  ClosedLoopOptions options;

  /// Starts in the air at altitude_m, hovering, with the chain told so (campaigns skip the
  /// take-off, which the core-paper flight covers).
  void start_airborne(double altitude_m) {
    world.start_world_m.z() = altitude_m;
    onboard.modes.start_landed = false;
  }

  void step(double t_s, std::optional<Eigen::Vector3d> v_mps = std::nullopt,
            std::optional<double> yaw_rate_radps = std::nullopt,
            std::optional<modes::Mode> mode = std::nullopt) {
    OperatorStep s;
    s.t_s = t_s;
    s.v_mps = v_mps;
    s.yaw_rate_radps = yaw_rate_radps;
    s.mode = mode;
    script.steps.push_back(s);
  }

  [[nodiscard]] std::unique_ptr<ClosedLoop> make() const {
    return std::make_unique<ClosedLoop>(
        sim, world, onboard, vehicle,
        OperatorPlayer(script, vehicle.camera.heading_rad()), options);
  }
};

}  // namespace hq::closed_loop::testing
