#pragma once
/// The closed loop in simulation: the software-in-the-loop Simulator flies the real on-board
/// chain (OnboardChain: odometry -> estimator -> obstacles -> modes -> PID), commanded by a
/// scripted operator, all on simulated time (lock-step), so a run is a pure function of
/// (configs, world, seed, script) whatever the machine's load.
///
/// The loop is the vehicle's own: the VehicleRuntime (onboard/vehicle) with the simulator as its
/// flight controller and camera (sim_vehicle.hpp), so every flight here runs the code path of a
/// real vehicle. Timing as on the vehicle: IMU samples reach the chain as the simulator produces
/// them; a frame is processed at its stamp and every setpoint reaches the flight controller a
/// processing delay later; between frames the chain is ticked at the flight computer's rate
/// (camera timeout). Camera faults (dropped frames, NaN depth) can be injected on a schedule.
///
/// Never linked into flight code: this is the test bench around it.

#include "hq/closed_loop/operator_script.hpp"
#include "hq/closed_loop/sim_vehicle.hpp"
#include "hq/geometry/camera_mount.hpp"
#include "hq/pipeline/onboard_chain.hpp"
#include "hq/pipeline/stage_timing.hpp"
#include "hq/sim/simulator.hpp"
#include "hq/vehicle/vehicle_runtime.hpp"
#include "hq/vehicle_config/vehicle_config.hpp"

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace hq::closed_loop {

/// Supplies the operator's command and mode requests in place of the scripted player (the DDS
/// link in hq-onboard --link), and sees what the loop produces. Called on run_until()'s thread.
class OperatorSource {
 public:
  virtual ~OperatorSource() = default;
  /// At control tick t_ns (simulated time): the command to fly; mode requests that fall due are
  /// appended to `mode_requests`.
  virtual modes::OperatorCommand poll(std::int64_t t_ns,
                                      std::vector<modes::Mode>& mode_requests) = 0;
  /// What the chain answered to one of those requests.
  virtual void on_mode_result(std::int64_t /*t_ns*/, modes::Mode /*mode*/,
                              const modes::ModeSwitch& /*result*/) {}
  /// Every recorded chain output, with the simulator's truth at that moment.
  virtual void on_output(const pipeline::ChainOutput& /*out*/, const sim::TruthState& /*truth*/) {}
  /// Every rendered camera image (as rendered: BGR or gray) at its stamp.
  virtual void on_camera(std::int64_t /*t_ns*/, const cv::Mat& /*image*/) {}
};

struct ClosedLoopOptions {
  /// Frame stamp to setpoint at the flight controller: the chain's median at 640x480 is ~3 ms
  /// (hq-bench-chain) plus the serial link to the flight controller.
  double processing_delay_s = 0.010;
  /// Rate at which the chain is ticked between frames and the operator command refreshed.
  std::int64_t control_period_ns = 5'000'000;
  std::vector<CameraFault> faults;
  /// Optional, not owned: times the chain's stages (wall time; the flight itself stays on
  /// simulated time). Null: no timing.
  const pipeline::Clock* clock = nullptr;
  /// Optional, not owned: the operator's command and mode requests come from here instead of
  /// the player (whose script then only gives end_s).
  OperatorSource* operator_source = nullptr;
  /// Optional, not owned, instead of operator_source: a vehicle operator port (the DDS link),
  /// with marker tasks and runtime events. Sees every output with the simulator's truth.
  vehicle::OperatorPort* operator_port = nullptr;
  /// Paced to wall time (CLOCK_MONOTONIC, absolute sleeps): simulated time tracks real time,
  /// as needed when a live operator flies it over the link. Off: as fast as possible.
  bool realtime = false;
};

/// One row of the flight record, per processed frame and per camera-timeout tick. Velocities in
/// H (NED, yaw only), yaw rates about NED z.
struct FlightSample {
  double t_s = 0.0;
  bool frame = false;  ///< From a frame (false: a camera-timeout tick).
  bool airborne = false;
  bool estimate_ok = false;
  bool safe_hover = false;
  bool degraded = false;  ///< The chain says its estimate is degraded or absent.
  bool collision = false;
  bool landed = false;  ///< The vehicle's own belief: on the ground, motors idle.
  modes::Mode mode = modes::Mode::kHover;
  Eigen::Vector3d v_est_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_true_mps = Eigen::Vector3d::Zero();
  /// Roll and pitch (NED, ZYX Euler): the estimator's, which levels the inertial coast's
  /// acceleration, and the truth's.
  Eigen::Vector2d roll_pitch_est_rad = Eigen::Vector2d::Zero();
  Eigen::Vector2d roll_pitch_true_rad = Eigen::Vector2d::Zero();
  Eigen::Vector3d v_star_des_mps = Eigen::Vector3d::Zero();  ///< The operator's, after ramps.
  Eigen::Vector3d v_des_mps = Eigen::Vector3d::Zero();       ///< v*_des + v_obs.
  Eigen::Vector3d v_obs_mps = Eigen::Vector3d::Zero();
  double yaw_rate_cmd_radps = 0.0;
  double yaw_rate_gyro_radps = 0.0;  ///< The estimator's low-passed, bias-corrected gyro z.
  double yaw_rate_true_radps = 0.0;
  double clearance_m = 0.0;  ///< Truth: surface to the vehicle sphere.
  /// The vehicle's own clearance as sent in its state (ChainOutput, ClearanceFilter); < 0: none.
  double clearance_sent_m = -1.0;
  Eigen::Vector3d p_N_m = Eigen::Vector3d::Zero();  ///< Truth, in the simulator's NWU world N.
  const char* reason = "";                          ///< Static text when safe_hover.
  /// The vehicle's own flight state and height above the floor (ChainOutput).
  modes::FlightState flight_state = modes::FlightState::kLanded;
  double height_m = 0.0;
  pipeline::HeightSource height_source = pipeline::HeightSource::kNone;
  double hover_thrust_gain = 1.0;  ///< Actual over commanded thrust, as learnt (ChainOutput).
  /// The chain's odom pose (ChainOutput::odom) and, for it, the truth's heading: the body's x
  /// axis in N as a NED yaw (clockwise from N's x seen from above).
  pipeline::OdomPoseEstimate odom;
  double heading_true_ned_rad = 0.0;
};

class ClosedLoop {
 public:
  /// @throws hq::InputError if the simulator or the chain reject their configs.
  ClosedLoop(const sim::SimConfig& sim_config, const sim::World& world,
             const pipeline::OnboardConfig& onboard, const VehicleConfig& vehicle,
             OperatorPlayer player, ClosedLoopOptions options = {});
  ~ClosedLoop();
  ClosedLoop(const ClosedLoop&) = delete;
  ClosedLoop& operator=(const ClosedLoop&) = delete;

  /// Advances the loop to simulated time t_s (no-op if already there).
  void run_until(double t_s);
  /// Sets options.operator_port after construction (a port that needs the loop's chain).
  /// @pre nothing run yet and no operator_source given.
  void set_operator_port(vehicle::OperatorPort* port) { options_.operator_port = port; }
  /// Runs to the script's end_s.
  void run() { run_until(player_.script().end_s); }

  [[nodiscard]] const std::vector<FlightSample>& samples() const { return samples_; }
  /// Smallest clearance (surface to vehicle sphere) seen at any physics tick while airborne.
  [[nodiscard]] double min_clearance_m() const { return min_clearance_m_; }
  /// Control ticks with the vehicle sphere inside an obstacle while airborne.
  [[nodiscard]] int collision_ticks() const { return collision_ticks_; }
  /// Mode requests the vehicle refused, as "t_s: mode: reason".
  [[nodiscard]] const std::vector<std::string>& refusals() const { return refusals_; }

  /// Stage durations of every frame after the first (all zero without options.clock).
  [[nodiscard]] const pipeline::StageTimingLog& timing() const { return timing_; }
  /// With options.realtime: the largest lag of a control tick behind its wall-clock time.
  [[nodiscard]] double max_realtime_lag_s() const {
    return 1e-9 * static_cast<double>(max_lag_ns_);
  }

  [[nodiscard]] sim::Simulator& simulator() { return *sim_; }
  [[nodiscard]] const sim::Simulator& simulator() const { return *sim_; }
  [[nodiscard]] pipeline::OnboardChain& chain() { return *chain_; }
  [[nodiscard]] const vehicle::VehicleRuntime& runtime() const { return *runtime_; }
  /// The runtime itself: begin_stop() when a run over the link ends.
  [[nodiscard]] vehicle::VehicleRuntime& runtime() { return *runtime_; }
  /// Simulated time reached by run_until().
  [[nodiscard]] std::int64_t t_ns() const { return t_ns_; }
  [[nodiscard]] const SimFlightController& flight_controller() const { return *fc_; }
  [[nodiscard]] const OperatorPlayer& player() const { return player_; }

 private:
  class Port;
  void pace(std::int64_t t_ns);
  void record(const pipeline::ChainOutput& out);

  std::unique_ptr<sim::Simulator> sim_;
  std::unique_ptr<pipeline::OnboardChain> chain_;
  OperatorPlayer player_;
  ClosedLoopOptions options_;
  std::unique_ptr<SimFlightController> fc_;
  std::unique_ptr<SimCamera> camera_;
  std::unique_ptr<Port> port_;
  std::unique_ptr<vehicle::VehicleRuntime> runtime_;
  std::int64_t t_ns_ = 0;
  std::vector<FlightSample> samples_;
  pipeline::StageTimingLog timing_;
  int frames_processed_ = 0;
  std::vector<std::string> refusals_;
  double min_clearance_m_ = 1e9;
  int collision_ticks_ = 0;
  bool have_wall_origin_ = false;
  std::int64_t wall_origin_ns_ = 0;  ///< CLOCK_MONOTONIC at simulated time 0 (realtime).
  std::int64_t max_lag_ns_ = 0;
};

/// The camera heading alpha of eq. 9, for scripts that command along it.
using geometry::camera_heading_rad;

}  // namespace hq::closed_loop
