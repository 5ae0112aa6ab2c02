// hq-bench-odometry: HaptiQuad's dense odometry beside OpenCV's rgbd odometries on the same
// frames, in one process and one run, one thread each. Prints median / p90 ms per frame (the
// odometry call only; loading and undistortion excluded), the thread's median CPU ms per frame
// (fairer on a shared machine), RPE / ATE against ground truth, and the relative pose error of
// every frame pair (pairs) and of consecutive frames (steps), which rank short sequences, and
// under each table the floor the ground truth's own noise sets on those figures.
// HaptiQuad runs as intensity only, + depth term, + gyro prior, + both, frame to frame and
// frame to keyframe. The gyro is synthesised from the ground truth (TUM has none): the true
// rotation between frames plus white noise and a constant residual bias, as a complementary
// filter's bias estimate leaves it; it also gives the rotation between each frame's depth and
// colour exposures (odometry.align_depth_to_colour; --align-depth-to-colour false to compare).
//
//   hq-bench-odometry [--passes N] [--camera calib/tum_fr1.yaml] [sequence-dir ...]
// (a sequence folder with its own camera.yaml, as hq-sim records, uses that one).
// Without sequence arguments it runs the bundled real sequences under ../shared/data/tum.
#include "hq/base/error.hpp"
#include "hq/base/log.hpp"
#include "hq/base/program.hpp"
#include "hq/base/quantile.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/config/camera_info.hpp"
#include "hq/evaluation/trajectory_error.hpp"
#include "hq/geometry/lie.hpp"
#include "hq/odometry/dense_odometry.hpp"
#include "hq/recording/data_dir.hpp"
#include "hq/recording/tum_io.hpp"
#include "hq/sources/tum_frame_source.hpp"

#include <CLI/CLI.hpp>
#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>
#include <opencv2/rgbd.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fmt/format.h>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace {

struct LoadedSequence {
  std::string name;
  std::vector<hq::sources::RgbdFrame> frames;
  std::vector<hq::recording::StampedPose> ground_truth;
  hq::geometry::PinholeCamera camera;
  std::vector<std::optional<hq::odometry::RotationPrior>> gyro;  ///< per frame; none at 0
};

// Synthetic gyro: noise density of an MPU-class gyro (as replay_imu synthesises) and the bias a
// complementary filter leaves after convergence, on every axis.
constexpr double kGyroNoiseDensity = 1.7e-4;  // rad/s/sqrt(Hz)
constexpr double kGyroResidualBiasRadps = 0.005;
constexpr double kGyroRateHz = 200.0;

std::optional<Eigen::Isometry3d> pose_at(const std::vector<hq::recording::StampedPose>& poses,
                                         std::int64_t t_ns) {
  if (poses.empty() || t_ns < poses.front().t_ns || t_ns > poses.back().t_ns) return std::nullopt;
  const auto next = std::lower_bound(
      poses.begin(), poses.end(), t_ns,
      [](const hq::recording::StampedPose& p, std::int64_t t) { return p.t_ns < t; });
  if (next == poses.begin()) return next->T_G_S;
  const auto prev = next - 1;
  const double s = static_cast<double>(t_ns - prev->t_ns) /
                   static_cast<double>(std::max<std::int64_t>(next->t_ns - prev->t_ns, 1));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(prev->T_G_S.linear())
                   .slerp(s, Eigen::Quaterniond(next->T_G_S.linear()))
                   .toRotationMatrix();
  T.translation() = (1.0 - s) * prev->T_G_S.translation() + s * next->T_G_S.translation();
  return T;
}

void synthesise_gyro(LoadedSequence& sequence) {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> gaussian(0.0, 1.0);
  const Eigen::Vector3d bias = Eigen::Vector3d::Constant(kGyroResidualBiasRadps);
  sequence.gyro.assign(sequence.frames.size(), std::nullopt);
  for (std::size_t i = 0; i < sequence.frames.size(); ++i) {
    const hq::sources::RgbdFrame& frame = sequence.frames[i];
    // The rotation from the depth's exposure to the colour's (Kinect v1 stamps them apart).
    const auto colour = pose_at(sequence.ground_truth, frame.t_ns);
    const auto depth = pose_at(sequence.ground_truth, frame.depth_exposure_ns());
    if (!colour || !depth) continue;
    hq::odometry::RotationPrior prior;
    const double lead_s = 1e-9 * static_cast<double>(frame.t_ns - frame.depth_exposure_ns());
    const Eigen::Vector3d lead_noise(gaussian(rng), gaussian(rng), gaussian(rng));
    prior.R_depth_colour =
        depth->linear().transpose() * colour->linear() *
        hq::geometry::exp_so3(kGyroNoiseDensity * std::sqrt(std::abs(lead_s)) * lead_noise +
                              bias * lead_s);
    prior.information.setZero();  // a first frame: no rotation since a previous one
    const auto a = i > 0 ? pose_at(sequence.ground_truth, sequence.frames[i - 1].t_ns) : colour;
    const auto& b = colour;
    if (i == 0 || !a) {
      sequence.gyro[i] = prior;
      continue;
    }
    const double dt_s =
        1e-9 * static_cast<double>(sequence.frames[i].t_ns - sequence.frames[i - 1].t_ns);
    // Integrated white noise: sigma = density sqrt(dt); the bias integrates to bias dt.
    const double sigma = kGyroNoiseDensity * std::sqrt(dt_s);
    const Eigen::Vector3d noise(gaussian(rng), gaussian(rng), gaussian(rng));
    const Eigen::Vector3d error = sigma * noise + bias * dt_s;
    prior.R_prev_cur = a->linear().transpose() * b->linear() * hq::geometry::exp_so3(error);
    // Information of the white noise (integrated over the interval and over one sample); the
    // residual bias is the odometry's to allow for (odometry.gyro_bias_sigma_radps, which is
    // kGyroResidualBiasRadps by default).
    const double var = sigma * sigma + kGyroNoiseDensity * kGyroNoiseDensity / kGyroRateHz;
    prior.information = Eigen::Matrix3d::Identity() / var;
    sequence.gyro[i] = prior;
  }
}

// A method tracks a whole sequence frame to frame: reset, then one call per frame, returning
// the camera pose in the first frame's coordinates.
class Method {
 public:
  virtual ~Method() = default;
  virtual std::string name() const = 0;
  virtual void reset(const hq::geometry::PinholeCamera& camera) = 0;
  virtual Eigen::Isometry3d track(const hq::sources::RgbdFrame& frame,
                                  const hq::odometry::RotationPrior* gyro) = 0;
  /// The last track()'s full result (HaptiQuad only): its information is what --nees checks.
  virtual const hq::odometry::OdometryResult* last_result() const { return nullptr; }
};

class HaptiQuadMethod final : public Method {
 public:
  HaptiQuadMethod(std::string name, hq::odometry::OdometryConfig config)
      : name_(std::move(name)), config_(config) {}
  std::string name() const override { return name_; }
  void reset(const hq::geometry::PinholeCamera& camera) override {
    odometry_ = std::make_unique<hq::odometry::DenseOdometry>(config_, camera);
  }
  Eigen::Isometry3d track(const hq::sources::RgbdFrame& frame,
                          const hq::odometry::RotationPrior* gyro) override {
    last_ = odometry_->track(frame.t_ns, frame.gray, frame.depth_m, gyro);
    return last_.T_O_C;
  }
  const hq::odometry::OdometryResult* last_result() const override { return &last_; }

 private:
  std::string name_;
  hq::odometry::OdometryConfig config_;
  std::unique_ptr<hq::odometry::DenseOdometry> odometry_;
  hq::odometry::OdometryResult last_;
};

class OpenCvMethod final : public Method {
 public:
  OpenCvMethod(std::string name, std::string type) : name_(std::move(name)), type_(type) {}
  std::string name() const override { return name_; }
  void reset(const hq::geometry::PinholeCamera& camera) override {
    const cv::Mat K =
        (cv::Mat_<float>(3, 3) << camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
    odometry_ = cv::rgbd::Odometry::create(type_);
    odometry_->setCameraMatrix(K);
    previous_.release();
    T_O_C_.setIdentity();
  }
  Eigen::Isometry3d track(const hq::sources::RgbdFrame& frame,
                          const hq::odometry::RotationPrior* /*gyro*/) override {
    cv::Ptr<cv::rgbd::OdometryFrame> current =
        cv::rgbd::OdometryFrame::create(frame.gray, frame.depth_m);
    if (previous_) {
      cv::Mat Rt;
      if (odometry_->compute(previous_, current, Rt)) {
        // OpenCV's Rt maps source (previous) coordinates into destination (current) ones.
        Eigen::Matrix4d T_cur_prev;
        for (int r = 0; r < 4; ++r) {
          for (int c = 0; c < 4; ++c) T_cur_prev(r, c) = Rt.at<double>(r, c);
        }
        T_O_C_ = T_O_C_ * Eigen::Isometry3d(T_cur_prev.inverse());
      }
    }
    previous_ = current;
    return T_O_C_;
  }

 private:
  std::string name_;
  std::string type_;
  cv::Ptr<cv::rgbd::Odometry> odometry_;
  cv::Ptr<cv::rgbd::OdometryFrame> previous_;
  Eigen::Isometry3d T_O_C_ = Eigen::Isometry3d::Identity();
};

LoadedSequence load(const std::string& dir, const hq::config::CameraInfo& camera, double skip_s) {
  hq::sources::TumFrameSource source(dir, camera);
  LoadedSequence sequence;
  sequence.name = std::filesystem::path(dir).filename().string();
  sequence.camera = source.camera();
  sequence.ground_truth = source.sequence().ground_truth();
  hq::sources::RgbdFrame frame;
  std::int64_t first_ns = -1;
  while (source.next(frame) == hq::sources::FrameStatus::kFrame) {
    if (first_ns < 0) first_ns = frame.t_ns;
    if (static_cast<double>(frame.t_ns - first_ns) < skip_s * 1e9) continue;
    hq::sources::RgbdFrame copy;
    copy.t_ns = frame.t_ns;
    copy.depth_t_ns = frame.depth_t_ns;
    copy.gray = frame.gray.clone();
    copy.depth_m = frame.depth_m.clone();
    sequence.frames.push_back(std::move(copy));
  }
  synthesise_gyro(sequence);
  return sequence;
}

struct Row {
  double median_ms = 0, p90_ms = 0, rpe_trans_mps = 0, rpe_rot_degps = 0, ate_m = 0;
  double rpe_window_s = 0;  ///< The RPE's window: 1 s, or the sequence's span when shorter.
  // The thread's CPU time per frame: on a machine shared with other jobs, wall time also
  // counts the time the thread waited for a core.
  double median_cpu_ms = 0;
  // Every pair of frames i < j (not only the 1 s windows): RMSE of the relative pose error
  // E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), not divided by the window, against the ground truth
  // interpolated at each frame's stamp. A short real sequence has few 1 s windows (fr1_360's 5
  // frames give 2, both ending at the last frame); its 10 pairs rank methods more fully.
  double pairs_trans_mm = 0, pairs_rot_deg = 0;
  int pairs = 0;
  // The same over consecutive frames only: each frame-to-frame motion once.
  double steps_trans_mm = 0, steps_rot_deg = 0;
  int steps = 0;
  // Consistency of the returned information (HaptiQuad, first pass): per tracked frame, the
  // rotation error e of T_ref_cur against the truth and e^T (Sigma_rr)^-1 e / 3, Sigma = the
  // inverse of the returned 6x6 information (the rotation's marginal). A consistent estimator
  // has mean 1; the same for the translation block.
  double nees_rot_mean = 0, nees_rot_median = 0, nees_trans_mean = 0, nees_trans_median = 0;
  int nees_count = 0;
  // After the last frame: the honest scale in use and the gyro bias estimate.
  double final_vision_scale = 0;
  // Per tracked frame, the standard deviation of the translation along its least constrained
  // direction (the returned information's): median and largest, mm.
  double translation_sigma_median_mm = 0, translation_sigma_max_mm = 0;
  Eigen::Vector3d final_gyro_bias_radps = Eigen::Vector3d::Zero();
};

/// Relative pose errors of every frame pair i < j (all_pairs) or of consecutive frames only.
void pair_errors(const LoadedSequence& sequence,
                 const std::vector<hq::recording::StampedPose>& trajectory, bool all_pairs,
                 double& trans_mm, double& rot_deg, int& count) {
  std::vector<std::optional<Eigen::Isometry3d>> truth;
  for (const auto& pose : trajectory) truth.push_back(pose_at(sequence.ground_truth, pose.t_ns));
  double sum_t = 0.0, sum_r = 0.0;
  count = 0;
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const std::size_t last =
        all_pairs ? trajectory.size() - 1 : std::min(i + 1, trajectory.size() - 1);
    for (std::size_t j = i + 1; j <= last; ++j) {
      if (!truth[i] || !truth[j]) continue;
      const Eigen::Isometry3d E = (truth[i]->inverse() * *truth[j]).inverse() *
                                  (trajectory[i].T_G_S.inverse() * trajectory[j].T_G_S);
      sum_t += 1e6 * E.translation().squaredNorm();
      const double angle_deg = Eigen::AngleAxisd(E.linear()).angle() * 180.0 / M_PI;
      sum_r += angle_deg * angle_deg;
      ++count;
    }
  }
  trans_mm = count > 0 ? std::sqrt(sum_t / count) : 0.0;
  rot_deg = count > 0 ? std::sqrt(sum_r / count) : 0.0;
}

/// Row::nees_*: one more pass, scoring each tracked frame's T_ref_cur and information against
/// the truth. The reference is the frame that last became one (first frame, lost, keyframe).
void nees(Method& method, const LoadedSequence& sequence, Row& row) {
  if (sequence.ground_truth.empty()) return;
  method.reset(sequence.camera);
  std::vector<double> rot, trans, sigma_mm;
  std::size_t reference = 0;
  for (std::size_t i = 0; i < sequence.frames.size(); ++i) {
    const auto& gyro = sequence.gyro[i];
    method.track(sequence.frames[i], gyro ? &*gyro : nullptr);
    const hq::odometry::OdometryResult* r = method.last_result();
    if (r == nullptr) return;
    if (r->ok()) {
      const auto a = pose_at(sequence.ground_truth, sequence.frames[reference].t_ns);
      const auto b = pose_at(sequence.ground_truth, sequence.frames[i].t_ns);
      const Eigen::LDLT<hq::odometry::Matrix6d> ldlt(r->information);
      if (a && b && ldlt.info() == Eigen::Success) {
        const Eigen::Isometry3d truth = a->inverse() * *b;
        const hq::odometry::Matrix6d covariance = ldlt.solve(hq::odometry::Matrix6d::Identity());
        const Eigen::Vector3d e_rot =
            hq::geometry::log_so3(truth.linear().transpose() * r->T_ref_cur.linear());
        const Eigen::Vector3d e_trans = r->T_ref_cur.translation() - truth.translation();
        const Eigen::Matrix3d cov_v = covariance.topLeftCorner<3, 3>();
        const Eigen::Matrix3d cov_w = covariance.bottomRightCorner<3, 3>();
        rot.push_back(e_rot.dot(cov_w.ldlt().solve(e_rot)) / 3.0);
        sigma_mm.push_back(
            1e3 *
            std::sqrt(
                Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov_v).eigenvalues().maxCoeff()));
        trans.push_back(e_trans.dot(cov_v.ldlt().solve(e_trans)) / 3.0);
      }
    }
    if (r->status != hq::odometry::TrackingStatus::kOk || r->new_keyframe) reference = i;
    row.final_vision_scale = r->vision_information_scale;
    row.final_gyro_bias_radps = r->gyro_bias_radps;
  }
  if (rot.empty()) return;
  const auto mean = [](const std::vector<double>& v) {
    double sum = 0.0;
    for (double x : v) sum += x;
    return sum / static_cast<double>(v.size());
  };
  row.nees_count = static_cast<int>(rot.size());
  row.nees_rot_mean = mean(rot);
  row.nees_trans_mean = mean(trans);
  row.nees_rot_median = hq::quantile(rot, 0.5);
  row.nees_trans_median = hq::quantile(trans, 0.5);
  row.translation_sigma_median_mm = hq::quantile(sigma_mm, 0.5);
  row.translation_sigma_max_mm = hq::quantile(sigma_mm, 1.0);
}

double thread_cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return 1e3 * static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_nsec);
}

Row run(Method& method, const LoadedSequence& sequence, int passes, bool with_nees) {
  std::vector<double> times_ms;
  std::vector<double> cpu_ms;
  std::vector<hq::recording::StampedPose> trajectory;
  for (int pass = 0; pass < passes; ++pass) {
    method.reset(sequence.camera);
    trajectory.clear();
    for (std::size_t i = 0; i < sequence.frames.size(); ++i) {
      const double cpu_start_ms = thread_cpu_ms();
      const auto start = std::chrono::steady_clock::now();
      const auto& gyro = sequence.gyro[i];
      const Eigen::Isometry3d T_O_C = method.track(sequence.frames[i], gyro ? &*gyro : nullptr);
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
              .count();
      const double cpu = thread_cpu_ms() - cpu_start_ms;
      if (i > 0) {  // the first frame only prepares a reference
        times_ms.push_back(ms);
        cpu_ms.push_back(cpu);
      }
      trajectory.push_back({sequence.frames[i].t_ns, T_O_C});
    }
  }
  Row row;
  if (with_nees) nees(method, sequence, row);
  row.median_ms = hq::quantile(times_ms, 0.5);
  row.p90_ms = hq::quantile(times_ms, 0.9);
  row.median_cpu_ms = hq::quantile(cpu_ms, 0.5);
  if (!sequence.ground_truth.empty()) {
    const auto rpe = hq::evaluation::relative_pose_error(sequence.ground_truth, trajectory);
    const auto ate = hq::evaluation::absolute_trajectory_error(sequence.ground_truth, trajectory);
    row.rpe_trans_mps = rpe.trans_mps.rmse;
    row.rpe_rot_degps = rpe.rot_degps.rmse;
    row.rpe_window_s = rpe.delta_s;
    row.ate_m = ate.trans_m.rmse;
    pair_errors(sequence, trajectory, true, row.pairs_trans_mm, row.pairs_rot_deg, row.pairs);
    pair_errors(sequence, trajectory, false, row.steps_trans_mm, row.steps_rot_deg, row.steps);
  }
  return row;
}

/// Every method compared: the shipped defaults, each term on and off in the three reference
/// modes, the defaults at full resolution, then OpenCV's three (unless only_haptiquad). Every
/// HaptiQuad variant starts from `defaults` (OdometryConfig{} with the command line's settings).
std::vector<std::unique_ptr<Method>> make_methods(const hq::odometry::OdometryConfig& defaults,
                                                  bool only_haptiquad) {
  std::vector<std::unique_ptr<Method>> methods;
  // The defaults (config/onboard.yaml) first, then each term on and off in both modes.
  methods.push_back(std::make_unique<HaptiQuadMethod>("hq default 320", defaults));
  // Frame to frame, frame to keyframe, frame to keyframe with the keyframe check.
  for (const int mode_index : {0, 1, 2}) {
    const auto mode = mode_index == 0 ? hq::odometry::ReferenceMode::kFrameToFrame
                                      : hq::odometry::ReferenceMode::kFrameToKeyframe;
    for (const int variant : {0, 1, 2, 3}) {
      hq::odometry::OdometryConfig c = defaults;
      c.reference_mode = mode;
      c.keyframe_check = mode_index == 2;
      c.use_depth_term = (variant & 1) != 0;
      c.use_rotation_prior = (variant & 2) != 0;
      const char* names[] = {"I", "I+D", "I+gyro", "I+D+gyro"};
      const char* modes[] = {"hq f2f ", "hq f2kf ", "hq f2kf+check "};
      std::string name = modes[mode_index];
      methods.push_back(std::make_unique<HaptiQuadMethod>(name + names[variant], c));
    }
  }
  // The depth term on the finest level only (odometry.depth_levels: 1), frame to keyframe with
  // the gyro: the coarse levels' depth is what real Kinect depth makes the least of.
  hq::odometry::OdometryConfig finest_depth = defaults;
  finest_depth.reference_mode = hq::odometry::ReferenceMode::kFrameToKeyframe;
  finest_depth.use_depth_term = true;
  finest_depth.use_rotation_prior = true;
  finest_depth.depth_levels = 1;
  methods.push_back(std::make_unique<HaptiQuadMethod>("hq f2kf I+D(finest)+gyro", finest_depth));
  hq::odometry::OdometryConfig full = defaults;
  full.finest_level = 0;
  methods.push_back(std::make_unique<HaptiQuadMethod>("hq default 640", full));
  if (!only_haptiquad) {
    methods.push_back(std::make_unique<OpenCvMethod>("opencv RgbdOdometry", "RgbdOdometry"));
    methods.push_back(std::make_unique<OpenCvMethod>("opencv ICPOdometry", "ICPOdometry"));
    methods.push_back(std::make_unique<OpenCvMethod>("opencv RgbdICPOdometry", "RgbdICPOdometry"));
  }
  return methods;
}

/// What the ground truth itself cannot tell apart: its noise per pose (from its own samples)
/// carried to a pair of poses (two independent ends) and to the RPE over its window; then, per
/// figure, the methods within that floor of the best one (those the data cannot rank apart).
void print_ground_truth_floor(const LoadedSequence& sequence,
                              const std::vector<std::unique_ptr<Method>>& methods,
                              const std::vector<Row>& rows) {
  if (sequence.ground_truth.empty() || rows.empty()) return;
  const hq::evaluation::PoseNoise noise = hq::evaluation::ground_truth_noise(sequence.ground_truth);
  const double window_s = rows.front().rpe_window_s;
  if (noise.differences == 0 || !(window_s > 0.0)) return;
  const double pair_mm = noise.pair_trans_m() * 1e3;
  const double pair_deg = noise.pair_rot_deg();
  const double rpe_mps = noise.pair_trans_m() / window_s;
  const double rpe_degps = pair_deg / window_s;
  fmt::print(
      "ground truth noise per pose (third differences of its {} poses): {:.3f} mm, {:.3f} deg; "
      "floor of a pair's error {:.2f} mm, {:.3f} deg; of the RPE over {:.2f} s {:.4f} m/s, {:.3f} "
      "deg/s\n",
      sequence.ground_truth.size(), noise.trans_m * 1e3, noise.rot_deg, pair_mm, pair_deg, window_s,
      rpe_mps, rpe_degps);
  struct Figure {
    const char* name;
    double Row::*value;
    double floor;
  };
  const Figure figures[] = {
      {"rpe_t_m/s", &Row::rpe_trans_mps, rpe_mps}, {"rpe_r_deg/s", &Row::rpe_rot_degps, rpe_degps},
      {"pairs_mm", &Row::pairs_trans_mm, pair_mm}, {"pairs_deg", &Row::pairs_rot_deg, pair_deg},
      {"steps_mm", &Row::steps_trans_mm, pair_mm}, {"steps_deg", &Row::steps_rot_deg, pair_deg}};
  for (const Figure& f : figures) {
    double best = std::numeric_limits<double>::infinity();
    for (const Row& r : rows) best = std::min(best, r.*f.value);
    std::string within;
    for (std::size_t m = 0; m < rows.size(); ++m) {
      if (rows[m].*f.value > best + f.floor) continue;
      within += (within.empty() ? "" : ", ") + methods[m]->name();
    }
    fmt::print("  best within the floor, {}: {}\n", f.name, within);
  }
}

/// One table: every method on one sequence; speedup against the method at reference_index.
void print_sequence_table(const LoadedSequence& sequence,
                          const std::vector<std::unique_ptr<Method>>& methods,
                          std::size_t reference_index, int passes, bool with_nees) {
  fmt::print("\nsequence {}: {} frames {}x{}, {} passes, one thread\n", sequence.name,
             sequence.frames.size(), sequence.camera.width, sequence.camera.height, passes);
  fmt::print("{:<24} {:>9} {:>9} {:>9} {:>11} {:>11} {:>9} {:>10} {:>9} {:>9} {:>9} {:>9}\n",
             "method", "median_ms", "p90_ms", "cpu_ms", "rpe_t_m/s", "rpe_r_deg/s", "ate_m",
             "speedup", "pairs_mm", "pairs_deg", "steps_mm", "steps_deg");
  std::vector<Row> rows;
  for (const auto& method : methods) rows.push_back(run(*method, sequence, passes, with_nees));
  const double reference_ms = rows[reference_index].median_ms;
  for (std::size_t m = 0; m < methods.size(); ++m) {
    const Row& r = rows[m];
    fmt::print(
        "{:<24} {:9.2f} {:9.2f} {:9.2f} {:11.4f} {:11.3f} {:9.4f} {:9.1f}x {:9.2f} {:9.3f} {:9.2f} "
        "{:9.3f}\n",
        methods[m]->name(), r.median_ms, r.p90_ms, r.median_cpu_ms, r.rpe_trans_mps,
        r.rpe_rot_degps, r.ate_m, reference_ms / r.median_ms, r.pairs_trans_mm, r.pairs_rot_deg,
        r.steps_trans_mm, r.steps_rot_deg);
    if (with_nees && r.nees_count > 0) {
      fmt::print(
          "  nees over {} frames: rotation mean {:.1f} median {:.2f}, translation mean {:.1f} "
          "median {:.2f}\n",
          r.nees_count, r.nees_rot_mean, r.nees_rot_median, r.nees_trans_mean, r.nees_trans_median);
      fmt::print(
          "  translation sigma, least constrained direction: median {:.2f} mm, largest {:.2f} mm\n",
          r.translation_sigma_median_mm, r.translation_sigma_max_mm);
      fmt::print(
          "  after the last frame: vision information scale {:.3g}, gyro bias {:.4f} {:.4f} {:.4f} "
          "rad/s\n",
          r.final_vision_scale, r.final_gyro_bias_radps.x(), r.final_gyro_bias_radps.y(),
          r.final_gyro_bias_radps.z());
    }
  }
  if (!rows.empty()) {
    fmt::print(
        "pairs: RMSE over all {} frame pairs i < j; steps: over the {} consecutive pairs (mm, deg, "
        "not per second)\n",
        rows.front().pairs, rows.front().steps);
    print_ground_truth_floor(sequence, methods, rows);
  }
}

// The odometry options every HaptiQuad variant of the run shares.
void add_shared_odometry_options(CLI::App& app, hq::odometry::OdometryConfig& defaults) {
  app.add_option("--depth-point-stride", defaults.depth_point_stride,
                 "odometry.depth_point_stride of every HaptiQuad variant")
      ->check(CLI::PositiveNumber);
  app.add_option("--vision-information-scale", defaults.vision_information_scale,
                 "odometry.vision_information_scale of every HaptiQuad variant")
      ->check(CLI::PositiveNumber);
  app.add_option("--estimate-gyro-bias", defaults.estimate_gyro_bias,
                 "odometry.estimate_gyro_bias of every HaptiQuad variant (true/false)");
  app.add_option("--gyro-bias-sigma", defaults.gyro_bias_sigma_radps,
                 "odometry.gyro_bias_sigma_radps of every HaptiQuad variant")
      ->check(CLI::PositiveNumber);
  app.add_option("--moving-min-displacement-px", defaults.moving_min_displacement_px,
                 "odometry.moving_min_displacement_px of every HaptiQuad method");
  app.add_option("--moving-realign-ratio", defaults.moving_realign_ratio,
                 "odometry.moving_realign_ratio of every HaptiQuad method (1: never)");
  app.add_option("--moving-mark-radius-px", defaults.moving_mark_radius_px,
                 "odometry.moving_mark_radius_px of every HaptiQuad method")
      ->check(CLI::Range(1, 32));
  app.add_option("--degenerate-step-ratio", defaults.degenerate_step_ratio,
                 "odometry.degenerate_step_ratio of every HaptiQuad variant")
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--depth-jacobian-from-normals", defaults.depth_jacobian_from_normals,
                 "odometry.depth_jacobian_from_normals of every HaptiQuad variant (true/false)");
  app.add_option("--align-depth-to-colour", defaults.align_depth_to_colour,
                 "odometry.align_depth_to_colour of every HaptiQuad variant (true/false)");
  app.add_option("--adapt-vision-information", defaults.adapt_vision_information,
                 "odometry.adapt_vision_information of every HaptiQuad variant (true/false)");
}

}  // namespace

static int run_benchmarks(int argc, char** argv) {
  CLI::App app{
      "HaptiQuad dense odometry beside OpenCV's RgbdOdometry, ICPOdometry, RgbdICPOdometry"};
  std::vector<std::string> sequence_dirs;
  std::string camera_path = "calib/tum_fr1.yaml";
  int passes = 10;
  double skip_s = 0.0;
  bool only_haptiquad = false;
  // What every HaptiQuad variant shares; the options below set it.
  hq::odometry::OdometryConfig defaults;
  app.add_option("sequences", sequence_dirs, "TUM RGB-D sequence folders");
  app.add_option("--camera", camera_path, "camera file of sequences without their own camera.yaml");
  app.add_option("--passes", passes, "times each sequence is run per method")
      ->check(CLI::PositiveNumber);
  app.add_option("--skip-s", skip_s,
                 "seconds skipped at each sequence's start (hq-sim: 3 s, take-off without depth)")
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--only-haptiquad", only_haptiquad, "skip OpenCV's methods (quick comparisons)");
  std::vector<std::string> method_filters;
  app.add_option("--method", method_filters,
                 "run only the methods whose name contains this text (repeatable; exact name "
                 "match when the text ends with '$')")
      ->allow_extra_args(false);  // one text per --method: sequence folders may follow
  add_shared_odometry_options(app, defaults);
  bool with_nees = false;
  app.add_flag("--nees", with_nees,
               "one more pass per HaptiQuad method: the returned information's consistency "
               "(NEES) against the ground truth");
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;

  cv::setNumThreads(1);
  if (sequence_dirs.empty()) {
    const auto data = hq::recording::find_data_dir();
    if (!data) {
      hq::log::error("hq-bench-odometry: no sequences given and no data found ({})\n",
                     hq::recording::data_dir_search_description());
      return 2;
    }
    for (const auto& entry : std::filesystem::directory_iterator(*data + "/tum")) {
      if (entry.is_directory()) sequence_dirs.push_back(entry.path().string());
    }
    std::sort(sequence_dirs.begin(), sequence_dirs.end());
  }
  const hq::config::CameraInfo camera = hq::config::load_camera_info(camera_path);
  std::vector<std::unique_ptr<Method>> methods;
  for (auto& method : make_methods(defaults, only_haptiquad)) {
    const std::string name = method->name();
    const bool wanted =
        method_filters.empty() ||
        std::any_of(method_filters.begin(), method_filters.end(), [&](const std::string& f) {
          return !f.empty() && f.back() == '$' ? name == f.substr(0, f.size() - 1)
                                               : name.find(f) != std::string::npos;
        });
    if (wanted) methods.push_back(std::move(method));
  }
  if (methods.empty()) throw hq::InputError("--method: no method's name matches");
  // Speedups against OpenCV's RgbdOdometry; without it, against the first method.
  std::size_t opencv_rgbd = 0;
  for (std::size_t m = 0; m < methods.size(); ++m) {
    if (methods[m]->name() == "opencv RgbdOdometry") opencv_rgbd = m;
  }

  for (const std::string& dir : sequence_dirs) {
    // A simulator recording carries its own camera.yaml; TUM folders use --camera.
    const std::string own_camera = dir + "/camera.yaml";
    const LoadedSequence sequence = load(
        dir,
        std::filesystem::exists(own_camera) ? hq::config::load_camera_info(own_camera) : camera,
        skip_s);
    print_sequence_table(sequence, methods, opencv_rgbd, passes, with_nees);
  }
  fmt::print(
      "\nspeedup = OpenCV RgbdOdometry (else the first method) median / method median, same "
      "run.\n");
  return 0;
}

int main(int argc, char** argv) {
  return hq::run_tool("hq-bench-odometry", argc, argv, run_benchmarks);
}
