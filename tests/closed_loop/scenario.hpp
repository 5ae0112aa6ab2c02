#pragma once
// Shared set-up of the closed-loop tests: the default configs from the repository, a script
// built in code, and an airborne start for the campaigns.

#include "hq/closed_loop/closed_loop.hpp"
#include "hq/closed_loop/operator_script.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/world.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace hq::closed_loop::testing {

struct Scenario {
  sim::SimConfig sim = sim::load_sim_config("onboard/sim/config/sim.yaml");
  sim::World world;
  pipeline::OnboardConfig onboard = pipeline::load_onboard_config("config/onboard.yaml");
  VehicleConfig vehicle = load_vehicle_config("calib/vehicle_core_paper.yaml");
  OperatorScript script;
  ClosedLoopOptions options;

  /// Starts in the air at altitude_m, hovering, with the chain told so (campaigns skip the
  /// take-off, which the core-paper flight covers).
  void start_airborne(double altitude_m) {
    world.start_N_m.z() = altitude_m;
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

  /// Adds a box with noise texture `salt` whose near face is distance_m in front of the camera
  /// of a vehicle at the world's start with NED yaw start_yaw_rad (the camera heading in the
  /// NWU world is yaw + alpha, with NWU y = -NED east).
  void add_box_in_view(double start_yaw_rad, double distance_m, const Eigen::Vector3d& size_m,
                       double box_yaw_rad, std::uint32_t salt) {
    const double heading = start_yaw_rad + vehicle.camera.heading_rad();
    const Eigen::Vector2d dir(std::cos(heading), -std::sin(heading));
    sim::Box box;
    box.size_m = size_m;
    box.yaw_rad = box_yaw_rad;
    const double half_depth = 0.5 * std::max(box.size_m.x(), box.size_m.y());
    box.center_m << (distance_m + half_depth) * dir, 0.5 * box.size_m.z();
    box.texture.kind = sim::Texture::Kind::kNoise;
    box.texture.scale_m = 0.06f;
    box.texture.contrast = 0.5f;
    box.texture.salt = salt;
    world.boxes.push_back(box);
  }

  [[nodiscard]] std::unique_ptr<ClosedLoop> make() const {
    return std::make_unique<ClosedLoop>(sim, world, onboard, vehicle,
                                        OperatorPlayer(script, vehicle.camera.heading_rad()),
                                        options);
  }
};

}  // namespace hq::closed_loop::testing
