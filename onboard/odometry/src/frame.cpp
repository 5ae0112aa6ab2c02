#include "frame.hpp"

#include "pyramid.hpp"
#include <Eigen/Geometry>

#include <utility>

namespace hq::odometry::detail {

namespace {

// A depth turn under this moves no pixel by a thousandth of one at 640x480: skipped.
constexpr double kMinDepthTurnRad = 2e-6;

}  // namespace

LevelCameras::LevelCameras(const geometry::PinholeCamera& camera, int levels, int finest)
    : levels_(levels), finest_(finest) {
  for (int l = 0; l < levels; ++l) at_level(cameras_, l) = camera.at_level(l);
}

FrameBuilder::FrameBuilder(const OdometryConfig& config, const LevelCameras& cameras)
    : config_(config), cameras_(cameras) {
  const geometry::PinholeCamera& finest = cameras_.at(cameras_.finest());
  turned_depth_.create(finest.height, finest.width, CV_32FC1);
  turned_depth_ = 0.0f;
}

void FrameBuilder::allocate(FrameSlot& slot) const {
  for (int l = 0; l < cameras_.levels(); ++l) {
    const geometry::PinholeCamera& cam = cameras_.at(l);
    // Each image is written once here: its pages are then mapped before the first frame,
    // not faulted in one by one during the first frames' tracking.
    at_level(slot.intensity, l).create(cam.height, cam.width, CV_32FC1);
    at_level(slot.intensity, l) = 0.0f;
    at_level(slot.depth_m, l).create(cam.height, cam.width, CV_32FC1);
    at_level(slot.depth_m, l) = 0.0f;
  }
}

bool FrameBuilder::should_align_depth(const RotationPrior* prior) const {
  if (prior == nullptr || !config_.align_depth_to_colour) return false;
  const Eigen::Matrix3d& R = prior->R_depth_colour;
  if (!R.allFinite() || !(R * R.transpose()).isIdentity(1e-6) || R.determinant() < 0.0) {
    return false;
  }
  const double angle = Eigen::AngleAxisd(R).angle();
  return angle > kMinDepthTurnRad;
}

void FrameBuilder::build(FrameSlot& slot, const cv::Mat& gray, const cv::Mat& depth_m,
                         bool depth_to_be_turned) const {
  const auto min_depth = static_cast<float>(config_.min_depth_m);
  const auto max_depth = static_cast<float>(config_.max_depth_m);
  const int levels = cameras_.levels();
  const int finest = cameras_.finest();
  sanitize_depth(depth_m, at_level(slot.depth_m, 0), min_depth, max_depth);
  if (finest == 0) gray.convertTo(at_level(slot.intensity, 0), CV_32F);
  const int depth_levels_built = depth_to_be_turned ? finest + 1 : levels;
  for (int l = 1; l < levels; ++l) {
    // Level 1 straight from the 8-bit input: one pass instead of convert-then-average.
    const cv::Mat& src = (l == 1) ? gray : at_level(slot.intensity, l - 1);
    downsample_intensity(src, at_level(slot.intensity, l));
    if (l < depth_levels_built) {
      downsample_depth(at_level(slot.depth_m, l - 1), at_level(slot.depth_m, l),
                       kDepthEdgeSpreadRatio);
    }
  }
}

void FrameBuilder::align_depth(FrameSlot& slot, const Eigen::Matrix3d& R_depth_colour) {
  const int finest = cameras_.finest();
  const Intrinsics k = cameras_.intrinsics(finest);
  rotate_depth(at_level(slot.depth_m, finest), turned_depth_, k.fx, k.fy, k.cx, k.cy,
               R_depth_colour.cast<float>(), kDepthEdgeSpreadRatio);
  std::swap(turned_depth_, at_level(slot.depth_m, finest));  // headers only: both stay allocated
  for (int l = finest + 1; l < cameras_.levels(); ++l) {
    downsample_depth(at_level(slot.depth_m, l - 1), at_level(slot.depth_m, l),
                     kDepthEdgeSpreadRatio);
  }
}

}  // namespace hq::odometry::detail
