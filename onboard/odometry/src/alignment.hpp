#pragma once
// Coarse-to-fine iteratively re-weighted Gauss-Newton of a frame against a prepared reference
// (private to hq_odometry): warp, residuals, robust weights, one-pass normal equations per
// iteration, and the step with the motion and gyro priors.

#include "hq/odometry/dense_odometry.hpp"

#include "frame.hpp"
#include "kernels.hpp"
#include "normal_equations.hpp"
#include "reference_points.hpp"
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <vector>

namespace hq::odometry::detail {

/// The outcome of one alignment (or of its finest level again, Aligner::vision_only).
struct Alignment {
  Eigen::Isometry3d T_cur_ref = Eigen::Isometry3d::Identity();
  NormalEquations normal;
  float brightness_offset = 0.0f;
  double variance = 0.0;  // the photometric one, as solve_level() keeps it
  int valid = 0;
  int iterations = 0;
  double weighted_error = 0.0;
};

/// What one alignment starts from and is pulled towards: the constant-velocity prediction
/// (Kerl 2013's motion prior) and the gyro's rotation (the rotation prior).
struct Prediction {
  bool predict = false;    // the motion prior around T_ref_predicted applies
  bool use_prior = false;  // the gyro prior around R_ref_prior applies
  // A step that raises the cost is undone and ends the level. The cost is re-weighted every
  // iteration, so from a start near the minimum (vision_only()) it may rise on the first step
  // of a good descent; there the step tolerance alone ends it.
  bool stop_on_rising_cost = true;
  int max_iterations = 0;  // per level; 0: config.max_iterations_per_level
  Eigen::Isometry3d T_ref_predicted = Eigen::Isometry3d::Identity();
  // The last frame's data-term information: the motion prior's shape (when predict).
  Matrix6d last_information = Matrix6d::Zero();
  Eigen::Matrix3d R_ref_prior = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d prior_information = Eigen::Matrix3d::Zero();
  // The gyro step's alone (data-term units), for the alignment to the previous frame.
  Eigen::Matrix3d step_information = Eigen::Matrix3d::Zero();
};

/// Reference points that found a residual in the current frame.
struct Counts {
  int photometric = 0;  // points with an intensity residual
  int depth = 0;        // points with a depth residual
  int any = 0;          // points with either
};

class Aligner {
 public:
  /// Sizes every per-point buffer for the finest optimised level.
  Aligner(const OdometryConfig& config, const LevelCameras& cameras);

  /// Coarse-to-fine from T_cur_ref, every optimised level.
  Alignment align(const ReferenceSet& reference, const FrameSlot& current,
                  Eigen::Isometry3d T_cur_ref, const Prediction& p);

  /// The vision's own minimum near a joint one: the finest level again, without the priors.
  Alignment vision_only(const ReferenceSet& reference, const FrameSlot& current,
                        const Alignment& joint);

  /// The finest level's residuals at a's pose, into residuals() and masks() (for the
  /// moving-pixel marks).
  void finest_residuals(const ReferenceSet& reference, const FrameSlot& current,
                        const Alignment& a);
  /// Per reference point of the last residuals: the photometric residual, and 1 where it exists.
  [[nodiscard]] const std::vector<float>& residuals() const { return residual_; }
  [[nodiscard]] const std::vector<float>& masks() const { return mask_; }

 private:
  void solve_level(int level, const FrameSlot& current, const Prediction& p,
                   Eigen::Isometry3d& T_cur_ref, float& brightness_offset, double& variance,
                   Alignment& out);
  void solve_step(const NormalEquations& normal, const Eigen::Isometry3d& T_cur_ref,
                  const Prediction& p, Vector6d& delta, double& delta_offset) const;
  [[nodiscard]] double prior_cost(int level, const Eigen::Isometry3d& T_cur_ref,
                                  const Prediction& p, double variance, int valid) const;
  double weigh_and_accumulate(int level, int count, const Counts& counts, double& level_variance,
                              double& variance, NormalEquations& out);

  Counts compute_residuals(int level, const FrameSlot& current, const Eigen::Isometry3d& T_cur_ref,
                           float brightness_offset);
  Counts compute_intensity_residuals(int level, const FrameSlot& current,
                                     const Eigen::Isometry3d& T_cur_ref, float brightness_offset);
  double estimate_variance(int count, int valid, double initial_variance);
  double student_t_variance(int count, int valid, double initial_variance) const;
  void estimate_scale_matrix(int count);
  double accumulate(int level, int count, double variance, NormalEquations& out);
  double accumulate_with_depth(int level, int count, NormalEquations& out);

  const OdometryConfig& config_;
  const LevelCameras& cameras_;
  const ReferenceSet* reference_ = nullptr;  // of the alignment under way
  float min_cos_incidence_;

  // Per-point work buffers, sized for the finest optimised level. mask: 1 where the residual
  // exists; weight: its robust weight including the scale.
  std::vector<float> residual_;
  std::vector<float> mask_;
  std::vector<std::uint32_t> residual_histogram_;  // |r| counts for the median scale
  std::vector<float> weight_;
  std::vector<float> depth_residual_;
  std::vector<float> depth_mask_;
  std::vector<float> depth_weight_;
  std::vector<float> depth_offset_jacobian_;  // d (whitened depth row) / d brightness offset
  // d r_Z / d q per point, from compute_residuals; the depth rows' Jacobians are formed from
  // it inside their accumulation.
  std::array<std::vector<float>, 3> depth_jacobian_;
  std::vector<float> depth_whitening_;  // c_z of the whitened depth row
  Warp warp_{};                         // T_cur_ref of the last compute_residuals
  // Scale matrix of (intensity, depth) residuals (Kerl IROS 2013, eq. 13).
  double sigma_ii_ = 0.0, sigma_iz_ = 0.0, sigma_zz_ = 0.0;
};

}  // namespace hq::odometry::detail
