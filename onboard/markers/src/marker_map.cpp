#include "hq/markers/marker_map.hpp"

#include "hq/base/error.hpp"
#include "hq/config/strict_yaml.hpp"

#include <ceres/ceres.h>
#include <ceres/manifold.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <deque>
#include <fstream>
#include <limits>
#include <unordered_map>

namespace hq::markers {
namespace {

using geometry::Matrix6d;

/// A pose node: quaternion (Eigen's x, y, z, w storage) and translation, the parameter blocks.
struct Node {
  double q[4] = {0, 0, 0, 1};
  double p[3] = {0, 0, 0};
  [[nodiscard]] Eigen::Isometry3d pose() const {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(p[0], p[1], p[2]);
    return T;
  }
  void set(const Eigen::Isometry3d& T) {
    const Eigen::Quaterniond r(T.linear());
    q[0] = r.x();
    q[1] = r.y();
    q[2] = r.z();
    q[3] = r.w();
    p[0] = T.translation().x();
    p[1] = T.translation().y();
    p[2] = T.translation().z();
  }
};

/// Measured T_a_b with covariance of the right perturbation xi = (v, omega): T_a_b = Z exp(xi).
struct Edge {
  Node* a = nullptr;
  Node* b = nullptr;
  Eigen::Isometry3d T_a_b = Eigen::Isometry3d::Identity();
  Matrix6d sqrt_information = Matrix6d::Identity();
};

/// Residual of one edge: the error E = Z^-1 T_a^-1 T_b written as (R_Z^T (p_ab - p_Z), 2 vec(q_E)),
/// which is xi of E = exp(xi) to first order, whitened by the square root information.
struct RelativePoseResidual {
  Eigen::Quaterniond q_meas;
  Eigen::Vector3d p_meas;
  Matrix6d sqrt_information;

  template <typename T>
  bool operator()(const T* q_a_ptr, const T* p_a_ptr, const T* q_b_ptr, const T* p_b_ptr,
                  T* residual_ptr) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_a(q_a_ptr);
    const Eigen::Map<const Eigen::Quaternion<T>> q_b(q_b_ptr);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(p_a_ptr);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_b(p_b_ptr);
    const Eigen::Quaternion<T> q_a_inv = q_a.conjugate();
    const Eigen::Quaternion<T> q_ab = q_a_inv * q_b;
    const Eigen::Matrix<T, 3, 1> p_ab = q_a_inv * (p_b - p_a);
    const Eigen::Quaternion<T> q_meas_inv = q_meas.conjugate().template cast<T>();
    Eigen::Quaternion<T> q_err = q_meas_inv * q_ab;
    // q and -q are one rotation: take the short way so the residual stays small.
    const T sign = q_err.w() < T(0) ? T(-1) : T(1);
    Eigen::Matrix<T, 6, 1> r;
    r.template head<3>() = q_meas_inv * (p_ab - p_meas.template cast<T>());
    r.template tail<3>() = T(2) * sign * q_err.vec();
    Eigen::Map<Eigen::Matrix<T, 6, 1>> residual(residual_ptr);
    residual = sqrt_information.template cast<T>() * r;
    return true;
  }
};

Matrix6d sqrt_information_of(const Matrix6d& covariance) {
  const Matrix6d symmetric = 0.5 * (covariance + covariance.transpose());
  const Matrix6d information = symmetric.ldlt().solve(Matrix6d::Identity());
  // information = L L^T, so |L^T r|^2 = r^T information r.
  const Eigen::LLT<Matrix6d> llt(0.5 * (information + information.transpose()));
  return llt.matrixL().transpose();
}

bool finite_pose(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

}  // namespace

struct MarkerMap::Impl {
  MarkerMapConfig config;
  std::deque<Node> markers;  // deque: stable addresses for Ceres parameter blocks
  std::vector<int> marker_ids;
  std::unordered_map<int, std::size_t> marker_index;
  std::deque<Node> cameras;
  std::vector<Edge> edges;
  int keyframes_since_optimisation = 0;

  // Odometry since the last keyframe.
  bool have_odometry = false;
  Eigen::Isometry3d T_O_C_prev = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_kf_camera = Eigen::Isometry3d::Identity();  // accumulated motion
  Matrix6d kf_motion_covariance = Matrix6d::Zero();

  Node* marker(int id) {
    const auto it = marker_index.find(id);
    return it == marker_index.end() ? nullptr : &markers[it->second];
  }
  Node& add_marker(int id, const Eigen::Isometry3d& T_map_marker) {
    marker_index[id] = markers.size();
    marker_ids.push_back(id);
    markers.emplace_back();
    markers.back().set(T_map_marker);
    return markers.back();
  }

  MapOptimisation solve(int max_iterations) {
    MapOptimisation out;
    if (edges.empty() || markers.empty()) return out;
    ceres::Problem::Options problem_options;
    problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    ceres::EigenQuaternionManifold quaternion_manifold;
    ceres::HuberLoss loss(config.huber_sigma);
    for (const Edge& e : edges) {
      auto* cost = new ceres::AutoDiffCostFunction<RelativePoseResidual, 6, 4, 3, 4, 3>(
          new RelativePoseResidual{Eigen::Quaterniond(e.T_a_b.linear()), e.T_a_b.translation(),
                                   e.sqrt_information});
      problem.AddResidualBlock(cost, &loss, e.a->q, e.a->p, e.b->q, e.b->p);
    }
    for (Node& n : markers) {
      if (problem.HasParameterBlock(n.q)) problem.SetManifold(n.q, &quaternion_manifold);
    }
    for (Node& n : cameras) {
      if (problem.HasParameterBlock(n.q)) problem.SetManifold(n.q, &quaternion_manifold);
    }
    // Gauge: the first marker is the map frame.
    if (problem.HasParameterBlock(markers.front().q)) {
      problem.SetParameterBlockConstant(markers.front().q);
      problem.SetParameterBlockConstant(markers.front().p);
    }
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    options.max_num_iterations = max_iterations;
    options.num_threads = 1;
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    out.iterations = static_cast<int>(summary.iterations.size()) - 1;
    out.initial_cost = summary.initial_cost;
    out.final_cost = summary.final_cost;
    out.converged = summary.termination_type == ceres::CONVERGENCE;
    return out;
  }
};

MarkerMap::MarkerMap(const MarkerMapConfig& config) : impl_(std::make_unique<Impl>()) {
  impl_->config = config;
}
MarkerMap::~MarkerMap() = default;
MarkerMap::MarkerMap(MarkerMap&&) noexcept = default;
MarkerMap& MarkerMap::operator=(MarkerMap&&) noexcept = default;

void MarkerMap::add_frame(std::int64_t t_ns, const std::vector<MarkerDetection>& detections,
                          const Eigen::Isometry3d& T_O_C, const Matrix6d& motion_covariance) {
  Impl& m = *impl_;
  if (!finite_pose(T_O_C) || !motion_covariance.allFinite()) {
    throw InputError("MarkerMap::add_frame(t_ns=" + std::to_string(t_ns) +
                     "): T_O_C or its covariance is not finite");
  }
  for (const MarkerDetection& d : detections) {
    if (!finite_pose(d.T_camera_marker) || !d.covariance.allFinite()) {
      throw InputError("MarkerMap::add_frame(t_ns=" + std::to_string(t_ns) + "): detection of id " +
                       std::to_string(d.id) + " has a non-finite pose or covariance");
    }
  }

  // Accumulate odometry since the last keyframe: T = T_hat exp(xi) composed with an increment
  // gives Sigma' = Ad(T_inc^-1) Sigma Ad(T_inc^-1)^T + Sigma_inc.
  if (m.have_odometry) {
    const Eigen::Isometry3d T_inc = m.T_O_C_prev.inverse() * T_O_C;
    const Matrix6d Ad = geometry::adjoint(T_inc.inverse());
    m.kf_motion_covariance = Ad * m.kf_motion_covariance * Ad.transpose() + motion_covariance;
    m.T_kf_camera = m.T_kf_camera * T_inc;
  }
  m.T_O_C_prev = T_O_C;
  m.have_odometry = true;
  if (detections.empty()) return;

  // Keyframe: the first, any frame with an unmapped marker, or after enough motion.
  bool new_marker = false;
  for (const MarkerDetection& d : detections) new_marker = new_marker || m.marker(d.id) == nullptr;
  const bool first = m.cameras.empty();
  if (!first && !new_marker) {
    const double moved_m = m.T_kf_camera.translation().norm();
    const double turned_rad = Eigen::AngleAxisd(m.T_kf_camera.linear()).angle();
    if (moved_m < m.config.keyframe_min_translation_m &&
        turned_rad < m.config.keyframe_min_rotation_rad) {
      return;
    }
  }

  Matrix6d floor = Matrix6d::Zero();
  floor.diagonal().head<3>().setConstant(m.config.detection_sigma_floor_m *
                                         m.config.detection_sigma_floor_m);
  floor.diagonal().tail<3>().setConstant(m.config.detection_sigma_floor_rad *
                                         m.config.detection_sigma_floor_rad);

  // Chained initial camera pose: through the best-known marker in view, else odometry.
  const MarkerDetection* anchor = nullptr;
  for (const MarkerDetection& d : detections) {
    if (m.marker(d.id) != nullptr &&
        (anchor == nullptr || d.covariance.trace() < anchor->covariance.trace())) {
      anchor = &d;
    }
  }
  Eigen::Isometry3d T_map_camera;
  if (anchor != nullptr) {
    T_map_camera = m.marker(anchor->id)->pose() * anchor->T_camera_marker.inverse();
  } else if (!m.cameras.empty()) {
    T_map_camera = m.cameras.back().pose() * m.T_kf_camera;
  } else {
    // The first marker ever seen is the map frame.
    T_map_camera = detections.front().T_camera_marker.inverse();
  }
  Node* previous = m.cameras.empty() ? nullptr : &m.cameras.back();
  m.cameras.emplace_back();
  Node& camera = m.cameras.back();
  camera.set(T_map_camera);
  if (previous != nullptr) {
    Matrix6d cov = m.kf_motion_covariance;
    cov.diagonal().array() += 1e-12;  // a perfect odometry still leaves the system solvable
    m.edges.push_back({previous, &camera, m.T_kf_camera, sqrt_information_of(cov)});
  }
  for (const MarkerDetection& d : detections) {
    Node* marker = m.marker(d.id);
    if (marker == nullptr) marker = &m.add_marker(d.id, T_map_camera * d.T_camera_marker);
    m.edges.push_back(
        {&camera, marker, d.T_camera_marker, sqrt_information_of(d.covariance + floor)});
  }
  m.T_kf_camera = Eigen::Isometry3d::Identity();
  m.kf_motion_covariance.setZero();

  ++m.keyframes_since_optimisation;
  if (m.config.optimise_every_keyframes > 0 &&
      m.keyframes_since_optimisation >= m.config.optimise_every_keyframes) {
    m.solve(m.config.incremental_iterations);
    m.keyframes_since_optimisation = 0;
  }
}

MapOptimisation MarkerMap::optimise(int max_iterations) {
  return impl_->solve(max_iterations > 0 ? max_iterations : impl_->config.full_iterations);
}

bool MarkerMap::contains(int id) const { return impl_->marker_index.count(id) != 0; }

std::optional<Eigen::Isometry3d> MarkerMap::T_map_marker(int id) const {
  const Node* n = impl_->marker(id);
  if (n == nullptr) return std::nullopt;
  return n->pose();
}

std::vector<int> MarkerMap::ids() const { return impl_->marker_ids; }

int MarkerMap::keyframes() const { return static_cast<int>(impl_->cameras.size()); }

std::optional<Eigen::Isometry3d> MarkerMap::T_map_camera_last() const {
  if (impl_->cameras.empty()) return std::nullopt;
  return impl_->cameras.back().pose();
}

void MarkerMap::save(const std::string& path) const {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap << YAML::Key << "markers" << YAML::Value << YAML::BeginSeq;
  for (int id : impl_->marker_ids) {
    const Node& n = *impl_->marker(id);
    const Eigen::Quaterniond q = Eigen::Quaterniond(n.q[3], n.q[0], n.q[1], n.q[2]).normalized();
    out << YAML::Flow << YAML::BeginMap << YAML::Key << "id" << YAML::Value << id;
    out << YAML::Key << "p_map_marker_m" << YAML::Value << YAML::Flow << YAML::BeginSeq << n.p[0]
        << n.p[1] << n.p[2] << YAML::EndSeq;
    out << YAML::Key << "q_map_marker_xyzw" << YAML::Value << YAML::Flow << YAML::BeginSeq << q.x()
        << q.y() << q.z() << q.w() << YAML::EndSeq << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  std::ofstream file(path);
  file << out.c_str() << '\n';
  if (!file) throw InputError(path + ": cannot write the marker map");
}

MarkerMap MarkerMap::load(const std::string& path, const MarkerMapConfig& config) {
  const YAML::Node root = config::load_yaml_file(path);
  if (!root.IsMap()) throw InputError(path + ": expected a mapping with key markers");
  config::StrictMap top(root, path);
  top.skip("markers");
  top.finish();
  const YAML::Node list = root["markers"];
  if (!list || !list.IsSequence()) {
    throw InputError(path +
                     ": markers is missing or not a list of {id, p_map_marker_m, "
                     "q_map_marker_xyzw}");
  }
  MarkerMap map(config);
  for (std::size_t i = 0; i < list.size(); ++i) {
    config::StrictMap item(list[i], path, "markers[" + std::to_string(i) + "]");
    int id = 0;
    double p[3];
    double q[4];
    item.require("id", id, 0, 100000);
    item.require_list("p_map_marker_m", p, 3);
    item.require_list("q_map_marker_xyzw", q, 4);
    item.finish();
    if (map.contains(id)) {
      throw InputError(item.describe("id") + " = " + std::to_string(id) +
                       ", expected each id once");
    }
    const Eigen::Vector3d p_m(p[0], p[1], p[2]);
    const Eigen::Quaterniond q_xyzw(q[3], q[0], q[1], q[2]);
    if (!p_m.allFinite()) {
      throw InputError(item.describe("p_map_marker_m") + " is not finite");
    }
    if (!q_xyzw.coeffs().allFinite() || std::abs(q_xyzw.norm() - 1.0) > 1e-6) {
      throw InputError(item.describe("q_map_marker_xyzw") + " has norm " +
                       std::to_string(q_xyzw.norm()) + ", expected a unit quaternion");
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = q_xyzw.normalized().toRotationMatrix();
    T.translation() = p_m;
    map.impl_->add_marker(id, T);
  }
  return map;
}

}  // namespace hq::markers
