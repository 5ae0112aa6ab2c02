// hq-evaluate: TUM benchmark accuracy (RPE, ATE; Sturm et al., IROS 2012) of an estimated
// trajectory against ground truth, both in TUM trajectory format.
#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/base/log.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/evaluation/trajectory_error.hpp"
#include "hq/recording/tum_io.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <optional>
#include <string>
#include <vector>

namespace {

void print_row(const char* name, const char* unit, const hq::evaluation::ErrorStats& s) {
  hq::log::info("{:<10} {:<6} {:10.6f} {:10.6f} {:10.6f} {:10.6f} {:6}\n", name, unit, s.rmse,
                s.mean, s.median, s.max, s.count);
}

double largest_coordinate_m(const std::vector<hq::recording::StampedPose>& poses) {
  double largest = 0.0;
  for (const auto& p : poses)
    largest = std::max(largest, p.T_G_S.translation().cwiseAbs().maxCoeff());
  return largest;
}

// A figure that is not finite (positions so large their squares overflow) is no accuracy: say
// so and exit 2 rather than print inf with exit 0.
void require_finite(const char* name, const hq::evaluation::ErrorStats& s, const std::string& gt,
                    double gt_largest_m, const std::string& est, double est_largest_m) {
  for (const double v : {s.rmse, s.mean, s.median, s.max}) {
    if (std::isfinite(v)) continue;
    char message[512];
    hq::format_into(message,
                    "{} is {:g} over {} pairs, expected finite; the largest coordinate is {:g} m "
                    "in {} and {:g} m in {}",
                    name, v, s.count, gt_largest_m, gt, est_largest_m, est);
    throw hq::InputError(message);
  }
}

}  // namespace

static int run(int argc, char** argv) {
  CLI::App app{"Relative pose error and absolute trajectory error of a TUM-format trajectory"};
  std::string gt_path;
  std::string est_path;
  double delta_s = 1.0;
  double max_dt_s = 0.02;
  app.add_option("--gt", gt_path, "ground truth, \"t tx ty tz qx qy qz qw\" per line")->required();
  app.add_option("--est", est_path, "estimated trajectory, same format")->required();
  app.add_option("--delta-s", delta_s, "RPE window length (s)");
  app.add_option("--max-dt-s", max_dt_s, "largest stamp difference of an associated pair (s)");
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;

  const auto gt = hq::recording::read_tum_trajectory(gt_path);
  const auto est = hq::recording::read_tum_trajectory(est_path);
  const auto pairs = hq::evaluation::associate_poses(gt, est, max_dt_s);
  const auto rpe = hq::evaluation::relative_pose_error(gt, est, delta_s, max_dt_s);
  const auto ate = hq::evaluation::absolute_trajectory_error(gt, est, max_dt_s);

  const double gt_largest_m = largest_coordinate_m(gt);
  const double est_largest_m = largest_coordinate_m(est);
  require_finite("RPE trans", rpe.trans_mps, gt_path, gt_largest_m, est_path, est_largest_m);
  require_finite("RPE rot", rpe.rot_degps, gt_path, gt_largest_m, est_path, est_largest_m);
  require_finite("ATE", ate.trans_m, gt_path, gt_largest_m, est_path, est_largest_m);

  hq::log::info("poses: ground truth {}, estimate {}, associated {} (max_dt {:.3f} s)\n", gt.size(),
                est.size(), pairs.size(), max_dt_s);
  hq::log::info(
      "RPE window {:.3f} s{}\n", rpe.delta_s,
      rpe.delta_clipped ? " (clipped: the associated poses span less than --delta-s)" : "");
  hq::log::info("{:<10} {:<6} {:>10} {:>10} {:>10} {:>10} {:>6}\n", "metric", "unit", "rmse",
                "mean", "median", "max", "count");
  print_row("RPE trans", "m/s", rpe.trans_mps);
  print_row("RPE rot", "deg/s", rpe.rot_degps);
  print_row("ATE", "m", ate.trans_m);
  // The ground truth's own noise: two estimates whose errors differ by less are not ranked by it.
  const hq::evaluation::PoseNoise noise = hq::evaluation::ground_truth_noise(gt);
  if (noise.differences == 0) {
    hq::log::info("ground truth noise: not estimated (needs 4 or more evenly spaced poses)\n");
  } else {
    hq::log::info(
        "ground truth noise per pose {:.6f} m, {:.4f} deg (third differences of its poses): "
        "floor of the RPE {:.6f} m/s, {:.4f} deg/s\n",
        noise.trans_m, noise.rot_deg, noise.pair_trans_m() / rpe.delta_s,
        noise.pair_rot_deg() / rpe.delta_s);
  }
  return 0;
}

int main(int argc, char** argv) { return hq::run_tool("hq-evaluate", argc, argv, run); }
