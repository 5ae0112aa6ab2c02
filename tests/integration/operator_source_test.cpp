// ClosedLoop with an external OperatorSource (what hq-onboard --link plugs the DDS link into):
// the source, not the script, commands the flight, hears every mode answer, output and frame.
#include "hq/closed_loop/closed_loop.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/sim/world.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <vector>

namespace hq::closed_loop {
namespace {

class ScriptedSource final : public OperatorSource {
 public:
  modes::OperatorCommand poll(std::int64_t t_ns, std::vector<modes::Mode>& requests) override {
    EXPECT_GT(t_ns, last_poll_ns);
    last_poll_ns = t_ns;
    ++polls;
    if (polls == 1) {
      requests.push_back(modes::Mode::kMarker);  // no provider registered: refused
      requests.push_back(modes::Mode::kTeleop);
    }
    modes::OperatorCommand command;
    command.t_ns = t_ns;
    const double t_s = 1e-9 * static_cast<double>(t_ns);
    if (t_s >= 1.0 && t_s < 3.5) command.v_H_mps.z() = -0.4;  // climb (NED)
    return command;
  }
  void on_mode_result(std::int64_t /*t_ns*/, modes::Mode mode,
                      const modes::ModeSwitch& result) override {
    results.push_back({mode, result.accepted});
  }
  void on_output(const pipeline::ChainOutput& /*out*/, const sim::TruthState& truth) override {
    ++outputs;
    max_altitude_m = std::max(max_altitude_m, truth.T_N_B.translation().z());
  }
  void on_camera(std::int64_t t_ns, const cv::Mat& image) override {
    EXPECT_FALSE(image.empty());
    EXPECT_GT(t_ns, last_camera_ns);
    last_camera_ns = t_ns;
    ++frames;
  }

  struct Result {
    modes::Mode mode;
    bool accepted;
  };
  std::vector<Result> results;
  std::int64_t last_poll_ns = 0;
  std::int64_t last_camera_ns = -1;
  int polls = 0;
  int outputs = 0;
  int frames = 0;
  double max_altitude_m = -1e9;
};

TEST(OperatorSource, CommandsTheFlightInsteadOfTheScript) {
  const sim::World world = sim::load_world("onboard/sim/worlds/room.yaml");
  sim::SimConfig sim_config = sim::load_sim_config("onboard/sim/config/sim.yaml");
  sim::set_resolution(sim_config, "320x240", "test");
  const pipeline::OnboardConfig onboard = pipeline::load_onboard_config("config/onboard.yaml");
  const VehicleConfig vehicle = load_vehicle_config("calib/vehicle_core_paper.yaml");
  OperatorScript script;  // no steps: the script only sets the end
  script.end_s = 6.0;
  ScriptedSource source;
  ClosedLoopOptions options;
  options.operator_source = &source;
  ClosedLoop loop(sim_config, world, onboard, vehicle,
                  OperatorPlayer(script, vehicle.camera.heading_rad()), options);
  loop.run();

  EXPECT_EQ(source.polls, 6.0 / 0.005);  // one poll per control tick
  ASSERT_EQ(source.results.size(), 2U);
  EXPECT_EQ(source.results[0].mode, modes::Mode::kMarker);
  EXPECT_FALSE(source.results[0].accepted);
  EXPECT_EQ(source.results[1].mode, modes::Mode::kTeleop);
  EXPECT_TRUE(source.results[1].accepted);
  EXPECT_EQ(loop.refusals().size(), 1U);
  EXPECT_EQ(source.outputs, static_cast<int>(loop.samples().size()));
  EXPECT_NEAR(source.frames, 6.0 * sim_config.camera.rate_hz, 2.0);
  // 2.5 s at 0.4 m/s climb from the floor: the source's command flew it, the empty script did not.
  EXPECT_GT(source.max_altitude_m, 0.6);
  EXPECT_TRUE(loop.samples().back().airborne);
  EXPECT_EQ(loop.samples().back().mode, modes::Mode::kTeleop);
  EXPECT_DOUBLE_EQ(loop.max_realtime_lag_s(), 0.0);  // not paced: never measured
}

}  // namespace
}  // namespace hq::closed_loop
