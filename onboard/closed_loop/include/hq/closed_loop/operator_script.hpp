#pragma once
/// A scripted operator: a timeline of velocity commands and mode requests standing in for the
/// haptic device until the DDS link exists, and for reproducible flights afterwards.
///
/// File layout (YAML, strict):
///   frame: camera_heading        # or horizontal
///   end_s: 30                    # the flight ends here
///   steps:
///     - {t_s: 1.0, mode: teleop, v_mps: [0, 0, -0.4]}
///     - {t_s: 3.5, v_mps: [0, 0, 0], yaw_rate_degps: -20}
///     - {t_s: 25, mode: land}
/// Each step holds from t_s until the next one (zero-order hold, as a hand resting on the
/// device); a key a step leaves out keeps its previous value. With `frame: camera_heading` v_mps
/// is [forward, right, down] about the camera's heading alpha (eq. 9), so [v, 0, w] is exactly
/// what eqs. 6-8 produce from an end-effector displacement; with `horizontal` it is H itself.

#include "hq/modes/mode_controller.hpp"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <vector>

namespace hq::closed_loop {

struct OperatorStep {
  double t_s = 0.0;
  std::optional<modes::Mode> mode;  ///< Requested at t_s, once.
  std::optional<Eigen::Vector3d> v_mps;
  std::optional<double> yaw_rate_radps;
};

enum class CommandFrame { kCameraHeading, kHorizontal };

struct OperatorScript {
  CommandFrame frame = CommandFrame::kCameraHeading;
  double end_s = 0.0;
  std::vector<OperatorStep> steps;  ///< Strictly increasing t_s.
};

/// Loads a script; throws hq::InputError naming file, step and key (unknown keys, unsorted or
/// negative times, unknown modes, non-finite numbers, steps after end_s).
OperatorScript load_operator_script(const std::string& path);

/// The mode name used in scripts and on the command line ("teleop", "hover", "land", ...).
std::optional<modes::Mode> mode_from_string(const std::string& name);

/// Plays a script: the held command at any time, and the mode requests as they fall due.
class OperatorPlayer {
 public:
  /// @param alpha_rad  camera heading in Q, eq. 9 (used with CommandFrame::kCameraHeading).
  OperatorPlayer(OperatorScript script, double alpha_rad);

  /// The command holding at t_s, in H (yaw rate about NED z).
  [[nodiscard]] modes::OperatorCommand command(std::int64_t t_ns) const;
  /// Mode requests whose time is in (previous call, t_ns], oldest first; appended to `out`.
  void take_mode_requests(std::int64_t t_ns, std::vector<modes::Mode>& out);

  [[nodiscard]] const OperatorScript& script() const { return script_; }

 private:
  OperatorScript script_;
  double alpha_rad_;
  std::vector<Eigen::Vector3d> v_H_mps_;  ///< Per step, held values resolved in H.
  std::vector<double> yaw_rate_radps_;
  std::size_t next_mode_step_ = 0;
};

}  // namespace hq::closed_loop
