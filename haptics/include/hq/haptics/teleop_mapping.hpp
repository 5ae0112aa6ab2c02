#pragma once
/// The operator's command and cue, §3.3 of the core paper.
///
/// Frames: D haptic device, NED, origin at the resting point of the end effector (x away from
/// the operator, y right, z down); H horizontal NED frame of the vehicle; Q body NED; C camera.
///
/// Eq. 6-10, applied to the dead-banded displacement p = D_p:
///   v_x = k_v p_x cos(alpha),  v_y = k_v p_x sin(alpha),  v_z = -k_v p_z,  yaw_rate = -k_psi p_y
/// with alpha the yaw of the camera's viewing direction in Q (eq. 9). As printed, eq. 8 and 10
/// carry a minus sign with D and H both NED: pushing the handle down (+p_z) commands a climb
/// (-v_z) and pushing it right (+p_y) a yaw to the left. These are the paper's signs, kept.
///
/// Force on the hand (Franchi et al. 2012b form): F = -K_c p - K M^+ (u_cmd - u_est) - B p_dot,
/// u = (v_H, yaw_rate) and M the linear part of eq. 6-10, so M^+ maps a velocity error back to
/// the device displacement that would command it; the cue weight fades to zero when the vehicle
/// estimate goes stale; |F| is saturated. That saturation is the law's own; the device's cap is
/// limit_force(), last in HapticLoop, after the passivity damper.

#include "hq/haptics/haptics_config.hpp"

#include <Eigen/Core>

#include <cstdint>

namespace hq::haptics {

/// The operator's command: output of eq. 6-10.
struct VelocityCommand {
  Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();  ///< Desired velocity in H (NED).
  double yaw_rate_radps = 0.0;                        ///< Desired yaw rate (NED: + turns right).
};

/// Result of one mapping: a zero command with a static reason when the input is unusable.
struct MappedCommand {
  VelocityCommand command;
  bool valid = false;
  bool saturated = false;
  const char* reason = "";  ///< Static text when !valid.
};

/// The vehicle's estimate as the ground last received it.
struct VehicleEstimate {
  std::int64_t t_ns = 0;  ///< Receipt time on the haptic loop's clock (CLOCK_MONOTONIC).
  bool valid = false;     ///< False until a first estimate arrives.
  Eigen::Vector3d v_H_mps = Eigen::Vector3d::Zero();  ///< Estimated velocity in H (eq. 5).
  double yaw_rate_radps = 0.0;                        ///< Estimated yaw rate.
};

/// Eq. 6-10 with dead-band and saturation.
class TeleopMapping {
 public:
  /// @param R_B_C  R_QC in the optical convention of hq::VehicleConfig (z
  /// forward). @throws hq::InputError if the camera looks (nearly) straight up or down, where
  /// eq. 9 has no direction, or if the matrix is not a rotation.
  TeleopMapping(const MappingConfig& config, const Eigen::Matrix3d& R_B_C);

  /// Eq. 6-10 on the end-effector position p_D_m. Non-finite input gives a zero, invalid command.
  [[nodiscard]] MappedCommand map(const Eigen::Vector3d& p_D_m) const;

  /// M^+ u: the (dead-banded) displacement that eq. 6-10 maps to `command`, least squares for
  /// the part of v_H across alpha, which the device cannot command.
  [[nodiscard]] Eigen::Vector3d displacement_for(const VelocityCommand& command) const;

  /// Eq. 9: yaw of the camera's viewing direction in Q (rad).
  [[nodiscard]] double alpha_rad() const { return alpha_rad_; }
  [[nodiscard]] const MappingConfig& config() const { return config_; }

 private:
  MappingConfig config_;
  double alpha_rad_ = 0.0;
  double cos_alpha_ = 1.0;
  double sin_alpha_ = 0.0;
};

/// The force cue of one tick, in D.
struct FeedbackForce {
  Eigen::Vector3d F_D_n = Eigen::Vector3d::Zero();  ///< Force on the hand (local + cue).
  /// The part of F_D_n computed from the vehicle's state (the velocity-error cue, after the same
  /// saturation scale): the port the link's delay acts on, for the passivity controller.
  Eigen::Vector3d F_cue_D_n = Eigen::Vector3d::Zero();
  double cue_weight = 0.0;  ///< 1 fresh estimate, 0 stale or none; the fade in between.
  bool saturated = false;
};

/// Force feedback: centring spring, velocity-error cue mapped back to D, damping, saturation.
class ForceFeedback {
 public:
  /// @param mapping  the mapping whose inverse carries the cue back to D (copied).
  ForceFeedback(const FeedbackConfig& config, const TeleopMapping& mapping);

  /// @param t_ns  loop time; @param p_D_m, p_dot_D_mps  effector position and velocity;
  /// @param command  what was sent this tick; @param estimate  latest vehicle estimate.
  /// Non-finite inputs give zero force.
  [[nodiscard]] FeedbackForce compute(std::int64_t t_ns, const Eigen::Vector3d& p_D_m,
                                      const Eigen::Vector3d& p_dot_D_mps,
                                      const VelocityCommand& command,
                                      const VehicleEstimate& estimate) const;

  /// Cue weight: 1 up to stale_after_s, raised-cosine fade to 0 over fade_s, 0 without estimate.
  [[nodiscard]] double cue_weight(std::int64_t t_ns, const VehicleEstimate& estimate) const;

  [[nodiscard]] const FeedbackConfig& config() const { return config_; }

 private:
  FeedbackConfig config_;
  TeleopMapping mapping_;
};

}  // namespace hq::haptics
