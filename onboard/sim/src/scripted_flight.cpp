#include "hq/sim/scripted_flight.hpp"

#include <algorithm>
#include <cmath>

namespace hq::sim {

namespace {
constexpr double kG = 9.81;
constexpr double kMaxTiltRad = 0.25;       // gentle: the script must not stress the tracker
constexpr double kCircleRampS = 2.0;       // speed ramped in so the start is smooth
constexpr double kPositionGain = 1.2;      // 1/s^2
constexpr double kVelocityGain = 1.8;      // 1/s
constexpr double kAltitudeGain = 3.0;      // 1/s^2
constexpr double kClimbDampingGain = 2.5;  // 1/s
}  // namespace

FlightScript script_for_world(const World& world, FlightScript::Kind kind) {
  FlightScript script;
  script.kind = kind;
  script.hover_xy_m = world.start_N_m.head<2>();
  const Eigen::Vector2d to_origin = -script.hover_xy_m;
  const Eigen::Vector2d inward =
      to_origin.norm() > 1e-6 ? to_origin.normalized() : Eigen::Vector2d(1.0, 0.0);
  script.circle_center_m = script.hover_xy_m + script.circle_radius_m * inward;
  return script;
}

AttitudeCommand scripted_command(const Simulator& sim, const FlightScript& s, double t_s) {
  const TruthState& truth = sim.truth();
  const double m = sim.config().vehicle.mass_kg;
  if (t_s < s.takeoff_s) return {0.0, 0.0, 0.0, 0.0};

  Eigen::Vector2d p_d = s.hover_xy_m;
  Eigen::Vector2d v_d = Eigen::Vector2d::Zero();
  Eigen::Vector2d a_ff = Eigen::Vector2d::Zero();
  double yaw_rate = 0.0;
  if (s.kind == FlightScript::Kind::kCircle && t_s > s.circle_start_s) {
    const double w = s.circle_speed_mps / s.circle_radius_m;
    const double phase = w * (t_s - s.circle_start_s);
    const Eigen::Vector2d r0 = s.hover_xy_m - s.circle_center_m;
    const double phase0 = std::atan2(r0.y(), r0.x());
    const Eigen::Vector2d radial(std::cos(phase0 + phase), std::sin(phase0 + phase));
    const Eigen::Vector2d tangent(-radial.y(), radial.x());
    const double ramp = std::min(1.0, (t_s - s.circle_start_s) / kCircleRampS);
    p_d = s.circle_center_m + s.circle_radius_m * radial;
    v_d = ramp * s.circle_speed_mps * tangent;
    a_ff = -ramp * s.circle_speed_mps * w * radial;
    yaw_rate = s.circle_yaw_rate_radps * ramp;
  }
  const Eigen::Vector3d p = truth.T_N_B.translation();
  const Eigen::Vector2d a_xy =
      a_ff + kPositionGain * (p_d - p.head<2>()) + kVelocityGain * (v_d - truth.v_N_mps.head<2>());
  const double a_z = kAltitudeGain * (s.altitude_m - p.z()) - kClimbDampingGain * truth.v_N_mps.z();

  // World (NWU) acceleration into the horizontal NED frame H, then tilt (core paper §3).
  const double yaw = truth.euler_rad.z();
  const double a_north = a_xy.x();
  const double a_east = -a_xy.y();
  const double a_forward = std::cos(yaw) * a_north + std::sin(yaw) * a_east;
  const double a_right = -std::sin(yaw) * a_north + std::cos(yaw) * a_east;
  const double pitch = std::clamp(-std::atan2(a_forward, kG + a_z), -kMaxTiltRad, kMaxTiltRad);
  const double roll =
      std::clamp(std::atan2(a_right * std::cos(pitch), kG + a_z), -kMaxTiltRad, kMaxTiltRad);
  return {m * (kG + a_z) / (std::cos(roll) * std::cos(pitch)), roll, pitch, yaw_rate};
}

}  // namespace hq::sim
