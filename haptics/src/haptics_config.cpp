#include "hq/haptics/haptics_config.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"

#include <cmath>
#include <sstream>

namespace hq::haptics {
namespace {

void read_mapping(config::StrictMap& map, MappingConfig& out) {
  map.read_positive("velocity_gain_mps_per_m", out.velocity_gain_mps_per_m, 1000.0);
  map.read_positive("yaw_gain_radps_per_m", out.yaw_gain_radps_per_m, 1000.0);
  map.read("dead_band_m", out.dead_band_m, 0.0, 0.05);
  map.read_positive("max_horizontal_speed_mps", out.max_horizontal_speed_mps, 20.0);
  map.read_positive("max_vertical_speed_mps", out.max_vertical_speed_mps, 10.0);
  map.read_deg_as_rad("max_yaw_rate_degps", out.max_yaw_rate_radps, 1.0, 720.0);
  map.finish();
}

void read_feedback(config::StrictMap& map, FeedbackConfig& out) {
  map.read("centring_stiffness_n_per_m", out.centring_stiffness_n_per_m, 0.0, 5000.0);
  map.read("velocity_stiffness_n_per_m", out.velocity_stiffness_n_per_m, 0.0, 5000.0);
  map.read("yaw_stiffness_n_per_m", out.yaw_stiffness_n_per_m, 0.0, 5000.0);
  map.read("damping_ns_per_m", out.damping_ns_per_m, 0.0, 500.0);
  map.read_positive("max_force_n", out.max_force_n, 100.0);
  map.read("stale_after_s", out.stale_after_s, 0.001, 10.0);
  map.read("fade_s", out.fade_s, 0.0, 10.0);
  map.read("velocity_filter_hz", out.velocity_filter_hz, 1.0, 400.0);
  map.read("passivity_control", out.passivity_control);
  map.read_positive("passivity_max_damping_ns_per_m", out.passivity_max_damping_ns_per_m, 1000.0);
  map.finish();
}

void read_loop(config::StrictMap& map, LoopConfig& out) {
  map.read("rate_hz", out.rate_hz, 100.0, 10000.0);
  map.read("realtime", out.realtime);
  map.read("realtime_priority", out.realtime_priority, 1, 99);
  map.read("lock_memory", out.lock_memory);
  map.finish();
}

void read_script(const YAML::Node& node, const std::string& where, SimulatedDeviceConfig& out) {
  if (!node.IsDefined() || node.IsNull()) return;
  if (!node.IsSequence()) throw InputError(where + ": sim.script is not a list of keyframes");
  out.script.clear();
  double previous_t_s = -1.0;
  for (std::size_t i = 0; i < node.size(); ++i) {
    config::StrictMap keyframe(node[i], where, "sim.script[" + std::to_string(i) + "]");
    HandKeyframe k;
    keyframe.require("t_s", k.t_s, 0.0, 1e6);
    if (!(k.t_s > previous_t_s)) {
      std::ostringstream message;
      message << keyframe.describe("t_s") << " = " << k.t_s << ", expected > " << previous_t_s
              << " (keyframes sorted by time)";
      throw InputError(message.str());
    }
    previous_t_s = k.t_s;
    double p[3] = {0.0, 0.0, 0.0};
    keyframe.require_list("p_m", p, 3);
    for (int a = 0; a < 3; ++a) {
      if (std::abs(p[a]) > out.workspace_m) {
        std::ostringstream message;
        message << keyframe.describe("p_m") << "[" << a << "] = " << p[a] << ", expected in [-"
                << out.workspace_m << ", " << out.workspace_m << "] (sim.workspace_m)";
        throw InputError(message.str());
      }
    }
    k.p_D_m = Eigen::Vector3d(p[0], p[1], p[2]);
    int buttons = 0;
    keyframe.read("buttons", buttons, 0, 0xFFFF);
    k.buttons = static_cast<std::uint32_t>(buttons);
    keyframe.read("connected", k.connected);
    keyframe.finish();
    out.script.push_back(k);
  }
}

void read_sim(config::StrictMap& map, const YAML::Node& sim_node, const std::string& where,
              SimulatedDeviceConfig& out) {
  map.read_positive("mass_kg", out.mass_kg, 100.0);
  map.read("hand_stiffness_n_per_m", out.hand_stiffness_n_per_m, 0.0, 1e5);
  map.read("hand_damping_ns_per_m", out.hand_damping_ns_per_m, 0.0, 1e3);
  map.read("device_damping_ns_per_m", out.device_damping_ns_per_m, 0.0, 1e3);
  map.read_positive("workspace_m", out.workspace_m, 1.0);
  map.skip("script");
  map.finish();
  read_script(sim_node.IsDefined() && sim_node.IsMap() ? sim_node["script"] : YAML::Node(), where,
              out);
}

}  // namespace

void read_config(const YAML::Node& root_node, const std::string& where, HapticsConfig& out) {
  config::StrictMap root(root_node, where);
  config::StrictMap mapping = root.child("mapping");
  read_mapping(mapping, out.mapping);
  config::StrictMap feedback = root.child("feedback");
  read_feedback(feedback, out.feedback);
  config::StrictMap loop = root.child("loop");
  read_loop(loop, out.loop);
  config::StrictMap sim = root.child("sim");
  // Indexing a const node never inserts; a missing section reads as undefined.
  const YAML::Node& const_root = root_node;
  read_sim(sim, root_node.IsMap() ? const_root["sim"] : YAML::Node(), where, out.sim);
  config::StrictMap keyboard = root.child("keyboard");
  keyboard.read_positive("step_m", out.keyboard.step_m, 0.05);
  keyboard.read_positive("range_m", out.keyboard.range_m, 1.0);
  keyboard.finish();
  config::StrictMap joystick = root.child("joystick");
  joystick.read_positive("range_m", out.joystick.range_m, 1.0);
  joystick.read("index", out.joystick.index, 0, 64);
  joystick.read_positive("rumble_full_scale_n", out.joystick.rumble_full_scale_n, 100.0);
  joystick.finish();
  root.finish();
}

HapticsConfig load_haptics_config(const std::string& path) {
  HapticsConfig config;
  read_config(config::load_yaml_file(path), path, config);
  return config;
}

}  // namespace hq::haptics
