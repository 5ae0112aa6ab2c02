#pragma once
/// What a simulated flight is judged by (core paper §4): how well the estimate follows truth,
/// how well the vehicle follows the command, how close it came to obstacles, and the signals of
/// its Fig. 6-8 as a CSV.

#include "hq/closed_loop/closed_loop.hpp"

#include <Eigen/Core>

#include <cstdio>
#include <string>
#include <vector>

namespace hq::closed_loop {

struct FlightSummary {
  double duration_s = 0.0;
  int frames = 0;
  int airborne_frames = 0;
  double estimate_available = 0.0;  ///< Fraction of airborne frames with an ok estimate.
  double safe_hover_s = 0.0;        ///< Airborne time spent in the safe hover (approximate).
  /// Per axis of H, over airborne frames with an ok estimate.
  Eigen::Vector3d velocity_rmse_mps = Eigen::Vector3d::Constant(NAN);
  /// Truth against v_des = v*_des + v_obs (what the PID was asked) and against the operator's
  /// v*_des alone (what the paper plots); airborne frames with an ok estimate.
  Eigen::Vector3d tracking_rmse_mps = Eigen::Vector3d::Constant(NAN);
  Eigen::Vector3d operator_tracking_rmse_mps = Eigen::Vector3d::Constant(NAN);
  double yaw_rate_rmse_radps = NAN;  ///< Commanded against the gyro, as Fig. 8.
  double min_clearance_m = NAN;      ///< Truth: surface to vehicle sphere, every physics tick.
  /// The vehicle's clearance as it sent it (ClearanceFilter), smallest over the flight's steps:
  /// what the ground shows and hq-report finds; NaN if it never saw an obstacle.
  double min_clearance_sent_m = NAN;
  int collision_ticks = 0;
  int floor_impacts = 0;  ///< touchdowns and impacts, each once
  double max_floor_impact_speed_mps = 0.0;
  double max_speed_true_mps = 0.0;
  /// Horizontal distance between first and last airborne truth position (for hovers).
  double horizontal_drift_m = NAN;
};

FlightSummary summarise(const ClosedLoop& loop);

/// A small table on `out`, one figure per line, named with units.
void print_summary(std::FILE* out, const std::string& title, const FlightSummary& summary);

/// The signals of the core paper's Fig. 6-8, one row per sample: estimated, true and commanded
/// (v*_des and v_des) velocity in H, v_obs, commanded and measured yaw rate, plus clearance,
/// mode and the safe-hover reason. Throws hq::InputError if the file cannot be written.
void write_figure_csv(const std::string& path, const std::vector<FlightSample>& samples);

}  // namespace hq::closed_loop
