#pragma once
/// The DDS link as the vehicle runtime's operator: commands and mode requests through the
/// fail-safes of the LinkBridge, and back to the ground the vehicle state (with the obstacle
/// memory's cloud, the marker filter's pose and, in simulation only, truth), camera frames and
/// the runtime's events. The same for every frame source and flight controller.

#include "hq/link_bridge/link_bridge.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/vehicle/vehicle_runtime.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <cstdio>
#include <string_view>
#include <vector>

namespace hq::link_bridge {

class LinkOperatorPort : public vehicle::OperatorPort {
 public:
  /// @param chain  the chain whose obstacle memory and marker stage go out with the state;
  ///               T_B_C its camera's extrinsics (the vehicle's own, not a simulator's truth).
  /// @param log    optional: fail-safe transitions are printed here (e.g. stdout).
  LinkOperatorPort(LinkBridge& bridge, const pipeline::OnboardChain& chain,
                   const Eigen::Isometry3d& T_B_C, std::FILE* log = nullptr);

  modes::OperatorCommand poll(std::int64_t t_ns,
                              std::vector<pipeline::ModeRequest>& requests) override;
  void on_mode_result(std::int64_t t_ns, const pipeline::ModeRequest& request,
                      const modes::ModeSwitch& result) override;
  void on_output(const pipeline::ChainOutput& out, const vehicle::VehicleStatus& status) override;
  void on_frame(const sources::RgbdFrame& frame) override;
  void on_event(std::int64_t t_ns, vehicle::FcSeverity severity, std::string_view text) override;

  [[nodiscard]] LinkBridge& bridge() { return bridge_; }

 private:
  LinkBridge& bridge_;
  const pipeline::OnboardChain& chain_;
  Eigen::Isometry3d T_C_B_;
  std::FILE* log_;
};

}  // namespace hq::link_bridge
