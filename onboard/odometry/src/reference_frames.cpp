#include "reference_frames.hpp"

#include "hq/geometry/lie.hpp"

#include "kernels.hpp"
#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

namespace hq::odometry::detail {

double entropy_of(const Matrix6d& information) {
  // Differential entropy of a Gaussian up to a constant: -0.5 ln det(information).
  const Eigen::LLT<Matrix6d> llt(information);
  if (llt.info() != Eigen::Success) return 0.0;
  const auto& L = llt.matrixL();
  double log_det = 0.0;
  for (int i = 0; i < 6; ++i) log_det += 2.0 * std::log(L(i, i));
  return -0.5 * log_det;
}

bool KeyframeSelection::reference_ends_with(const Matrix6d& H, int valid) const {
  if (config_.reference_mode == ReferenceMode::kFrameToFrame) return true;
  const int age = age_ + 1;
  const double entropy = entropy_of(H);
  const double first = age == 1 ? entropy : first_entropy_;
  const double ratio = first != 0.0 ? entropy / first : 0.0;
  return age >= config_.max_keyframe_age || (age > 1 && ratio < config_.keyframe_entropy_ratio) ||
         static_cast<double>(valid) / finest_pixels_ < config_.keyframe_min_valid_ratio;
}

void KeyframeSelection::count_alignment(const Matrix6d& H) {
  if (config_.reference_mode != ReferenceMode::kFrameToKeyframe) return;
  ++age_;
  if (age_ == 1) first_entropy_ = entropy_of(H);
}

void KeyframeSelection::restart() {
  age_ = 0;
  first_entropy_ = 0.0;
}

bool keyframe_chain_broke(const OdometryConfig& config, int finest_pixels, const Alignment& a,
                          const Alignment& to_previous, const Eigen::Isometry3d& T_ref_prev) {
  const bool keyframe_ok = a.T_cur_ref.matrix().allFinite() && a.valid >= 6 &&
                           static_cast<double>(a.valid) / finest_pixels >= config.min_valid_ratio;
  const Eigen::Isometry3d chain = T_ref_prev.inverse() * a.T_cur_ref.inverse();
  const Eigen::Isometry3d difference = to_previous.T_cur_ref * chain;
  return !keyframe_ok ||
         difference.translation().norm() > config.keyframe_check_max_translation_m ||
         geometry::log_so3(difference.linear()).norm() >
             config.keyframe_check_max_rotation_deg * M_PI / 180.0;
}

MovingPixels::MovingPixels(const OdometryConfig& config, const LevelCameras& cameras)
    : config_(config), cameras_(cameras) {
  for (int l = cameras_.finest(); l < cameras_.levels(); ++l) {
    const geometry::PinholeCamera& cam = cameras_.at(l);
    at_level(marks_, l).create(cam.height, cam.width, CV_8UC1);
    at_level(marks_, l) = 0;
  }
}

void MovingPixels::mark(Aligner& aligner, const ReferenceSet& reference, const FrameSlot& current,
                        const Alignment& a) {
  known_ = false;
  if (config_.moving_residual_sigmas <= 0.0) return;
  aligner.finest_residuals(reference, current, a);
  int used = 0;
  const int marked = mark_finest(at_level(reference, cameras_.finest()), aligner, a, used);
  if (used == 0 || marked > config_.max_moving_ratio * used) return;
  spread_to_coarser_levels();
  known_ = true;
}

// The finest level's marks; returns how many points were marked, `used` how many landed
// inside the image.
int MovingPixels::mark_finest(const ReferenceLevel& ref, const Aligner& aligner, const Alignment& a,
                              int& used) {
  const int finest = cameras_.finest();
  const Intrinsics k = cameras_.intrinsics(finest);
  const Eigen::Matrix3f R = a.T_cur_ref.linear().cast<float>();
  const Eigen::Vector3f t = a.T_cur_ref.translation().cast<float>();
  const Warp T{R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2),
               R(2, 0), R(2, 1), R(2, 2), t.x(),   t.y(),   t.z()};
  const geometry::PinholeCamera& cam = cameras_.at(finest);
  const auto limit = static_cast<float>(config_.moving_residual_sigmas * std::sqrt(a.variance));
  const std::vector<float>& residual = aligner.residuals();
  const std::vector<float>& mask = aligner.masks();
  cv::Mat& marks = at_level(marks_, finest);
  marks = 0;
  int marked = 0;
  used = 0;
  for (std::size_t i = 0; i < static_cast<std::size_t>(ref.count); ++i) {
    if (ref.photometric[i] <= 0.0f) continue;
    float qx, qy, qz;
    T.apply(ref.x[i], ref.y[i], ref.z[i], qx, qy, qz);
    if (qz <= 0.0f) continue;
    const auto u = static_cast<int>(std::lround(k.fx * qx / qz + k.cx));
    const auto v = static_cast<int>(std::lround(k.fy * qy / qz + k.cy));
    if (u < 1 || v < 1 || u >= cam.width - 1 || v >= cam.height - 1) continue;
    ++used;
    // mask 0 inside the image: the depth disagreed (or the sample fell off the last column)
    const bool moved =
        mask[i] > 0.0f ? std::abs(residual[i]) > limit : config_.occlusion_depth_ratio > 0.0;
    if (!moved) continue;
    ++marked;
    marks.at<std::uint8_t>(v, u) = 1;
    marks.at<std::uint8_t>(v - 1, u) = 1;
    marks.at<std::uint8_t>(v + 1, u) = 1;
    marks.at<std::uint8_t>(v, u - 1) = 1;
    marks.at<std::uint8_t>(v, u + 1) = 1;
  }
  return marked;
}

void MovingPixels::spread_to_coarser_levels() {
  for (int l = cameras_.finest() + 1; l < cameras_.levels(); ++l) {
    const cv::Mat& fine = at_level(marks_, l - 1);
    cv::Mat& coarse = at_level(marks_, l);
    for (int v = 0; v < coarse.rows; ++v) {
      for (int u = 0; u < coarse.cols; ++u) {
        const int fu = std::min(2 * u, fine.cols - 2);
        const int fv = std::min(2 * v, fine.rows - 2);
        coarse.at<std::uint8_t>(v, u) =
            fine.at<std::uint8_t>(fv, fu) | fine.at<std::uint8_t>(fv, fu + 1) |
            fine.at<std::uint8_t>(fv + 1, fu) | fine.at<std::uint8_t>(fv + 1, fu + 1);
      }
    }
  }
}

}  // namespace hq::odometry::detail
