#include "hq/markers/marker_detector.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"

#include <opencv2/imgproc.hpp>
#include <visp3/core/vpCameraParameters.h>
#include <visp3/core/vpHomogeneousMatrix.h>
#include <visp3/core/vpImage.h>
#include <visp3/core/vpImagePoint.h>
#include <visp3/core/vpPoint.h>
#include <visp3/detection/vpDetectorAprilTag.h>
#include <visp3/vision/vpPose.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <string>

namespace hq::markers {
namespace {

using geometry::Matrix6d;

struct FamilyName {
  const char* name;
  vpDetectorAprilTag::vpAprilTagFamily family;
};

// Only the families ViSP 3.5 recommends; the deprecated ones detect poorly or not at all.
constexpr FamilyName kFamilies[] = {
    {"36h11", vpDetectorAprilTag::TAG_36h11},
    {"25h9", vpDetectorAprilTag::TAG_25h9},
    {"16h5", vpDetectorAprilTag::TAG_16h5},
    {"circle21h7", vpDetectorAprilTag::TAG_CIRCLE21h7},
    {"circle49h12", vpDetectorAprilTag::TAG_CIRCLE49h12},
    {"custom48h12", vpDetectorAprilTag::TAG_CUSTOM48h12},
    {"standard41h12", vpDetectorAprilTag::TAG_STANDARD41h12},
    {"standard52h13", vpDetectorAprilTag::TAG_STANDARD52h13},
};

vpDetectorAprilTag::vpAprilTagFamily family_of(const std::string& name) {
  for (const FamilyName& f : kFamilies) {
    if (name == f.name) return f.family;
  }
  throw InputError("marker family \"" + name + "\" unknown");
}

Eigen::Isometry3d to_eigen(const vpHomogeneousMatrix& m) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c)
      T.linear()(r, c) = m[static_cast<unsigned>(r)][static_cast<unsigned>(c)];
    T.translation()(r) = m[static_cast<unsigned>(r)][3];
  }
  return T;
}

// Copies a CV_8UC1 / CV_32FC1 matrix into a vpImage, reallocating only on a size change.
template <typename T>
void copy_into(const cv::Mat& src, vpImage<T>& dst) {
  const auto rows = static_cast<unsigned>(src.rows);
  const auto cols = static_cast<unsigned>(src.cols);
  if (dst.getHeight() != rows || dst.getWidth() != cols) dst.resize(rows, cols);
  for (unsigned r = 0; r < rows; ++r) {
    std::memcpy(dst[r], src.ptr<T>(static_cast<int>(r)), cols * sizeof(T));
  }
}

// Fraction of pixels inside the tag quadrilateral (sampled on a grid of bilinear
// interpolations between its corners) that carry finite, positive depth.
double valid_depth_ratio(const cv::Mat& depth_m, const std::array<Eigen::Vector2d, 4>& c) {
  constexpr int kSamples = 12;
  int valid = 0;
  int total = 0;
  for (int i = 0; i < kSamples; ++i) {
    for (int j = 0; j < kSamples; ++j) {
      const double a = (i + 0.5) / kSamples;
      const double b = (j + 0.5) / kSamples;
      const Eigen::Vector2d p =
          (1 - a) * (1 - b) * c[0] + a * (1 - b) * c[1] + a * b * c[2] + (1 - a) * b * c[3];
      const int u = static_cast<int>(std::lround(p.x()));
      const int v = static_cast<int>(std::lround(p.y()));
      ++total;
      if (u < 0 || v < 0 || u >= depth_m.cols || v >= depth_m.rows) continue;
      const float z = depth_m.at<float>(v, u);
      if (std::isfinite(z) && z > 0.0f) ++valid;
    }
  }
  return static_cast<double>(valid) / total;
}

constexpr int kPlaneGrid = 12;  // depth samples per side of the tag
constexpr int kMaxPlanePoints = kPlaneGrid * kPlaneGrid;

// Back-projects depth samples on a grid inside the tag quadrilateral (its outer tenth left out:
// depth at the tag border mixes in the surroundings). Returns the number written to p_C.
int tag_depth_points(const cv::Mat& depth_m, const geometry::PinholeCamera& camera,
                     const std::array<Eigen::Vector2d, 4>& c, Eigen::Vector3d* p_C) {
  int n = 0;
  for (int i = 0; i < kPlaneGrid; ++i) {
    for (int j = 0; j < kPlaneGrid; ++j) {
      const double a = 0.1 + 0.8 * (i + 0.5) / kPlaneGrid;
      const double b = 0.1 + 0.8 * (j + 0.5) / kPlaneGrid;
      const Eigen::Vector2d p =
          (1 - a) * (1 - b) * c[0] + a * (1 - b) * c[1] + a * b * c[2] + (1 - a) * b * c[3];
      const int u = static_cast<int>(std::lround(p.x()));
      const int v = static_cast<int>(std::lround(p.y()));
      if (u < 0 || v < 0 || u >= depth_m.cols || v >= depth_m.rows) continue;
      const double z = depth_m.at<float>(v, u);
      if (!std::isfinite(z) || z <= 0.0) continue;
      p_C[n++] = camera.unproject(static_cast<double>(u), static_cast<double>(v), z);
    }
  }
  return n;
}

}  // namespace

const std::vector<std::string>& tag_families() {
  static const std::vector<std::string> kNames = [] {
    std::vector<std::string> out;
    for (const FamilyName& f : kFamilies) out.emplace_back(f.name);
    return out;
  }();
  return kNames;
}

void read_config(config::StrictMap& section, MarkerDetectorConfig& out) {
  section.read("family", out.family, tag_families());
  section.read_positive("tag_size_m", out.tag_size_m, 10.0);
  section.read_positive("quad_decimate", out.quad_decimate, 8.0);
  section.read("threads", out.threads, 1, 64);
  section.read("refine_with_depth", out.refine_with_depth);
  section.read("min_valid_depth_ratio", out.min_valid_depth_ratio, 0.0, 1.0);
  section.read_positive("corner_sigma_floor_px", out.corner_sigma_floor_px, 100.0);
  section.read_positive("depth_sigma_per_m2", out.depth_sigma_per_m2, 1.0);
  section.skip("tag_size_overrides");
  section.finish();
}

MarkerDetectorConfig load_marker_detector_config(const std::string& path) {
  const YAML::Node root = config::load_yaml_file(path);
  config::StrictMap top(root, path);
  MarkerDetectorConfig out;
  config::StrictMap section = top.child("markers");
  read_config(section, out);
  top.finish();
  // The override list is read here, not through StrictMap, which has no list-of-maps getter.
  const YAML::Node list = root["markers"] ? root["markers"]["tag_size_overrides"] : YAML::Node();
  if (list && !list.IsNull()) {
    if (!list.IsSequence()) {
      throw InputError(path + ": markers.tag_size_overrides is not a list of {id, size_m}");
    }
    for (std::size_t i = 0; i < list.size(); ++i) {
      config::StrictMap item(list[i], path,
                             "markers.tag_size_overrides[" + std::to_string(i) + "]");
      int id = 0;
      double size_m = 0.0;
      item.require("id", id, 0, 100000);
      item.require("size_m", size_m, 1e-4, 10.0);
      item.finish();
      for (const auto& [known, unused] : out.tag_size_overrides_m) {
        if (known == id) {
          throw InputError(item.describe("id") + " = " + std::to_string(id) +
                           ", expected each id once");
        }
      }
      out.tag_size_overrides_m.emplace_back(id, size_m);
    }
  }
  return out;
}

std::array<Eigen::Vector3d, 4> tag_corners_marker_m(double tag_size_m) {
  const double h = 0.5 * tag_size_m;
  // ViSP's order (vpDetectorAprilTag::getTagsPoints3D), matching getPolygon().
  return {Eigen::Vector3d(-h, -h, 0), Eigen::Vector3d(h, -h, 0), Eigen::Vector3d(h, h, 0),
          Eigen::Vector3d(-h, h, 0)};
}

double corner_reprojection(const geometry::PinholeCamera& camera,
                           const Eigen::Isometry3d& T_camera_marker, double tag_size_m,
                           const std::array<Eigen::Vector2d, 4>& corners_px,
                           Eigen::Matrix<double, 8, 6>* d_residual_d_xi) {
  const std::array<Eigen::Vector3d, 4> p_M = tag_corners_marker_m(tag_size_m);
  const Eigen::Matrix3d& R_CM = T_camera_marker.linear();
  double sum_sq = 0.0;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector3d p_C = T_camera_marker * p_M[static_cast<std::size_t>(k)];
    Eigen::Matrix<double, 2, 3> d_uv_d_p_C;
    const Eigen::Vector2d uv =
        camera.project(p_C, d_residual_d_xi != nullptr ? &d_uv_d_p_C : nullptr);
    sum_sq += (uv - corners_px[static_cast<std::size_t>(k)]).squaredNorm();
    if (d_residual_d_xi != nullptr) {
      // p_C = R (p_M + v + omega x p_M) + t for T * exp(xi) to first order.
      Eigen::Matrix<double, 3, 6> d_p_C_d_xi;
      d_p_C_d_xi.leftCols<3>() = R_CM;
      d_p_C_d_xi.rightCols<3>() = -R_CM * geometry::hat(p_M[static_cast<std::size_t>(k)]);
      d_residual_d_xi->middleRows<2>(2 * k) = d_uv_d_p_C * d_p_C_d_xi;
    }
  }
  return std::sqrt(sum_sq / 4.0);
}

struct MarkerDetector::Impl {
  vpDetectorAprilTag detector;
  vpCameraParameters cam;
  vpImage<unsigned char> gray_vp;
  vpImage<float> depth_vp;
  cv::Mat gray;
  std::map<int, double> sizes;  // for getTagsPoints3D; filled per frame (ViSP's interface).
  std::array<Eigen::Vector3d, kMaxPlanePoints> plane_points_C;
  explicit Impl(vpDetectorAprilTag::vpAprilTagFamily family) : detector(family) {}
};

MarkerDetector::MarkerDetector(const MarkerDetectorConfig& config,
                               const geometry::PinholeCamera& camera)
    : config_(config), camera_(camera) {
  const bool finite = std::isfinite(camera.fx) && std::isfinite(camera.fy) &&
                      std::isfinite(camera.cx) && std::isfinite(camera.cy);
  if (!finite || camera.fx <= 0.0 || camera.fy <= 0.0 || camera.width <= 0 || camera.height <= 0) {
    throw InputError("MarkerDetector: camera intrinsics fx=" + std::to_string(camera.fx) +
                     " fy=" + std::to_string(camera.fy) + " size " + std::to_string(camera.width) +
                     "x" + std::to_string(camera.height) + ", expected positive and finite");
  }
  impl_ = std::make_unique<Impl>(family_of(config.family));
  impl_->detector.setAprilTagQuadDecimate(static_cast<float>(config.quad_decimate));
  impl_->detector.setAprilTagNbThreads(config.threads);
  impl_->detector.setAprilTagPoseEstimationMethod(vpDetectorAprilTag::HOMOGRAPHY_VIRTUAL_VS);
  impl_->cam.initPersProjWithoutDistortion(camera.fx, camera.fy, camera.cx, camera.cy);
  detections_.reserve(64);
}

MarkerDetector::~MarkerDetector() = default;

double MarkerDetector::tag_size_m(int id) const {
  for (const auto& [known, size_m] : config_.tag_size_overrides_m) {
    if (known == id) return size_m;
  }
  return config_.tag_size_m;
}

DetectionStatus MarkerDetector::detect(const cv::Mat& image, const cv::Mat& depth_m) {
  detections_.clear();
  if (image.empty()) return {false, "empty image"};
  if (image.type() != CV_8UC1 && image.type() != CV_8UC3) {
    return {false, "image type is not CV_8UC1 or CV_8UC3"};
  }
  if (image.cols != camera_.width || image.rows != camera_.height) {
    return {false, "image size differs from the camera's"};
  }
  const bool have_depth = !depth_m.empty();
  if (have_depth && depth_m.type() != CV_32FC1) return {false, "depth type is not CV_32FC1"};
  if (have_depth && depth_m.size() != image.size()) return {false, "depth size differs from image"};

  Impl& im = *impl_;
  if (image.type() == CV_8UC3) {
    cv::cvtColor(image, im.gray, cv::COLOR_BGR2GRAY);  // reuses im.gray once sized
    copy_into(im.gray, im.gray_vp);
  } else {
    copy_into(image, im.gray_vp);
  }
  im.detector.detect(im.gray_vp);
  const std::vector<int> ids = im.detector.getTagsId();
  const std::size_t n = im.detector.getNbObjects();
  const bool use_depth = have_depth && config_.refine_with_depth;
  if (use_depth) copy_into(depth_m, im.depth_vp);

  for (std::size_t i = 0; i < n; ++i) {
    MarkerDetection d;
    d.id = ids[i];
    d.tag_size_m = tag_size_m(d.id);
    const std::vector<vpImagePoint>& polygon = im.detector.getPolygon(i);
    if (polygon.size() != 4) continue;
    for (std::size_t k = 0; k < 4; ++k) {
      d.corners_px[k] = Eigen::Vector2d(polygon[k].get_u(), polygon[k].get_v());
    }
    vpHomogeneousMatrix visp_T_C_M;
    if (!im.detector.getPose(i, d.tag_size_m, im.cam, visp_T_C_M)) continue;
    d.T_camera_marker = to_eigen(visp_T_C_M);

    if (use_depth && valid_depth_ratio(depth_m, d.corners_px) >= config_.min_valid_depth_ratio) {
      // ViSP's plane-based pose (computePlanarObjectPoseFromRGBD) seeds the fusion: it ends
      // with a reprojection-only VVS, so on its own it returns the image pose again.
      im.sizes.clear();
      im.sizes[d.id] = d.tag_size_m;
      const std::vector<std::vector<vpPoint>> points =
          im.detector.getTagsPoints3D(std::vector<int>{d.id}, im.sizes);
      vpHomogeneousMatrix visp_T_C_M_depth;
      double confidence = 0.0;
      if (vpPose::computePlanarObjectPoseFromRGBD(im.depth_vp, polygon, im.cam, points[0],
                                                  visp_T_C_M_depth, &confidence)) {
        const Eigen::Isometry3d T = to_eigen(visp_T_C_M_depth);
        if (T.matrix().allFinite() && T.translation().z() > 0.0) d.T_camera_marker = T;
      }
      const int n_points =
          tag_depth_points(depth_m, camera_, d.corners_px, im.plane_points_C.data());
      if (n_points >= 12 && refine_with_plane(d, im.plane_points_C.data(), n_points)) {
        d.used_depth = true;
      }
    }
    if (!d.T_camera_marker.matrix().allFinite()) continue;

    Eigen::Matrix<double, 8, 6> J;
    d.reprojection_rms_px =
        corner_reprojection(camera_, d.T_camera_marker, d.tag_size_m, d.corners_px, &J);
    if (!d.used_depth) {
      // Covariance sigma^2 (J^T J)^-1 (Gauss-Newton at the optimum), sigma^2 from the corner
      // residuals over their 8 - 6 = 2 degrees of freedom, floored.
      const double sigma2_sample = 8.0 * d.reprojection_rms_px * d.reprojection_rms_px / 2.0;
      const double sigma2 =
          std::max(sigma2_sample, config_.corner_sigma_floor_px * config_.corner_sigma_floor_px);
      const Matrix6d Jt_J = J.transpose() * J;
      d.covariance = sigma2 * Jt_J.ldlt().solve(Matrix6d::Identity());
    }
    if (!d.covariance.allFinite()) continue;
    detections_.push_back(d);
  }
  return {};
}

}  // namespace hq::markers

namespace hq::markers {

bool MarkerDetector::refine_with_plane(MarkerDetection& d, const Eigen::Vector3d* p_C,
                                       int n_points) const {
  // Joint Gauss-Newton on xi (T = T_hat exp(xi)) over the corner reprojections (sigma =
  // corner_sigma_floor_px) and the depth points' distances to the tag plane z_M = 0 (sigma_z =
  // k z^2, Khoshelham and Oude Elberink 2012): depth fixes distance and tilt, which four
  // corners of a small tag constrain weakly; the corners fix the in-plane pose.
  const double sigma_px = config_.corner_sigma_floor_px;
  Eigen::Isometry3d T = d.T_camera_marker;
  Matrix6d H = Matrix6d::Zero();
  double chi2 = 0.0;
  int used = 0;
  for (int iteration = 0; iteration < 6; ++iteration) {
    Eigen::Matrix<double, 8, 6> J_corners;
    corner_reprojection(camera_, T, d.tag_size_m, d.corners_px, &J_corners);
    const std::array<Eigen::Vector3d, 4> p_M = tag_corners_marker_m(d.tag_size_m);
    H.setZero();
    geometry::Vector6d g = geometry::Vector6d::Zero();
    chi2 = 0.0;
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector3d q = T * p_M[static_cast<std::size_t>(k)];
      const Eigen::Vector2d r =
          (camera_.project(q) - d.corners_px[static_cast<std::size_t>(k)]) / sigma_px;
      const Eigen::Matrix<double, 2, 6> Jk = J_corners.middleRows<2>(2 * k) / sigma_px;
      H += Jk.transpose() * Jk;
      g += Jk.transpose() * r;
      chi2 += r.squaredNorm();
    }
    const Eigen::Isometry3d T_inv = T.inverse();
    used = 0;
    for (int i = 0; i < n_points; ++i) {
      const Eigen::Vector3d q = T_inv * p_C[i];  // point in M; on the tag, q.z() = 0
      const double z = p_C[i].z();
      const double sigma_z = std::max(config_.depth_sigma_per_m2 * z * z, 1e-4);
      // Gross outliers (depth of the floor through a border pixel) are dropped.
      if (std::abs(q.z()) > 3.0 * sigma_z + 0.01) continue;
      const double r = q.z() / sigma_z;
      // q(xi) = exp(-xi) T^-1 p = q - v - omega x q: d q_z / d(v, omega) = (-e_z, (-q_y, q_x, 0)).
      Eigen::Matrix<double, 1, 6> Jp;
      Jp << 0.0, 0.0, -1.0, -q.y(), q.x(), 0.0;
      Jp /= sigma_z;
      H += Jp.transpose() * Jp;
      g += Jp.transpose() * r;
      chi2 += r * r;
      ++used;
    }
    if (used < 12) return false;
    const geometry::Vector6d step = -H.ldlt().solve(g);
    if (!step.allFinite()) return false;
    T = T * geometry::exp_se3(step);
    if (step.norm() < 1e-9) break;
  }
  if (!T.matrix().allFinite() || T.translation().z() <= 0.0) return false;
  d.T_camera_marker = T;
  // Covariance H^-1, inflated when the residuals exceed their model (chi2 per dof > 1).
  const double dof = std::max(1, 8 + used - 6);
  d.covariance = std::max(1.0, chi2 / dof) * H.ldlt().solve(Matrix6d::Identity());
  return true;
}

}  // namespace hq::markers
