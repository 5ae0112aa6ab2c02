// hq-report: the flight report of a recording made by hq-ground --record. Plots in the manner
// of Fig. 6-8 of the core paper (velocity in H estimated vs commanded per axis, and vs simulator
// truth when recorded; v_obs; yaw rate commanded vs measured), the dead-reckoned top view with
// the vehicle's own position where it sent one and the summary figures (tracking error,
// closest obstacle, mode changes, link incidents), drawn by Debian's gnuplot run as a
// subprocess on a generated script, plus report.md linking them. No shell is involved and no
// path reaches gnuplot's script: gnuplot is spawned with an argument vector in the output
// folder, and the script names only the fixed file names there.
//   hq-report <recording-dir> [--out DIR] [--format png|svg]
#include "hq/base/error.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/console/recording.hpp"

#include <CLI/CLI.hpp>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

extern char** environ;

namespace {

namespace fs = std::filesystem;

struct Summary {
  double duration_s = 0;
  std::array<double, 3> rms_tracking_mps{};  ///< |v_est - v_cmd| per axis of H, teleop only.
  std::size_t tracking_samples = 0;
  double closest_obstacle_m = NAN;
  double max_v_obs_mps = 0;
  std::vector<std::string> mode_changes;
  std::size_t sequence_gaps = 0;
  double max_state_gap_s = 0;
  double latency_p50_ms = 0;
  double latency_max_ms = 0;
  std::size_t warnings = 0;
  /// |v_est - v_truth| per axis of H over the states that carry simulator truth.
  std::array<double, 3> rmse_truth_mps{};
  std::size_t truth_samples = 0;
  std::size_t position_samples = 0;  ///< States with the vehicle's own position in W.
};

// Runs `args` (args[0] looked up on PATH) in `directory` with stdin from /dev/null and stderr
// to `stderr_name` there; returns the exit status, or -1 if it died of a signal. A path, quote
// or ';' in any argument is passed as bytes, never seen by a shell. Throws if it cannot start.
int run_in(const std::vector<std::string>& args, const std::string& directory,
           const std::string& stderr_name) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addchdir_np(&actions, directory.c_str());
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, stderr_name.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = -1;
  const int error = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (error == ENOENT) {
    throw hq::InputError(args[0] +
                         ": not found on PATH; hq-report draws its figures with "
                         "Debian's gnuplot (apt-get install gnuplot-nox)");
  }
  if (error != 0) {
    throw hq::InputError("posix_spawnp(" + args[0] + ") in " + directory + ": " +
                         std::strerror(error));
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) throw hq::InputError("waitpid(" + args[0] + "): " + std::strerror(errno));
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// Latest command at or before t_ns (commands are in time order).
const hq::console::RecordedCommand* command_at(const std::vector<hq::console::RecordedCommand>& c,
                                               std::int64_t t_ns) {
  const auto it = std::upper_bound(c.begin(), c.end(), t_ns,
                                   [](std::int64_t t, const auto& x) { return t < x.t_ns; });
  return it == c.begin() ? nullptr : &*(it - 1);
}

int run(int argc, char** argv) {
  CLI::App app{"hq-report: flight report of an hq-ground recording"};
  std::string dir;
  std::string out_dir;
  std::string format = "png";
  app.add_option("recording", dir, "recording directory (hq-ground --record)")->required();
  app.add_option("--out", out_dir, "output directory (default: <recording>/report)");
  app.add_option("--format", format, "figure format")->check(CLI::IsMember({"png", "svg"}));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (out_dir.empty()) out_dir = (fs::path(dir) / "report").string();
  const hq::console::Recording r = hq::console::load_recording(dir);
  for (const std::string& p : r.problems) std::fprintf(stderr, "hq-report: %s\n", p.c_str());
  for (const std::string& c : r.absent_columns) {
    std::fprintf(stderr, "hq-report: column absent (older layout): %s\n", c.c_str());
  }
  if (r.states.empty()) {
    throw hq::InputError(dir + "/telemetry.csv: no readable vehicle state, nothing to report");
  }
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) throw hq::InputError("--out " + out_dir + ": cannot create: " + ec.message());

  // One data file for gnuplot: time, estimate, command, v_obs, yaw rates, track, closest.
  const std::int64_t t0_ns = r.states.front().receipt_ns;
  Summary sum;
  const std::string data_name = "flight.dat";
  const std::string data_path = (fs::path(out_dir) / data_name).string();
  std::ofstream data(data_path);
  if (!data) throw hq::InputError(data_path + ": cannot open for writing");
  data << "# t_s v_est_x v_est_y v_est_z v_cmd_x v_cmd_y v_cmd_z v_obs_x v_obs_y v_obs_z "
          "yaw_cmd yaw_meas x_W y_W closest_m latency_ms v_truth_x v_truth_y v_truth_z "
          "p_W_x p_W_y (NaN: absent)\n";
  double yaw = 0;
  double x = 0;
  double y = 0;
  std::vector<double> latencies;
  const char* previous_mode = nullptr;
  for (std::size_t i = 0; i < r.states.size(); ++i) {
    const hq::console::RecordedState& s = r.states[i];
    const double t_s = 1e-9 * static_cast<double>(s.receipt_ns - t0_ns);
    if (i > 0) {
      // Dead reckoning as the console's top view: p_W += R_z(yaw) v_H dt.
      const double dt = std::min(1e-9 * static_cast<double>(s.receipt_ns - r.states[i - 1].receipt_ns), 1.0);
      sum.max_state_gap_s = std::max(sum.max_state_gap_s, dt);
      if (s.sequence > r.states[i - 1].sequence + 1) {
        sum.sequence_gaps += s.sequence - r.states[i - 1].sequence - 1;
      }
      yaw += s.omega_body_radps[2] * dt;
      x += (std::cos(yaw) * s.v_H_mps[0] - std::sin(yaw) * s.v_H_mps[1]) * dt;
      y += (std::sin(yaw) * s.v_H_mps[0] + std::cos(yaw) * s.v_H_mps[1]) * dt;
    }
    if (previous_mode != s.mode) {
      char line[96];
      std::snprintf(line, sizeof line, "%.2f s: %s", t_s, s.mode);
      sum.mode_changes.emplace_back(line);
      previous_mode = s.mode;
    }
    const hq::console::RecordedCommand* c = command_at(r.commands, s.receipt_ns);
    const std::array<float, 3> v_cmd = c ? c->v_H_mps : std::array<float, 3>{};
    const float yaw_cmd = c ? c->yaw_rate_radps : 0.0F;
    if (std::string_view(s.mode) == "teleop" && c != nullptr) {
      for (std::size_t a = 0; a < 3; ++a) {
        const double e = s.v_H_mps[a] - v_cmd[a];
        sum.rms_tracking_mps[a] += e * e;
      }
      ++sum.tracking_samples;
    }
    if (std::isfinite(s.closest_obstacle_m)) {
      sum.closest_obstacle_m = std::isnan(sum.closest_obstacle_m)
                                   ? s.closest_obstacle_m
                                   : std::min(sum.closest_obstacle_m, s.closest_obstacle_m);
    }
    sum.max_v_obs_mps = std::max(sum.max_v_obs_mps,
                                 static_cast<double>(std::hypot(s.v_obs_H_mps[0], s.v_obs_H_mps[1], s.v_obs_H_mps[2])));
    if (s.truth_valid) {
      for (std::size_t a = 0; a < 3; ++a) {
        const double e = s.v_H_mps[a] - s.v_truth_H_mps[a];
        sum.rmse_truth_mps[a] += e * e;
      }
      ++sum.truth_samples;
    }
    sum.position_samples += s.position_valid ? 1 : 0;
    latencies.push_back(s.latency_ms);
    data << t_s << ' ' << s.v_H_mps[0] << ' ' << s.v_H_mps[1] << ' ' << s.v_H_mps[2] << ' '
         << v_cmd[0] << ' ' << v_cmd[1] << ' ' << v_cmd[2] << ' ' << s.v_obs_H_mps[0] << ' '
         << s.v_obs_H_mps[1] << ' ' << s.v_obs_H_mps[2] << ' ' << yaw_cmd << ' '
         << s.omega_body_radps[2] << ' ' << x << ' ' << y << ' '
         << (std::isfinite(s.closest_obstacle_m) ? std::to_string(s.closest_obstacle_m) : "NaN")
         << ' ' << s.latency_ms;
    // gnuplot leaves NaN points out, so absent truth or position breaks the trace there.
    for (std::size_t a = 0; a < 3; ++a) {
      data << ' ' << (s.truth_valid ? std::to_string(s.v_truth_H_mps[a]) : "NaN");
    }
    for (std::size_t a = 0; a < 2; ++a) {
      data << ' ' << (s.position_valid ? std::to_string(s.p_W_m[a]) : "NaN");
    }
    data << '\n';
  }
  data.close();
  if (!data) throw hq::InputError(data_path + ": write failed (disk full?)");
  sum.duration_s = 1e-9 * static_cast<double>(r.states.back().receipt_ns - t0_ns);
  for (double& v : sum.rms_tracking_mps) {
    v = sum.tracking_samples > 0 ? std::sqrt(v / static_cast<double>(sum.tracking_samples)) : NAN;
  }
  for (double& v : sum.rmse_truth_mps) {
    v = sum.truth_samples > 0 ? std::sqrt(v / static_cast<double>(sum.truth_samples)) : NAN;
  }
  std::sort(latencies.begin(), latencies.end());
  sum.latency_p50_ms = latencies[latencies.size() / 2];
  sum.latency_max_ms = latencies.back();
  for (const auto& e : r.events) sum.warnings += e.severity >= 1 ? 1 : 0;

  // The gnuplot script: one figure per Fig. 6-8 panel group.
  const std::string terminal = format == "png" ? "pngcairo size 1000,700" : "svg size 1000,700";
  const std::string script_path = (fs::path(out_dir) / "report.gp").string();
  {
    std::ofstream gp(script_path);
    if (!gp) throw hq::InputError(script_path + ": cannot open for writing");
    gp << "set terminal " << terminal << "\nset grid\nset key outside top center horizontal\n"
       << "d = '" << data_name << "'\n";
    gp << "set output '" << ("velocity_H." + format) << "'\n"
       << "set multiplot layout 3,1 title 'Velocity in H: estimated vs commanded"
       << (sum.truth_samples > 0 ? " vs simulator truth" : "") << " (Fig. 6-8)'\n";
    const char* axes[3] = {"x", "y", "z"};
    for (int a = 0; a < 3; ++a) {
      gp << "set ylabel 'v_" << axes[a] << " [m/s]'\n" << (a == 2 ? "set xlabel 't [s]'\n" : "")
         << "plot d u 1:" << 2 + a << " w l lw 2 t 'estimated', d u 1:" << 5 + a
         << " w l lw 2 dt 2 t 'commanded'";
      if (sum.truth_samples > 0) gp << ", d u 1:" << 17 + a << " w l lw 1 t 'truth'";
      gp << '\n';
    }
    gp << "unset multiplot\nunset xlabel\n";
    gp << "set output '" << ("v_obs." + format) << "'\n"
       << "set title 'Obstacle repulsion v_{obs} in H (Fig. 8)'\nset xlabel 't [s]'\n"
       << "set ylabel '[m/s]'\nplot d u 1:8 w l lw 2 t 'x', d u 1:9 w l lw 2 t 'y', d u 1:10 w l "
          "lw 2 t 'z'\n";
    gp << "set output '" << ("yaw_rate." + format) << "'\n"
       << "set title 'Yaw rate: commanded vs measured'\nset ylabel '[rad/s]'\n"
       << "plot d u 1:11 w l lw 2 dt 2 t 'commanded', d u 1:12 w l lw 2 t 'measured (gyro z)'\n";
    gp << "set output '" << ("latency." + format) << "'\n"
       << "set title 'Vehicle state latency (one way)'\nset ylabel '[ms]'\n"
       << "plot d u 1:16 w l t 'latency'\n";
    gp << "set output '" << ("top_view." + format) << "'\n"
       << "set title 'Top view, dead-reckoned from v_H and gyro yaw (drifts)"
       << (sum.position_samples > 0 ? "; vehicle position from the marker filter" : "") << "'\n"
       << "set size ratio -1\nset xlabel 'east y_W [m]'\nset ylabel 'north x_W [m]'\n"
       << "plot d u 14:13 w l lw 2 t 'track (dead-reckoned)', d u (column(14)):(column(13)) "
          "every ::0::0 w p pt 7 ps 2 t 'start'";
    if (sum.position_samples > 0) gp << ", d u 21:20 w p pt 7 ps 0.4 t 'vehicle position p_W'";
    gp << '\n';
  }
  const int rc = run_in({"gnuplot", "report.gp"}, out_dir, "gnuplot.log");
  if (rc != 0) {
    throw hq::InputError(script_path + ": gnuplot failed (exit " + std::to_string(rc) + "), see " +
                         (fs::path(out_dir) / "gnuplot.log").string());
  }

  const std::string md_path = (fs::path(out_dir) / "report.md").string();
  std::FILE* md = std::fopen(md_path.c_str(), "w");
  if (md == nullptr) throw hq::InputError(md_path + ": cannot open for writing");
  std::fprintf(md, "# Flight report: %s\n\n", dir.c_str());
  std::fprintf(md, "| figure | value |\n| --- | --- |\n");
  std::fprintf(md, "| duration | %.1f s, %zu states, %zu commands, %zu camera frames |\n",
               sum.duration_s, r.states.size(), r.commands.size(), r.rgb.size());
  std::fprintf(md, "| tracking error RMS (teleop, v_est - v_cmd in H) | x %.3f, y %.3f, z %.3f m/s "
                   "over %zu states |\n",
               sum.rms_tracking_mps[0], sum.rms_tracking_mps[1], sum.rms_tracking_mps[2],
               sum.tracking_samples);
  if (sum.truth_samples > 0) {
    std::fprintf(md, "| velocity estimate RMSE vs truth (simulator, v_est - v_truth in H) | x "
                     "%.3f, y %.3f, z %.3f m/s over %zu states |\n",
                 sum.rmse_truth_mps[0], sum.rmse_truth_mps[1], sum.rmse_truth_mps[2],
                 sum.truth_samples);
  } else {
    std::fprintf(md, "| velocity estimate RMSE vs truth | no truth in this recording |\n");
  }
  if (std::isnan(sum.closest_obstacle_m)) {
    std::fprintf(md, "| closest obstacle | unknown (no obstacle cloud sent) |\n");
  } else {
    std::fprintf(md, "| closest obstacle | %.2f m |\n", sum.closest_obstacle_m);
  }
  std::fprintf(md, "| largest v_obs | %.3f m/s |\n", sum.max_v_obs_mps);
  std::fprintf(md, "| mode changes | %zu: %s |\n", sum.mode_changes.size() - 1,
               [&] {
                 std::string all;
                 for (const std::string& m : sum.mode_changes) all += (all.empty() ? "" : "; ") + m;
                 return all;
               }().c_str());
  std::fprintf(md, "| link incidents | %zu states missing, largest gap %.0f ms, %zu warning/error "
                   "events, %zu unreadable recording lines |\n",
               sum.sequence_gaps, 1e3 * sum.max_state_gap_s, sum.warnings, r.problem_count);
  std::fprintf(md, "| latency (one way) | p50 %.2f ms, max %.2f ms |\n\n", sum.latency_p50_ms,
               sum.latency_max_ms);
  for (const char* name : {"velocity_H", "v_obs", "yaw_rate", "top_view", "latency"}) {
    std::fprintf(md, "![%s](%s.%s)\n\n", name, name, format.c_str());
  }
  if (!r.absent_columns.empty()) {
    std::fprintf(md, "## Columns absent (older recording layout)\n\n");
    for (const std::string& c : r.absent_columns) std::fprintf(md, "- %s\n", c.c_str());
    std::fprintf(md, "\n");
  }
  if (!r.problems.empty()) {
    std::fprintf(md, "## Recording problems\n\n");
    for (const std::string& p : r.problems) std::fprintf(md, "- %s\n", p.c_str());
  }
  std::fclose(md);
  std::printf("hq-report: %s (figures %s in %s)\n", md_path.c_str(), format.c_str(),
              out_dir.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-report", argc, argv, run); }
