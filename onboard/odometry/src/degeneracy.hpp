#pragma once
// What the scene leaves unmeasured (private to hq_odometry): Gauss-Newton steps that keep the
// prediction along unobserved translation directions, and the test that loses a frame whose
// translation the scene does not constrain (a textureless wall seen with the depth term).

#include "hq/odometry/dense_odometry.hpp"

#include "normal_equations.hpp"

namespace hq::odometry::detail {

/// A7 x = b7, with no step along the translation directions whose information (rotation held)
/// is at most degenerate_step_ratio of the best one's (Zhang, Kaess and Singh, ICRA 2016,
/// "solution remapping"): in the basis of the translation block's eigenvectors their rows
/// become the identity's and their right-hand sides 0. 0 (or less): a plain solve.
Vector7d solve_remapped(const Matrix7d& A7, const Vector7d& b7, double degenerate_step_ratio);

/// min_translation_information_ratio: whether the weakest translation direction's
/// information is under that share of the best direction's the depth rows give (their
/// Jacobians' noise adds about that much to every direction). Never with the ratio at 0.
bool translation_information_too_weak(const NormalEquations& normal, double min_ratio);

/// Whether the translation's standard deviation along its least constrained direction exceeds
/// max_translation_sigma_m under the configured honest scale (not the learnt one, which also
/// carries the gyro's disagreement: this is about the scene's geometry and texture), or the
/// depth rows' noise floor says so (translation_information_too_weak).
bool translation_unconstrained(const NormalEquations& normal, const OdometryConfig& config);

}  // namespace hq::odometry::detail
