#pragma once
// Marker-mode flights in the marker_grid world: the closed loop with the marker stage enabled,
// and simulator truth of the markers in the map's terms.

#include "hq/closed_loop/closed_loop.hpp"
#include "hq/closed_loop/operator_script.hpp"
#include "hq/marker_modes/marker_navigation.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/world.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

namespace hq::marker_modes::test {

inline constexpr const char* kWorld = "onboard/sim/worlds/marker_grid.yaml";
inline constexpr const char* kVehicle = "calib/vehicle_core_paper.yaml";

struct Flight {
  sim::World world;
  std::unique_ptr<closed_loop::ClosedLoop> loop;

  marker_modes::MarkerStage& stage() { return *loop->chain().markers(); }
  /// Truth centre of marker `id` (world NWU).
  [[nodiscard]] Eigen::Vector3d marker_truth_m(int id) const {
    for (const sim::Marker& m : world.markers) {
      if (m.id == id) return m.center_N_m;
    }
    return Eigen::Vector3d::Constant(NAN);
  }
  [[nodiscard]] Eigen::Vector3d p_truth_m() {
    return loop->simulator().truth().T_N_B.translation();
  }
};

/// @param imu  the simulated IMU instead of onboard/sim/config/sim.yaml's (e.g. larger biases).
inline Flight make_flight(const std::string& script, std::uint64_t seed,
                          closed_loop::ClosedLoopOptions options = {},
                          const std::optional<sim::ImuParams>& imu = std::nullopt) {
  Flight f;
  f.world = sim::load_world(kWorld);
  sim::SimConfig sim_config = sim::load_sim_config("onboard/sim/config/sim.yaml");
  sim::set_resolution(sim_config, "320x240", "test");
  sim_config.seed = seed;
  if (imu) sim_config.imu = *imu;
  pipeline::OnboardConfig config = pipeline::load_onboard_config("config/onboard.yaml");
  config.markers.enabled = true;
  const VehicleConfig vehicle = load_vehicle_config(kVehicle);
  closed_loop::OperatorPlayer player(closed_loop::load_operator_script(script),
                                     vehicle.camera.heading_rad());
  f.loop = std::make_unique<closed_loop::ClosedLoop>(sim_config, f.world, config, vehicle,
                                                     std::move(player), options);
  return f;
}

}  // namespace hq::marker_modes::test
