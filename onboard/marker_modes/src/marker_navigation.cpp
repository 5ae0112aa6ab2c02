#include "hq/marker_modes/marker_navigation.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/estimator/velocity_estimator.hpp"
#include "hq/geometry/camera_mount.hpp"
#include "hq/geometry/lie.hpp"

#include <cmath>
#include <cstdio>

namespace hq::marker_modes {
namespace {

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d s;
  s << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return s;
}

void read_marker_mode(config::StrictMap& s, MarkerModeConfig& out) {
  s.read("target_id", out.target_id, 0, 1 << 20);
  s.read_positive("hold_height_m", out.hold_height_m, 5.0);
  s.read_positive("kp_position_per_s", out.kp_position_per_s, 10.0);
  s.read_positive("max_speed_mps", out.max_speed_mps, 2.0);
  s.read_positive("kp_yaw_per_s", out.kp_yaw_per_s, 10.0);
  s.read_positive("max_yaw_rate_radps", out.max_yaw_rate_radps, 3.0);
  s.read_positive("search_yaw_rate_radps", out.search_yaw_rate_radps, 3.0);
  s.read_positive("face_target_beyond_m", out.face_target_beyond_m, 100.0);
  s.read_positive("land_align_m", out.land_align_m, 1.0);
  s.read_positive("land_descent_mps", out.land_descent_mps, 1.0);
  s.read_positive("land_handover_height_m", out.land_handover_height_m, 2.0);
  // One limit on a marker's age: the filter's. This mode's own (10 s) never acted, the filter
  // declared the pose invalid at its 5 s first, so a file setting it meant nothing it said.
  if (s.has("max_marker_age_s")) {
    throw InputError(s.describe("max_marker_age_s") +
                     ": removed; the one limit on a marker's age is the marker filter's "
                     "markers.navigation.position_max_age_s (default 5.0 s): set that instead");
  }
  s.finish();
}

void read_explore(config::StrictMap& s, ExploreConfig& out) {
  s.read_positive("height_m", out.height_m, 5.0);
  s.read_positive("liftoff_climb_mps", out.liftoff_climb_mps, 2.0);
  s.read_positive("liftoff_max_s", out.liftoff_max_s, 60.0);
  s.read_positive("search_yaw_rate_radps", out.search_yaw_rate_radps, 2.0);
  s.read_positive("cell_m", out.cell_m, 5.0);
  s.read_positive("view_distance_m", out.view_distance_m, 10.0);
  s.read_positive("max_view_range_m", out.max_view_range_m, 10.0);
  s.read_positive("budget_s", out.budget_s, 3600.0);
  s.read_positive("goal_timeout_s", out.goal_timeout_s, 600.0);
  s.read_positive("edge_timeout_s", out.edge_timeout_s, 10.0);
  s.read("edge_margin_m", out.edge_margin_m, 0.0, 5.0);
  s.read_positive("counter_steer_mps", out.counter_steer_mps, 2.0);
  s.read("land_at_end", out.land_at_end);
  s.finish();
}

}  // namespace

void read_config(config::StrictMap& section, MarkerModesConfig& out) {
  section.read("enabled", out.enabled);
  section.read("detect_every_frames", out.detect_every_frames, 1, 100);
  section.read_positive("map_position_sigma_m", out.map_position_sigma_m, 1.0);
  section.read_deg_as_rad("map_rotation_sigma_deg", out.map_rotation_sigma_rad, 0.0, 45.0);
  config::StrictMap detector = section.child("detector");
  markers::read_config(detector, out.detector);
  config::StrictMap navigation = section.child("navigation");
  navigation::read_config(navigation, out.navigation);
  config::StrictMap marker_mode = section.child("marker_mode");
  read_marker_mode(marker_mode, out.marker_mode);
  config::StrictMap explore = section.child("explore");
  read_explore(explore, out.explore);
  section.finish();
}

const Eigen::Matrix3d& R_W_map() {
  static const Eigen::Matrix3d kR = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  return kR;
}

namespace {
Eigen::Isometry3d body_camera(const Eigen::Matrix3d& R, const Eigen::Vector3d& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = p;
  return T;
}
}  // namespace

MarkerNavigation::MarkerNavigation(const MarkerModesConfig& config,
                                   const geometry::PinholeCamera& camera,
                                   const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m)
    : config_(config),
      camera_(camera),
      T_B_C_(body_camera(R_B_C, p_B_C_m)),
      camera_heading_rad_(geometry::camera_heading_rad(R_B_C)),
      detector_(config.detector, camera),
      map_(config.map),
      filter_(config.navigation, T_B_C_) {}

void MarkerNavigation::on_imu(std::int64_t t_ns, const Eigen::Vector3d& gyro_radps,
                              const Eigen::Vector3d& accel_mps2) {
  if (!gyro_radps.allFinite() || !accel_mps2.allFinite()) return;
  if (!filter_.health().initialized) {
    // At rest the specific force is -R_WB^T g_W: roll and pitch from its direction (NED).
    navigation::NominalState start;
    const double roll = std::atan2(-accel_mps2.y(), -accel_mps2.z());
    const double pitch = std::atan2(accel_mps2.x(), std::hypot(accel_mps2.y(), accel_mps2.z()));
    start.q_W_B = Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX());
    filter_.initialize(t_ns, start);
  }
  filter_.predict(t_ns, gyro_radps, accel_mps2);
}

void MarkerNavigation::on_frame(std::int64_t t_ns, const cv::Mat& gray, const cv::Mat& depth_m,
                                const estimator::VelocityEstimate& estimate, bool odometry_ok,
                                const Eigen::Isometry3d& T_O_C) {
  if (!filter_.health().initialized) return;
  if (estimate.ok()) filter_.update_velocity(estimate);
  detections_last_frame_ = 0;
  const bool detect = !hidden_ && (frames_++ % config_.detect_every_frames) == 0;
  if (!detect) return;
  if (!detector_.detect(gray, depth_m).ok) return;
  const std::vector<markers::MarkerDetection>& detections = detector_.detections();
  detections_last_frame_ = static_cast<int>(detections.size());
  // Motion covariance of the odometry since the last frame (per-frame drift of dense RGB-D
  // odometry, a few mm); without tracking the map must not trust the odometry link.
  const double motion_sigma_m = odometry_ok ? 0.005 : 1.0;
  geometry::Matrix6d motion_covariance = geometry::Matrix6d::Identity();
  motion_covariance.topLeftCorner<3, 3>() *= motion_sigma_m * motion_sigma_m;
  motion_covariance.bottomRightCorner<3, 3>() *= (motion_sigma_m * motion_sigma_m);
  if (detections.empty()) return;
  have_detection_ = true;
  t_last_detection_ns_ = t_ns;
  map_.add_frame(t_ns, detections, T_O_C, motion_covariance);
  // The providers run per control step and must not allocate: the box is kept here.
  have_box_ = false;
  for (int id : map_.ids()) {
    const Eigen::Vector2d p = (R_W_map() * map_.T_map_marker(id)->translation()).head<2>();
    map_lo_m_ = have_box_ ? Eigen::Vector2d(map_lo_m_.cwiseMin(p)) : p;
    map_hi_m_ = have_box_ ? Eigen::Vector2d(map_hi_m_.cwiseMax(p)) : p;
    have_box_ = true;
  }

  for (const markers::MarkerDetection& d : detections) {
    const std::optional<Eigen::Isometry3d> T_map_marker = map_.T_map_marker(d.id);
    if (!T_map_marker) continue;
    const Eigen::Isometry3d T_marker_camera = d.T_camera_marker.inverse();
    Eigen::Isometry3d T_W_C = Eigen::Isometry3d::Identity();
    T_W_C.linear() = R_W_map() * T_map_marker->linear() * T_marker_camera.linear();
    T_W_C.translation() = R_W_map() * (*T_map_marker * T_marker_camera.translation());
    // Detection noise xi (right perturbation of T_CM, in M) mapped to the camera pose:
    // T_MC' = exp(-xi) T_MC, so dp_M = -v + [p_MC]x omega and theta_C = -R_MC^T omega.
    Eigen::Matrix<double, 6, 6> J = Eigen::Matrix<double, 6, 6>::Zero();
    const Eigen::Matrix3d R_W_M = R_W_map() * T_map_marker->linear();
    J.block<3, 3>(0, 0) = -R_W_M;
    J.block<3, 3>(0, 3) = R_W_M * skew(T_marker_camera.translation());
    J.block<3, 3>(3, 3) = -T_marker_camera.linear().transpose();
    navigation::Matrix6d covariance = J * d.covariance * J.transpose();
    const double sp = config_.map_position_sigma_m;
    const double sr = config_.map_rotation_sigma_rad;
    covariance.topLeftCorner<3, 3>() += sp * sp * Eigen::Matrix3d::Identity();
    covariance.bottomRightCorner<3, 3>() += sr * sr * Eigen::Matrix3d::Identity();
    filter_.update_marker(t_ns, T_W_C, covariance);
  }
}

bool MarkerNavigation::pose_usable(std::int64_t t_ns) const {
  return filter_.check_position(t_ns).valid;
}

const char* describe_position(const navigation::PositionCheck& check,
                              const navigation::NavigationConfig& config, char* out,
                              std::size_t size) {
  using navigation::PositionInvalid;
  switch (check.reason) {
    case PositionInvalid::kNone:
      hq::format_into(out, size, "position valid");
      break;
    case PositionInvalid::kNotAnchored:
      hq::format_into(out, size, "no position (no marker seen yet)");
      break;
    case PositionInvalid::kNoMarker:
      hq::format_into(out, size, "position lost (no marker for {:.1f} s)", check.age_s);
      break;
    case PositionInvalid::kCovarianceOverBound:
      hq::format_into(out, size, "position lost (uncertainty {:.2f} m, over {:.2f} m)",
                      check.sigma_horizontal_m, config.position_max_sigma_m);
      break;
    case PositionInvalid::kInnovationInconsistent:
      hq::format_into(out, size,
                      "position lost (markers or velocity disagree with the estimate: {} frames or "
                      "{} velocities in a row gated)",
                      config.position_inconsistent_after_frames,
                      config.position_inconsistent_after_velocities);
      break;
  }
  return out;
}

double MarkerNavigation::yaw_rad() const {
  return navigation::yaw_rad(filter_.state().q_W_B.toRotationMatrix());
}

std::optional<Eigen::Vector3d> MarkerNavigation::p_W_M_m(int id) const {
  const std::optional<Eigen::Isometry3d> T = map_.T_map_marker(id);
  if (!T) return std::nullopt;
  return Eigen::Vector3d(R_W_map() * T->translation());
}

double MarkerNavigation::time_since_detection_s(std::int64_t t_ns) const {
  if (!have_detection_) return 1e9;
  return 1e-9 * static_cast<double>(t_ns - t_last_detection_ns_);
}

bool MarkerNavigation::in_view(const Eigen::Vector3d& p_W_m, double range_m) const {
  const Eigen::Isometry3d T_W_C = filter_.T_W_B() * T_B_C_;
  const Eigen::Vector3d p_C = T_W_C.inverse() * p_W_m;
  if (!(p_C.z() > 0.1) || p_C.norm() > range_m) return false;
  const Eigen::Vector2d uv = camera_.project(p_C);
  const double u = uv.x();
  const double v = uv.y();
  const double margin_u = 0.1 * camera_.width;
  const double margin_v = 0.1 * camera_.height;
  return u > margin_u && u < camera_.width - margin_u && v > margin_v &&
         v < camera_.height - margin_v;
}

}  // namespace hq::marker_modes
