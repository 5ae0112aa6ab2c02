#include "hq/closed_loop/operator_script.hpp"

#include "hq/base/error.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/config/strict_yaml.hpp"

#include <cmath>
#include <numbers>
#include <utility>

namespace hq::closed_loop {

std::optional<modes::Mode> mode_from_string(const std::string& name) {
  for (const modes::Mode mode : {modes::Mode::kTeleop, modes::Mode::kHover, modes::Mode::kLand,
                                 modes::Mode::kMarker, modes::Mode::kExplore}) {
    if (name == modes::to_string(mode)) return mode;
  }
  return std::nullopt;
}

OperatorScript load_operator_script(const std::string& path) {
  const YAML::Node root = config::load_yaml_file(path);
  if (!root.IsMap()) throw InputError(path + ": expected a mapping with frame, end_s and steps");
  config::StrictMap map(root, path);
  OperatorScript script;
  std::string frame = "camera_heading";
  map.read("frame", frame, {"camera_heading", "horizontal"});
  script.frame = frame == "horizontal" ? CommandFrame::kHorizontal : CommandFrame::kCameraHeading;
  map.require("end_s", script.end_s, 0.0, 24.0 * 3600.0);
  map.skip("steps");
  map.finish();

  const YAML::Node steps = root["steps"];
  if (!steps || !steps.IsSequence() || steps.size() == 0) {
    throw InputError(path + ": steps = " + (steps ? YAML::Dump(steps) : std::string("(absent)")) +
                     ", expected a non-empty list of {t_s, mode, v_mps, yaw_rate_degps}");
  }
  for (std::size_t i = 0; i < steps.size(); ++i) {
    config::StrictMap s(steps[i], path, "steps[" + std::to_string(i) + "]");
    OperatorStep step;
    s.require("t_s", step.t_s, 0.0, script.end_s);
    if (!script.steps.empty() && !(step.t_s > script.steps.back().t_s)) {
      throw InputError(s.describe("t_s") + " = " + std::to_string(step.t_s) +
                       ", expected later than the previous step's " +
                       std::to_string(script.steps.back().t_s));
    }
    if (s.has("mode")) {
      std::string name;
      s.read("mode", name, {"teleop", "hover", "land", "marker", "explore"});
      step.mode = mode_from_string(name);
    }
    if (s.has("v_mps")) {
      Eigen::Vector3d v;
      s.read_list("v_mps", v.data(), 3);
      // 5 m/s bounds a script typo, not the vehicle: the on-board envelope clamps commands.
      for (int k = 0; k < 3; ++k) {
        if (!(std::abs(v[k]) <= 5.0)) {
          throw InputError(s.describe("v_mps") + "[" + std::to_string(k) +
                           "] = " + std::to_string(v[k]) + ", expected within [-5, 5] m/s");
        }
      }
      step.v_mps = v;
    }
    if (s.has("yaw_rate_degps")) {
      double yaw_rate_degps = 0.0;
      s.read("yaw_rate_degps", yaw_rate_degps, -360.0, 360.0);
      step.yaw_rate_radps = yaw_rate_degps * std::numbers::pi / 180.0;
    }
    s.finish();
    script.steps.push_back(step);
  }
  return script;
}

OperatorPlayer::OperatorPlayer(OperatorScript script, double alpha_rad)
    : script_(std::move(script)), alpha_rad_(alpha_rad) {
  Eigen::Vector3d v_held = Eigen::Vector3d::Zero();
  double yaw_rate_held = 0.0;
  const double c = std::cos(alpha_rad_);
  const double s = std::sin(alpha_rad_);
  for (const OperatorStep& step : script_.steps) {
    if (step.v_mps) {
      const Eigen::Vector3d& v = *step.v_mps;
      // eqs. 6-8: forward along alpha in H; "right" is alpha + 90 deg; down is H z.
      v_held = script_.frame == CommandFrame::kHorizontal
                   ? v
                   : Eigen::Vector3d(c * v.x() - s * v.y(), s * v.x() + c * v.y(), v.z());
    }
    if (step.yaw_rate_radps) yaw_rate_held = *step.yaw_rate_radps;
    v_H_mps_.push_back(v_held);
    yaw_rate_radps_.push_back(yaw_rate_held);
  }
}

modes::OperatorCommand OperatorPlayer::command(std::int64_t t_ns) const {
  modes::OperatorCommand command;
  command.t_ns = t_ns;
  const double t_s = hq::to_seconds(t_ns);
  for (std::size_t i = script_.steps.size(); i-- > 0;) {
    if (script_.steps[i].t_s <= t_s) {
      command.v_H_mps = v_H_mps_[i];
      command.yaw_rate_radps = yaw_rate_radps_[i];
      break;
    }
  }
  return command;
}

void OperatorPlayer::take_mode_requests(std::int64_t t_ns, std::vector<modes::Mode>& out) {
  const double t_s = hq::to_seconds(t_ns);
  while (next_mode_step_ < script_.steps.size() && script_.steps[next_mode_step_].t_s <= t_s) {
    if (const auto& mode = script_.steps[next_mode_step_].mode) out.push_back(*mode);
    ++next_mode_step_;
  }
}

}  // namespace hq::closed_loop
