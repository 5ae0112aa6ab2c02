#pragma once
/// The marker and explore modes as VelocityProviders of the one ModeController: each
/// turns the filter's pose in the marker map into v*_des in H and a yaw rate; the controller
/// adds v_obs and ramps every switch, so the obstacle field and bumpless switching hold here too.

#include "hq/marker_modes/marker_navigation.hpp"
#include "hq/modes/mode_controller.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <optional>

namespace hq::marker_modes {

enum class MarkerTask { kHold, kGoTo, kLand };
const char* to_string(MarkerTask task);

/// Mode::kMarker: hold a pose above a marker, go to one, or land on one.
class MarkerModeProvider final : public modes::VelocityProvider {
 public:
  MarkerModeProvider(const MarkerModeConfig& config, const MarkerNavigation& navigation);

  /// Holding and going keep the height; landing aligns, descends, then asks for Mode::kLand.
  void set_task(MarkerTask task, int marker_id);
  modes::ModeCommand desired(std::int64_t t_ns) override;

  /// Low over the marker: the chain should switch to Mode::kLand for the touchdown.
  [[nodiscard]] bool wants_land() const { return wants_land_; }
  [[nodiscard]] MarkerTask task() const { return task_; }
  [[nodiscard]] const MarkerModeConfig& config() const { return config_; }
  [[nodiscard]] int marker_id() const { return marker_id_; }
  /// Horizontal distance to the marker (W) at the last command.
  [[nodiscard]] double horizontal_error_m() const { return horizontal_error_m_; }

 private:
  /// Target not mapped: towards the mapped field's middle, then turning in place.
  modes::ModeCommand search(double yaw_rad, const Eigen::Vector3d& p_m);

  MarkerModeConfig config_;
  const MarkerNavigation& navigation_;
  MarkerTask task_ = MarkerTask::kHold;
  int marker_id_ = 0;
  bool descending_ = false;
  bool wants_land_ = false;
  bool have_yaw_ = false;
  double yaw_hold_rad_ = 0.0;
  std::int64_t t_last_ns_ = 0;
  double horizontal_error_m_ = 0.0;
};

enum class ExplorePhase { kLiftOff, kSearch, kExplore, kEdge, kNavigate, kLand, kDone };
const char* to_string(ExplorePhase phase);

/// Mode::kExplore, the smartphone seed's state machine: lift-off -> exploration (unseen frontier
/// cells of the coverage grid, the map built online) -> navigation to the target marker ->
/// land, with edge detection (no marker for 750 ms outside the map -> counter-steer back).
class ExploreProvider final : public modes::VelocityProvider {
 public:
  ExploreProvider(const ExploreConfig& config, const MarkerNavigation& navigation,
                  MarkerModeProvider& marker_mode);

  modes::ModeCommand desired(std::int64_t t_ns) override;

  [[nodiscard]] ExplorePhase phase() const { return phase_; }
  /// Seconds since the exploration phase began (0 before).
  [[nodiscard]] double exploring_for_s(std::int64_t t_ns) const;
  [[nodiscard]] int edge_events() const { return edge_events_; }
  [[nodiscard]] int cells_seen() const;
  /// Whether the explore flight wants the touchdown (Mode::kLand) now.
  [[nodiscard]] bool wants_land() const {
    return phase_ == ExplorePhase::kLand && marker_mode_.wants_land();
  }

 private:
  static constexpr int kCells = 41;  ///< Coverage grid kCells x kCells around the first marker.
  [[nodiscard]] bool cell_index(const Eigen::Vector2d& p_m, int& i, int& j) const;
  [[nodiscard]] Eigen::Vector2d cell_centre(int i, int j) const;
  /// Mapped markers' horizontal box in W; false with none.
  bool map_box(Eigen::Vector2d& lo, Eigen::Vector2d& hi) const;
  void mark_seen();
  bool choose_goal(const Eigen::Vector2d& p_m);
  void enter(ExplorePhase phase, std::int64_t t_ns);
  /// What every phase reads once per pass: time in the phase, pose (W, NED), targets.
  struct StepInputs {
    double in_phase_s = 0.0;
    bool have_pose = false;
    Eigen::Vector3d p_W_m = Eigen::Vector3d::Zero();
    double z_target_m = 0.0;  ///< The working height as z in W (NED: negative).
    double alpha_rad = 0.0;   ///< The camera's heading relative to the body's.
  };
  /// One pass of desired(): the phase's command, or nullopt after it handed over.
  std::optional<modes::ModeCommand> step(std::int64_t t_ns);
  std::optional<modes::ModeCommand> lift_off(std::int64_t t_ns, const StepInputs& in);
  std::optional<modes::ModeCommand> explore(std::int64_t t_ns, const StepInputs& in);
  std::optional<modes::ModeCommand> counter_steer(std::int64_t t_ns, const StepInputs& in);
  modes::ModeCommand fly_to(const Eigen::Vector3d& p_target_m, double yaw_target_rad) const;

  ExploreConfig config_;
  const MarkerNavigation& navigation_;
  MarkerModeProvider& marker_mode_;
  ExplorePhase phase_ = ExplorePhase::kLiftOff;
  bool started_ = false;
  std::int64_t t_phase_ns_ = 0;
  std::int64_t t_explore_ns_ = 0;
  bool exploring_started_ = false;
  std::array<unsigned char, kCells * kCells> seen_{};
  bool have_goal_ = false;
  int goal_i_ = 0;
  int goal_j_ = 0;
  std::int64_t t_goal_ns_ = 0;
  int edge_events_ = 0;
};

}  // namespace hq::marker_modes

namespace hq::marker_modes {

/// What the chain owns when `markers: enabled`: the navigation and both providers.
class MarkerStage {
 public:
  MarkerStage(const MarkerModesConfig& config, const geometry::PinholeCamera& camera,
              const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m);

  void on_imu(std::int64_t t_ns, const Eigen::Vector3d& gyro_radps,
              const Eigen::Vector3d& accel_mps2) {
    navigation_.on_imu(t_ns, gyro_radps, accel_mps2);
  }
  void on_frame(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m,
                const estimator::VelocityEstimate& estimate, bool odometry_ok,
                const Eigen::Isometry3d& T_O_C) {
    navigation_.on_frame(t_ns, gray, depth_m, estimate, odometry_ok, T_O_C);
  }
  /// In `mode`, the active provider wants the touchdown (Mode::kLand) now.
  [[nodiscard]] bool wants_land(modes::Mode mode) const;
  /// Called once per step with the chain's mode: in marker or explore mode, the text of an event
  /// when the pose just became unusable after being flown on ("marker mode: position lost (no
  /// marker for 5.0 s), holding") or usable again ("... position valid again, resuming"), else
  /// nullptr. The text lives until the next call. Allocates nothing.
  const char* position_event(modes::Mode mode, std::int64_t t_ns);
  /// In marker or explore mode, the pose became unusable after being flown on: hovering.
  [[nodiscard]] bool holding_for_position() const { return holding_; }

  [[nodiscard]] MarkerNavigation& navigation() { return navigation_; }
  [[nodiscard]] const MarkerNavigation& navigation() const { return navigation_; }
  [[nodiscard]] MarkerModeProvider& marker_mode() { return marker_mode_; }
  [[nodiscard]] ExploreProvider& explore() { return explore_; }
  [[nodiscard]] const MarkerModeProvider& marker_mode() const { return marker_mode_; }
  [[nodiscard]] const ExploreProvider& explore() const { return explore_; }

 private:
  MarkerNavigation navigation_;
  MarkerModeProvider marker_mode_;
  ExploreProvider explore_;
  bool flying_on_pose_ = false;
  bool holding_ = false;
  char event_text_[160] = {};
};

}  // namespace hq::marker_modes
