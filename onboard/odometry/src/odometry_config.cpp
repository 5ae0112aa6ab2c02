#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/odometry/dense_odometry.hpp"

#include "frame.hpp"

#include <limits>
#include <sstream>
#include <string>

namespace hq::odometry {

namespace {

using detail::kMaxLevels;

}  // namespace

const char* to_string(TrackingStatus status) {
  switch (status) {
    case TrackingStatus::kFirstFrame:
      return "first_frame";
    case TrackingStatus::kOk:
      return "ok";
    case TrackingStatus::kLost:
      return "lost";
  }
  return "unknown";
}

namespace {

// Range checks of validate(): each names where.key, the value and what was expected.
class ConfigChecker {
 public:
  explicit ConfigChecker(const std::string& where) : where_(where) {}

  void in_range(const char* key, double value, double min, double max) const {
    if (!(value >= min && value <= max)) {
      fail(key, value, "expected in [" + text(min) + ", " + text(max) + "]");
    }
  }
  void positive(const char* key, double value, double max) const {
    if (!(value > 0.0)) fail(key, value, "expected > 0");
    if (!(value <= max)) fail(key, value, "expected in [0, " + text(max) + "]");
  }
  [[noreturn]] void fail(const char* key, double value, const std::string& expected) const {
    throw InputError(where_ + "." + key + " = " + text(value) + ", " + expected);
  }
  static std::string text(double value) {
    std::ostringstream s;
    s << value;
    return s.str();
  }

 private:
  const std::string& where_;
};

// "file: odometry" of a section, the prefix validate() puts before each key.
std::string section_name(const config::StrictMap& section) {
  std::string where = section.describe("");
  if (!where.empty() && where.back() == '.') where.pop_back();
  return where;
}

}  // namespace

void validate(const OdometryConfig& c, const std::string& where) {
  const ConfigChecker check(where);
  check.in_range("pyramid_levels", c.pyramid_levels, 1, kMaxLevels);
  check.in_range("finest_level", c.finest_level, 0, kMaxLevels - 1);
  if (c.finest_level >= c.pyramid_levels) {
    check.fail("finest_level", c.finest_level,
               "expected < pyramid_levels (" + std::to_string(c.pyramid_levels) + ")");
  }
  check.in_range("max_iterations_per_level", c.max_iterations_per_level, 1, 200);
  check.positive("step_tolerance", c.step_tolerance, 1.0);
  check.positive("min_depth_m", c.min_depth_m, 100.0);
  check.positive("max_depth_m", c.max_depth_m, 1000.0);
  if (c.max_depth_m <= c.min_depth_m) {
    check.fail("max_depth_m", c.max_depth_m,
               "expected > min_depth_m (" + ConfigChecker::text(c.min_depth_m) + ")");
  }
  check.in_range("min_gradient", c.min_gradient, 0.0, 255.0);
  check.positive("student_t_dof", c.student_t_dof, 1000.0);
  check.in_range("min_valid_ratio", c.min_valid_ratio, 0.0, 1.0);
  check.in_range("motion_prior_precision", c.motion_prior_precision, 0.0, 1e6);
  check.in_range("keyframe_entropy_ratio", c.keyframe_entropy_ratio, 0.0, 1.0);
  check.in_range("keyframe_min_valid_ratio", c.keyframe_min_valid_ratio, 0.0, 1.0);
  check.in_range("max_keyframe_age", c.max_keyframe_age, 1, 100000);
  check.positive("keyframe_check_max_translation_m", c.keyframe_check_max_translation_m, 10.0);
  check.positive("keyframe_check_max_rotation_deg", c.keyframe_check_max_rotation_deg, 180.0);
  check.in_range("occlusion_depth_ratio", c.occlusion_depth_ratio, 0.0, 10.0);
  check.in_range("moving_residual_sigmas", c.moving_residual_sigmas, 0.0, 100.0);
  check.in_range("max_moving_ratio", c.max_moving_ratio, 0.0, 1.0);
  check.in_range("moving_min_displacement_px", c.moving_min_displacement_px, 0.0, 100.0);
  check.in_range("moving_mark_radius_px", c.moving_mark_radius_px, 1, 32);
  check.in_range("moving_realign_ratio", c.moving_realign_ratio, 0.0, 1.0);
  check.positive("depth_noise_per_m", c.depth_noise_per_m, 1.0);
  check.in_range("depth_point_stride", c.depth_point_stride, 1, 64);
  check.positive("depth_max_spread_ratio", c.depth_max_spread_ratio, 1.0);
  check.in_range("depth_levels", c.depth_levels, 0, kMaxLevels);
  if (c.depth_levels > c.pyramid_levels - c.finest_level) {
    check.fail("depth_levels", c.depth_levels,
               "expected <= pyramid_levels - finest_level (" +
                   std::to_string(c.pyramid_levels - c.finest_level) + ")");
  }
  check.in_range("depth_normal_smoothing_levels", c.depth_normal_smoothing_levels, 0, kMaxLevels);
  check.in_range("depth_max_incidence_deg", c.depth_max_incidence_deg, 1.0, 89.0);
  check.in_range("min_translation_information_ratio", c.min_translation_information_ratio, 0.0,
                 1.0);
  check.in_range("degenerate_step_ratio", c.degenerate_step_ratio, 0.0, 1.0);
  check.in_range("rotation_prior_information_scale", c.rotation_prior_information_scale, 0.0, 1e6);
  check.positive("vision_information_scale", c.vision_information_scale, 1.0);
  check.positive("gyro_bias_sigma_radps", c.gyro_bias_sigma_radps, 1.0);
  check.in_range("gyro_bias_random_walk", c.gyro_bias_random_walk, 0.0, 1.0);
  check.positive("gyro_bias_gate_chi2", c.gyro_bias_gate_chi2, 1e6);
  check.in_range("vision_information_frames", c.vision_information_frames, 1, 100000);
  check.in_range("vision_only_iterations", c.vision_only_iterations, 1, 200);
  check.positive("max_translation_sigma_m", c.max_translation_sigma_m, 100.0);
}

void read_config(config::StrictMap& section, OdometryConfig& out) {
  // Types and keys here; every range in validate(), which the constructor runs as well.
  constexpr double kAny = std::numeric_limits<double>::infinity();
  constexpr int kAnyInt = std::numeric_limits<int>::max();
  section.read("pyramid_levels", out.pyramid_levels, -kAnyInt, kAnyInt);
  section.read("finest_level", out.finest_level, -kAnyInt, kAnyInt);
  section.read("max_iterations_per_level", out.max_iterations_per_level, -kAnyInt, kAnyInt);
  section.read("step_tolerance", out.step_tolerance, -kAny, kAny);
  section.read("min_depth_m", out.min_depth_m, -kAny, kAny);
  section.read("max_depth_m", out.max_depth_m, -kAny, kAny);
  section.read("min_gradient", out.min_gradient, -kAny, kAny);
  section.read("student_t_dof", out.student_t_dof, -kAny, kAny);
  section.read("min_valid_ratio", out.min_valid_ratio, -kAny, kAny);
  section.read("use_motion_prior", out.use_motion_prior);
  section.read("motion_prior_precision", out.motion_prior_precision, -kAny, kAny);
  section.read("initialize_with_previous_motion", out.initialize_with_previous_motion);
  section.read("estimate_brightness_offset", out.estimate_brightness_offset);
  std::string mode =
      out.reference_mode == ReferenceMode::kFrameToFrame ? "frame_to_frame" : "frame_to_keyframe";
  section.read("reference_mode", mode, {"frame_to_frame", "frame_to_keyframe"});
  out.reference_mode =
      mode == "frame_to_frame" ? ReferenceMode::kFrameToFrame : ReferenceMode::kFrameToKeyframe;
  section.read("keyframe_entropy_ratio", out.keyframe_entropy_ratio, -kAny, kAny);
  section.read("keyframe_min_valid_ratio", out.keyframe_min_valid_ratio, -kAny, kAny);
  section.read("max_keyframe_age", out.max_keyframe_age, -kAnyInt, kAnyInt);
  section.read("keyframe_check", out.keyframe_check);
  section.read("keyframe_check_max_translation_m", out.keyframe_check_max_translation_m, -kAny,
               kAny);
  section.read("keyframe_check_max_rotation_deg", out.keyframe_check_max_rotation_deg, -kAny, kAny);
  section.read("use_depth_term", out.use_depth_term);
  section.read("occlusion_depth_ratio", out.occlusion_depth_ratio, -kAny, kAny);
  section.read("moving_residual_sigmas", out.moving_residual_sigmas, -kAny, kAny);
  section.read("max_moving_ratio", out.max_moving_ratio, -kAny, kAny);
  section.read("drop_moving_keyframe_points", out.drop_moving_keyframe_points);
  section.read("moving_min_displacement_px", out.moving_min_displacement_px, -kAny, kAny);
  section.read("moving_mark_radius_px", out.moving_mark_radius_px, -kAnyInt, kAnyInt);
  section.read("moving_realign_ratio", out.moving_realign_ratio, -kAny, kAny);
  section.read("dense_moving_marks", out.dense_moving_marks);
  section.read("depth_noise_per_m", out.depth_noise_per_m, -kAny, kAny);
  section.read("depth_point_stride", out.depth_point_stride, -kAnyInt, kAnyInt);
  section.read("depth_max_spread_ratio", out.depth_max_spread_ratio, -kAny, kAny);
  section.read("depth_levels", out.depth_levels, -kAnyInt, kAnyInt);
  section.read("depth_jacobian_from_normals", out.depth_jacobian_from_normals);
  section.read("depth_normal_smoothing_levels", out.depth_normal_smoothing_levels, -kAnyInt,
               kAnyInt);
  section.read("depth_max_incidence_deg", out.depth_max_incidence_deg, -kAny, kAny);
  section.read("min_translation_information_ratio", out.min_translation_information_ratio, -kAny,
               kAny);
  section.read("degenerate_step_ratio", out.degenerate_step_ratio, -kAny, kAny);
  section.read("align_depth_to_colour", out.align_depth_to_colour);
  section.read("use_rotation_prior", out.use_rotation_prior);
  section.read("rotation_prior_information_scale", out.rotation_prior_information_scale, -kAny,
               kAny);
  section.read("vision_information_scale", out.vision_information_scale, -kAny, kAny);
  section.read("estimate_gyro_bias", out.estimate_gyro_bias);
  section.read("gyro_bias_sigma_radps", out.gyro_bias_sigma_radps, -kAny, kAny);
  section.read("gyro_bias_random_walk", out.gyro_bias_random_walk, -kAny, kAny);
  section.read("gyro_bias_gate_chi2", out.gyro_bias_gate_chi2, -kAny, kAny);
  section.read("adapt_vision_information", out.adapt_vision_information);
  section.read("vision_information_frames", out.vision_information_frames, -kAnyInt, kAnyInt);
  section.read("vision_only_iterations", out.vision_only_iterations, -kAnyInt, kAnyInt);
  section.read("max_translation_sigma_m", out.max_translation_sigma_m, -kAny, kAny);
  section.finish();
  validate(out, section_name(section));
}

}  // namespace hq::odometry
