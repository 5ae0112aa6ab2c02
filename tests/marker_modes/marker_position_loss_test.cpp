// Marker mode when the markers leave the view for 30 s, with IMU biases beyond the simulator's
// default: the marker pose is never flown on, nor shown valid, once it may have drifted. GIVEN a
// hold over the target marker WHEN every marker is hidden for 30 s THEN
// - while the pose says valid, its horizontal error against simulator truth stays within
//   kMaxUnflaggedErrorM;
// - it turns invalid within navigation.position_max_age_s (plus one camera frame) of the last
//   marker, and an event says why in plain words;
// - no step of marker mode flies on an invalid pose: the provider gives no command and the
//   controller hovers on the velocity estimate;
// - with the markers back it resumes (event), and holds over the marker again.

#include "hq/closed_loop/operator_script.hpp"
#include "hq/marker_modes/marker_providers.hpp"
#include "hq/markers/testing/sim_marker_truth.hpp"

#include "scenario.hpp"
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <string>
#include <vector>

namespace hq::marker_modes {
namespace {

/// While the pose says valid its horizontal error against truth stays below this. Measured
/// (seed 5): 0.049 m worst with the biases below, 0.104 m with six times the simulator's; the
/// margin is for other seeds and the filter's 5 s coast at the age limit.
constexpr double kMaxUnflaggedErrorM = 0.25;
/// The chain's outputs come with the camera's frames (30 Hz, 33-34 ms apart on the simulator's
/// 1 ms clock), so a check is seen to turn within one frame: 34 ms measured, 40 ms allowed.
constexpr double kOutputPeriodS = 1.0 / 30.0;
constexpr double kOutputSlackS = 0.040;
constexpr double kHideAtS = 20.0;
constexpr double kHiddenForS = 30.0;
/// Twice the simulator's default biases (onboard/sim/config/sim.yaml), the filter's own initial
/// bias sigmas (navigation.initial_*_bias_sigma_*).
constexpr double kGyroBiasSigmaRadps = 0.01;
constexpr double kAccelBiasSigmaMps2 = 0.1;

std::string write_script() {
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / "hq_marker_position_loss.yaml";
  std::ofstream(path) << "frame: camera_heading\n"
                         "end_s: 70\n"
                         "steps:\n"
                         "  - {t_s: 0.0, mode: teleop, v_mps: [0, 0, 0]}\n"
                         "  - {t_s: 1.0, v_mps: [0, 0, -0.4]}\n"
                         "  - {t_s: 3.5, v_mps: [0, 0, 0]}\n"
                         "  - {t_s: 4.5, mode: marker}\n";
  return path.string();
}

/// The operator (the script) and an observer of every step and event.
class Observer final : public vehicle::OperatorPort {
 public:
  Observer(closed_loop::OperatorPlayer player, test::Flight& flight)
      : player_(std::move(player)), flight_(flight) {}

  modes::OperatorCommand poll(std::int64_t t_ns,
                              std::vector<pipeline::ModeRequest>& requests) override {
    modes_.clear();
    player_.take_mode_requests(t_ns, modes_);
    for (const modes::Mode mode : modes_) requests.push_back({mode, std::nullopt});
    return player_.command(t_ns);
  }

  void on_output(const pipeline::ChainOutput& out, const vehicle::VehicleStatus&) override {
    MarkerStage& stage = flight_.stage();
    const MarkerNavigation& nav = stage.navigation();
    const navigation::PositionCheck check = nav.position_check(out.t_ns);
    const double t_s = 1e-9 * static_cast<double>(out.t_ns);
    if (check.valid && invalid_at_s < 0) last_marker_s = t_s - check.age_s;
    if (hidden && !check.valid) {
      if (invalid_at_s < 0) invalid_at_s = t_s;
      last_invalid_s = t_s;
    }
    const navigation::NavigationHealth health = nav.filter().health();
    if (!hidden) {
      max_disagreeing_frames = std::max(max_disagreeing_frames, health.disagreeing_marker_frames);
    }
    if (check.valid && !nav.map().ids().empty()) {
      // Truth in W: the map frame is the first marker's, W is it turned by R_W_map.
      const int first = nav.map().ids().front();
      for (const sim::Marker& m : flight_.world.markers) {
        if (m.id != first) continue;
        const Eigen::Vector3d p_W_truth =
            R_W_map() * (hq::markers::test::T_N_M(m).inverse() * flight_.p_truth_m());
        const double e = (nav.p_W_m() - p_W_truth).head<2>().norm();
        max_valid_error_m = std::max(max_valid_error_m, e);
        if (hidden) max_valid_error_hidden_m = std::max(max_valid_error_hidden_m, e);
      }
    }
    if (out.mode.mode == modes::Mode::kMarker) {
      const bool usable = nav.pose_usable(out.t_ns);
      if (!usable) {
        ++steps_invalid_in_marker;
        if (!out.mode.provider_failed) ++steps_flown_on_invalid;
      }
    }
  }

  void on_event(std::int64_t t_ns, vehicle::FcSeverity, std::string_view text) override {
    events.push_back({1e-9 * static_cast<double>(t_ns), std::string(text)});
  }

  bool hidden = false;
  double last_marker_s = -1.0;  ///< Of the last valid check before the pose went invalid.
  double invalid_at_s = -1.0;
  double last_invalid_s = -1.0;
  double max_valid_error_m = 0.0;
  double max_valid_error_hidden_m = 0.0;
  int max_disagreeing_frames = 0;
  long steps_invalid_in_marker = 0;
  long steps_flown_on_invalid = 0;
  std::vector<std::pair<double, std::string>> events;

 private:
  closed_loop::OperatorPlayer player_;
  test::Flight& flight_;
  std::vector<modes::Mode> modes_;
};

const std::pair<double, std::string>* find_event(const Observer& o, const std::string& prefix) {
  for (const auto& e : o.events) {
    if (e.second.rfind(prefix, 0) == 0) return &e;
  }
  return nullptr;
}

TEST(MarkerPositionLoss, MarkersHiddenThirtySecondsNeverFlownOnAnInvalidPose) {
  sim::ImuParams imu;
  imu.gyro_initial_bias_sigma_radps = kGyroBiasSigmaRadps;
  imu.accel_initial_bias_sigma_mps2 = kAccelBiasSigmaMps2;
  const std::string script = write_script();
  test::Flight f = test::make_flight(script, 5, {}, imu);
  const double alpha_rad = load_vehicle_config(test::kVehicle).camera.heading_rad();
  Observer observer(
      closed_loop::OperatorPlayer(closed_loop::load_operator_script(script), alpha_rad), f);
  f.loop->set_operator_port(&observer);
  const double limit_s = f.stage().navigation().config().navigation.position_max_age_s;
  const int id = f.stage().marker_mode().config().target_id;

  f.loop->run_until(kHideAtS);
  ASSERT_EQ(f.loop->chain().mode(), modes::Mode::kMarker);
  const navigation::PositionCheck before =
      f.stage().navigation().position_check(static_cast<std::int64_t>(kHideAtS * 1e9));
  ASSERT_TRUE(before.valid) << "before the gap: " << navigation::to_string(before.reason)
                            << ", age " << before.age_s << " s, sigma " << before.sigma_horizontal_m
                            << " m";
  f.stage().navigation().set_markers_hidden(true);
  observer.hidden = true;
  f.loop->run_until(kHideAtS + kHiddenForS);
  const navigation::PositionCheck at_end = f.stage().navigation().position_check(
      static_cast<std::int64_t>((kHideAtS + kHiddenForS) * 1e9));
  const Eigen::Vector3d p_truth_hidden = f.p_truth_m();
  observer.hidden = false;
  f.stage().navigation().set_markers_hidden(false);
  f.loop->run_until(kHideAtS + kHiddenForS + 15.0);
  const navigation::PositionCheck after = f.stage().navigation().position_check(
      static_cast<std::int64_t>((kHideAtS + kHiddenForS + 15.0) * 1e9));
  const double hold_error_m = (f.p_truth_m() - f.marker_truth_m(id)).head<2>().norm();

  const auto* lost = find_event(observer, "marker mode: position lost (no marker for");
  const auto* resumed = find_event(observer, "marker mode: position valid again, resuming");
  fmt::print(
      "markers hidden {:.0f} s at {:.0f} s (gyro bias sigma {:.3f} rad/s, accel {:.2f} m/s^2)\n",
      kHiddenForS, kHideAtS, kGyroBiasSigmaRadps, kAccelBiasSigmaMps2);
  fmt::print("  last marker {:.3f} s, invalid from {:.3f} s to {:.3f} s (limit {:.1f} s)\n",
             observer.last_marker_s, observer.invalid_at_s, observer.last_invalid_s, limit_s);
  fmt::print(
      "  worst horizontal error while valid: {:.3f} m overall, {:.3f} m in the gap (bound {:.2f} "
      "m)\n",
      observer.max_valid_error_m, observer.max_valid_error_hidden_m, kMaxUnflaggedErrorM);
  const navigation::NavigationHealth health = f.stage().navigation().filter().health();
  fmt::print(
      "  markers accepted {}, gated {}, re-anchors {}; most frames in a row all gated with markers "
      "in view: {}; velocities accepted {}, gated {}\n",
      health.markers_accepted, health.markers_gated, health.reanchors,
      observer.max_disagreeing_frames, health.velocities_accepted, health.velocities_gated);
  fmt::print("  marker-mode steps on an invalid pose {}, of which flown {}\n",
             observer.steps_invalid_in_marker, observer.steps_flown_on_invalid);
  fmt::print("  at the gap's end: {}, sigma {:.2f} m; truth drift from the marker {:.2f} m\n",
             navigation::to_string(at_end.reason), at_end.sigma_horizontal_m,
             (p_truth_hidden - f.marker_truth_m(id)).head<2>().norm());
  for (const auto& e : observer.events) fmt::print("  event {:.2f} s: {}\n", e.first, e.second);
  fmt::print("  15 s after: {}, hold error {:.3f} m\n", navigation::to_string(after.reason),
             hold_error_m);

  EXPECT_LT(observer.max_valid_error_m, kMaxUnflaggedErrorM);
  ASSERT_GT(observer.invalid_at_s, 0.0) << "the pose never became invalid without markers";
  EXPECT_GT(observer.invalid_at_s - observer.last_marker_s, limit_s);
  EXPECT_LE(observer.invalid_at_s - observer.last_marker_s, limit_s + kOutputSlackS);
  // Invalid for the rest of the gap.
  EXPECT_GT(observer.last_invalid_s - observer.invalid_at_s, kHiddenForS - limit_s - 0.2);
  EXPECT_FALSE(at_end.valid);
  EXPECT_GT(observer.steps_invalid_in_marker,
            static_cast<long>((kHiddenForS - limit_s) / kOutputPeriodS * 0.95));
  EXPECT_EQ(observer.steps_flown_on_invalid, 0) << "marker mode flew on an invalid pose";
  ASSERT_NE(lost, nullptr) << "no event said the position was lost";
  EXPECT_NEAR(lost->first, observer.invalid_at_s, 1e-6);
  EXPECT_NE(lost->second.find("holding"), std::string::npos);
  ASSERT_NE(resumed, nullptr) << "no event said marker mode resumed";
  EXPECT_GT(resumed->first, kHideAtS + kHiddenForS);
  EXPECT_TRUE(after.valid) << navigation::to_string(after.reason);
  EXPECT_EQ(f.loop->chain().mode(), modes::Mode::kMarker);
  EXPECT_LT(hold_error_m, 0.10);
  EXPECT_EQ(f.loop->collision_ticks(), 0);
}

// GIVEN IMU biases six times the simulator's (beyond the filter's initial bias sigmas, so its
// bias states converge slowly and its markers and velocities fail their gates) WHEN the markers
// are hidden 30 s THEN the checks still keep every pose shown valid within kMaxUnflaggedErrorM of
// truth, and marker mode flies on none that is invalid. With the age and sigma checks alone (the
// frame and velocity consistency checks off) a pose read valid 44 m from truth 2.5 s after the
// last marker: the filter's covariance did not see its own divergence.
TEST(MarkerPositionLoss, FilterFightingLargeBiasesIsFlaggedNotFlown) {
  sim::ImuParams imu;
  imu.gyro_initial_bias_sigma_radps = 6.0 * 0.005;
  imu.accel_initial_bias_sigma_mps2 = 6.0 * 0.05;
  const std::string script = write_script();
  test::Flight f = test::make_flight(script, 5, {}, imu);
  const double alpha_rad = load_vehicle_config(test::kVehicle).camera.heading_rad();
  Observer observer(
      closed_loop::OperatorPlayer(closed_loop::load_operator_script(script), alpha_rad), f);
  f.loop->set_operator_port(&observer);
  f.loop->run_until(kHideAtS);
  f.stage().navigation().set_markers_hidden(true);
  observer.hidden = true;
  f.loop->run_until(kHideAtS + kHiddenForS);
  const navigation::NavigationHealth health = f.stage().navigation().filter().health();
  fmt::print(
      "6x biases: worst error while valid {:.3f} m (bound {:.2f} m); markers accepted {}, gated "
      "{}, re-anchors {}; velocities gated {}; marker-mode steps on an invalid pose {}, flown {}\n",
      observer.max_valid_error_m, kMaxUnflaggedErrorM, health.markers_accepted,
      health.markers_gated, health.reanchors, health.velocities_gated,
      observer.steps_invalid_in_marker, observer.steps_flown_on_invalid);
  EXPECT_LT(observer.max_valid_error_m, kMaxUnflaggedErrorM);
  EXPECT_GT(observer.steps_invalid_in_marker, 0);
  EXPECT_EQ(observer.steps_flown_on_invalid, 0);
  EXPECT_GT(observer.invalid_at_s, 0.0);
  EXPECT_FALSE(f.stage()
                   .navigation()
                   .position_check(static_cast<std::int64_t>((kHideAtS + kHiddenForS) * 1e9))
                   .valid);
}

}  // namespace
}  // namespace hq::marker_modes
