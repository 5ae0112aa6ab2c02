#include "hq/closed_loop/flight_summary.hpp"

#include "hq/base/error.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>

namespace hq::closed_loop {

namespace {

Eigen::Vector3d rms(const Eigen::Vector3d& sum_sq, int n) {
  return n > 0 ? Eigen::Vector3d((sum_sq / n).cwiseSqrt())
               : Eigen::Vector3d::Constant(std::nan(""));
}

}  // namespace

FlightSummary summarise(const ClosedLoop& loop) {
  FlightSummary s;
  const std::vector<FlightSample>& samples = loop.samples();
  s.min_clearance_m = loop.min_clearance_m() < 1e8 ? loop.min_clearance_m() : std::nan("");
  s.collision_ticks = loop.collision_ticks();
  s.floor_impacts = loop.simulator().floor_impacts();
  s.max_floor_impact_speed_mps = loop.simulator().max_floor_impact_speed_mps();
  if (samples.empty()) return s;
  s.duration_s = samples.back().t_s;

  Eigen::Vector3d est_sq = Eigen::Vector3d::Zero();
  Eigen::Vector3d track_sq = Eigen::Vector3d::Zero();
  Eigen::Vector3d operator_sq = Eigen::Vector3d::Zero();
  double yaw_sq = 0.0;
  int n_ok = 0;
  const FlightSample* first_airborne = nullptr;
  const FlightSample* last_airborne = nullptr;
  double previous_t_s = 0.0;
  for (const FlightSample& x : samples) {
    if (x.clearance_sent_m >= 0.0 && !(x.clearance_sent_m >= s.min_clearance_sent_m)) {
      s.min_clearance_sent_m = x.clearance_sent_m;  // NaN compares false: the first one
    }
    const double dt_s = x.t_s - previous_t_s;
    previous_t_s = x.t_s;
    if (x.frame) ++s.frames;
    if (!x.airborne) continue;
    if (!first_airborne) first_airborne = &x;
    last_airborne = &x;
    s.max_speed_true_mps = std::max(s.max_speed_true_mps, x.v_true_mps.norm());
    if (x.safe_hover) s.safe_hover_s += dt_s;
    if (!x.frame) continue;
    ++s.airborne_frames;
    if (!x.estimate_ok) continue;
    ++n_ok;
    est_sq += (x.v_est_mps - x.v_true_mps).cwiseAbs2();
    track_sq += (x.v_des_mps - x.v_true_mps).cwiseAbs2();
    operator_sq += (x.v_star_des_mps - x.v_true_mps).cwiseAbs2();
    yaw_sq += std::pow(x.yaw_rate_cmd_radps - x.yaw_rate_gyro_radps, 2);
  }
  s.estimate_available = s.airborne_frames > 0 ? static_cast<double>(n_ok) / s.airborne_frames : 0;
  s.velocity_rmse_mps = rms(est_sq, n_ok);
  s.tracking_rmse_mps = rms(track_sq, n_ok);
  s.operator_tracking_rmse_mps = rms(operator_sq, n_ok);
  s.yaw_rate_rmse_radps = n_ok > 0 ? std::sqrt(yaw_sq / n_ok) : std::nan("");
  if (first_airborne) {
    s.horizontal_drift_m =
        (last_airborne->p_N_m.head<2>() - first_airborne->p_N_m.head<2>()).norm();
  }
  return s;
}

void print_summary(std::FILE* out, const std::string& title, const FlightSummary& s) {
  const auto row3 = [out](const char* name, const Eigen::Vector3d& v, const char* unit) {
    fmt::print(out, "  {:<40} x {:.3f}  y {:.3f}  z {:.3f} {}\n", name, v.x(), v.y(), v.z(), unit);
  };
  fmt::print(out, "{}\n", title.c_str());
  fmt::print(out, "  {:<40} {:.1f} s, {} frames ({} airborne)\n", "flight", s.duration_s, s.frames,
             s.airborne_frames);
  fmt::print(out, "  {:<40} {:.1f} %\n", "estimate available (airborne frames)",
             100.0 * s.estimate_available);
  row3("velocity estimate RMSE vs truth (H)", s.velocity_rmse_mps, "m/s");
  row3("tracking RMSE, v_des vs truth (H)", s.tracking_rmse_mps, "m/s");
  row3("tracking RMSE, operator v*_des vs truth", s.operator_tracking_rmse_mps, "m/s");
  fmt::print(out, "  {:<40} {:.3f} rad/s\n", "yaw rate RMSE, command vs gyro",
             s.yaw_rate_rmse_radps);
  // The vehicle's own figure (the state's, the console's, hq-report's), then the truth.
  fmt::print(out, "  {:<40} {:.3f} m\n", "closest distance (clearance)", s.min_clearance_sent_m);
  fmt::print(out, "  {:<40} {:.3f} m\n", "closest distance, simulator truth", s.min_clearance_m);
  fmt::print(out, "  {:<40} {}\n", "collision ticks", s.collision_ticks);
  fmt::print(out, "  {:<40} {}, fastest {:.2f} m/s\n", "floor contacts (falls count as collisions)",
             s.floor_impacts, s.max_floor_impact_speed_mps);
  fmt::print(out, "  {:<40} {:.2f} m/s\n", "max true speed", s.max_speed_true_mps);
  fmt::print(out, "  {:<40} {:.2f} s\n", "time in safe hover (airborne)", s.safe_hover_s);
}

void write_figure_csv(const std::string& path, const std::vector<FlightSample>& samples) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) throw InputError(path + ": cannot open for writing");
  fmt::print(f,
             "# Core paper Fig. 6-8 signals from a simulated flight. Frames "
             "(hq/geometry/frames.hpp): H horizontal (yaw only, z down), N the simulator's NWU "
             "world. est = on-board estimate, true = simulator, cmd = operator v*_des, "
             "des = v*_des + v_obs. Yaw rates about z of H. SI units.\n");
  fmt::print(f,
             "t_s,frame,airborne,mode,estimate_ok,v_est_H_x_mps,v_est_H_y_mps,v_est_H_z_mps,"
             "v_true_H_x_mps,v_true_H_y_mps,v_true_H_z_mps,v_cmd_H_x_mps,v_cmd_H_y_mps,"
             "v_cmd_H_z_mps,v_des_H_x_mps,v_des_H_y_mps,v_des_H_z_mps,v_obs_H_x_mps,"
             "v_obs_H_y_mps,v_obs_H_z_mps,yaw_rate_cmd_radps,yaw_rate_gyro_radps,"
             "yaw_rate_true_radps,clearance_m,p_N_x_m,p_N_y_m,p_N_z_m,safe_hover,reason\n");
  for (const FlightSample& s : samples) {
    fmt::print(f, "{:.4f},{},{},{},{}", s.t_s, s.frame ? 1 : 0, s.airborne ? 1 : 0,
               modes::to_string(s.mode), s.estimate_ok ? 1 : 0);
    for (const Eigen::Vector3d* v :
         {&s.v_est_mps, &s.v_true_mps, &s.v_star_des_mps, &s.v_des_mps, &s.v_obs_mps}) {
      fmt::print(f, ",{:.5f},{:.5f},{:.5f}", v->x(), v->y(), v->z());
    }
    fmt::print(f, ",{:.5f},{:.5f},{:.5f},{:.4f},{:.4f},{:.4f},{:.4f},{},\"{}\"\n",
               s.yaw_rate_cmd_radps, s.yaw_rate_gyro_radps, s.yaw_rate_true_radps, s.clearance_m,
               s.p_N_m.x(), s.p_N_m.y(), s.p_N_m.z(), s.safe_hover ? 1 : 0, s.reason);
  }
  if (std::fclose(f) != 0) throw InputError(path + ": write failed");
}

}  // namespace hq::closed_loop
