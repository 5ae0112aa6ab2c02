// hq-report: the flight report of a recording made by hq-ground --record. Plots in the manner
// of Fig. 6-8 of the core paper (velocity in H estimated vs commanded per axis, and vs simulator
// truth when recorded; v_obs; yaw rate commanded vs measured), the dead-reckoned top view with
// the vehicle's own position where it sent one and the summary figures (tracking error,
// closest obstacle, mode changes, link incidents), drawn by Debian's gnuplot run as a
// subprocess on a generated script, plus report.md linking them. No shell is involved and no
// path reaches gnuplot's script: gnuplot is spawned with an argument vector in the output
// folder, and the script names only the fixed file names there.
// The recording is a flight record (a .mcap, or a folder's flight.mcap) or, without one, the
// CSV files of older recordings (hq::console::load_recording). Two more jobs on flight records:
// --csv exports the CSV files gnuplot users had (hq::ground::TelemetryRecorder writes them, so
// the columns are the recorder's own), --recover rewrites a file whose writer was killed into a
// complete indexed one.
//   hq-report <recording-dir | flight.mcap> [--out DIR] [--format png|svg]
//   hq-report <recording-dir | flight.mcap> --csv OUT_DIR
//   hq-report --recover IN.mcap OUT.mcap
#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/base/log.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/base/program.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/console/flight_mcap.hpp"
#include "hq/console/flight_report.hpp"
#include "hq/console/recording.hpp"
#include "hq/ground/ground_station.hpp"
#include "hq/mcap/mcap.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <spawn.h>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

extern char** environ;

namespace {

namespace fs = std::filesystem;

struct Summary {
  double duration_s = 0;
  std::array<double, 3> rms_tracking_mps{};  ///< |v_est - v_cmd| per axis of H, teleop only.
  std::size_t tracking_samples = 0;
  double max_v_obs_mps = 0;
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

// gnuplot objects behind every time plot, as on the replay's scrub bar: the vehicle's mode
// bands (none where no state came for over a second), event marks (ticks at the top, coloured by
// severity) and vehicle restarts (red lines).
std::string band_script(const hq::console::Timeline& t) {
  const auto colour = [](std::string_view mode) {
    if (mode == "teleop") return "#3ca050";
    if (mode == "hover") return "#3c6ebe";
    if (mode == "land") return "#d28228";
    if (mode == "marker") return "#9650b4";
    if (mode == "explore") return "#28a0a0";
    return "#5a5a5a";
  };
  std::string gp;
  char line[256];
  int object = 1;
  for (const hq::console::ModeBand& b : t.bands) {
    hq::format_into(line,
                    "set object {} rect from {:.3f}, graph 0 to {:.3f}, graph 1 fc rgb '{}' fs "
                    "transparent solid 0.12 noborder behind\n",
                    object++, b.start_s, std::max(b.end_s, b.start_s + 1e-3), colour(b.mode));
    gp += line;
  }
  int arrow = 1;
  for (const hq::console::EventMark& e : t.marks) {
    hq::format_into(
        line, "set arrow {} from {:.3f}, graph 0.92 to {:.3f}, graph 1 nohead lw 2 lc rgb '{}'\n",
        arrow++, e.t_s, e.t_s,
        e.severity >= 2   ? "#e03030"
        : e.severity == 1 ? "#e0a000"
                          : "#808080");
    gp += line;
  }
  for (std::size_t i = 1; i < t.sessions.size(); ++i) {
    hq::format_into(
        line,
        "set arrow {} from {:.3f}, graph 0 to {:.3f}, graph 1 nohead lw 3 lc rgb '#ff0000'\nset "
        "label {} 'vehicle restarted' at {:.3f}, graph 0.85 tc rgb '#ff0000'\n",
        arrow++, t.sessions[i].t_s, t.sessions[i].t_s, i, t.sessions[i].t_s);
    gp += line;
  }
  return gp;
}

std::string number_or_nan(double v) {
  if (!std::isfinite(v)) return "NaN";
  char text[32];
  hq::format_into(text, "{:.4f}", v);
  return text;
}

struct Options {
  std::string recording;
  std::string out_dir;
  std::string format = "png";
  std::string csv_dir;
  std::vector<std::string> recover;  ///< IN.mcap OUT.mcap
};

constexpr const char* kUsage =
    "usage: hq-report <recording-dir | flight.mcap> [--out DIR] [--format png|svg] | "
    "<recording-dir | flight.mcap> --csv OUT_DIR | --recover IN.mcap OUT.mcap";

// Returns an exit code when parsing ends the run (--help, a bad argument).
std::optional<int> parse_options(int argc, char** argv, Options& o) {
  CLI::App app{"hq-report: flight report of an hq-ground recording"};
  app.add_option("recording", o.recording,
                 "recording: a folder (hq-ground --record) or its flight.mcap");
  app.add_option("--out", o.out_dir, "output directory (default: <recording>/report)");
  app.add_option("--format", o.format, "figure format")->check(CLI::IsMember({"png", "svg"}));
  app.add_option("--csv", o.csv_dir,
                 "export the flight record as the CSV files of hq-ground --record into this new "
                 "folder (no report)");
  app.add_option("--recover", o.recover,
                 "rewrite IN.mcap (a writer killed: no summary) into a complete OUT.mcap")
      ->expected(2);
  if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;
  if (o.recover.empty() && o.recording.empty()) {
    throw hq::InputError(std::string("no recording given (") + kUsage + ")");
  }
  return std::nullopt;
}

// Loads the recording, prints what could not be read, and refuses one without states.
hq::console::Recording load_checked(const std::string& path) {
  hq::console::Recording r;
  try {
    r = hq::console::load_recording(path);
  } catch (const hq::InputError& e) {
    throw hq::InputError(std::string(e.what()) + " (" + kUsage + ")");
  }
  for (const std::string& p : r.problems) hq::log::note("hq-report: {}\n", p.c_str());
  for (const std::string& c : r.absent_columns) {
    hq::log::note("hq-report: column absent (older layout): {}\n", c.c_str());
  }
  if (r.states.empty()) {
    throw hq::InputError(
        (r.from_mcap ? r.directory + ": /hq/vehicle_state" : path + "/telemetry.csv") +
        ": no readable vehicle state, nothing to report");
  }
  return r;
}

// Adds one state's contribution to the summary figures.
void accumulate(const hq::console::RecordedState& s, const hq::console::RecordedCommand* c,
                Summary& sum) {
  if (std::string_view(s.mode) == "teleop" && c != nullptr) {
    for (std::size_t a = 0; a < 3; ++a) {
      const double e = s.v_H_mps[a] - c->v_H_mps[a];
      sum.rms_tracking_mps[a] += e * e;
    }
    ++sum.tracking_samples;
  }
  sum.max_v_obs_mps = std::max(
      sum.max_v_obs_mps,
      static_cast<double>(std::hypot(s.v_obs_H_mps[0], s.v_obs_H_mps[1], s.v_obs_H_mps[2])));
  if (s.truth_valid) {
    for (std::size_t a = 0; a < 3; ++a) {
      const double e = s.v_H_mps[a] - s.v_truth_H_mps[a];
      sum.rmse_truth_mps[a] += e * e;
    }
    ++sum.truth_samples;
  }
  sum.position_samples += s.position_valid ? 1 : 0;
}

void finish(Summary& sum) {
  for (double& v : sum.rms_tracking_mps) {
    v = sum.tracking_samples > 0 ? std::sqrt(v / static_cast<double>(sum.tracking_samples))
                                 : std::numeric_limits<double>::quiet_NaN();
  }
  for (double& v : sum.rmse_truth_mps) {
    v = sum.truth_samples > 0 ? std::sqrt(v / static_cast<double>(sum.truth_samples))
                              : std::numeric_limits<double>::quiet_NaN();
  }
}

// Dead reckoning as the console's top view: p_W += R_z(yaw) v_H dt; a new vehicle session
// starts its own track from its own start.
struct DeadReckoning {
  double yaw = 0;
  double x = 0;
  double y = 0;
  void step(const hq::console::RecordedState& s, double dt_s) {
    yaw += static_cast<double>(s.omega_B_radps[2]) * dt_s;
    const auto vx = static_cast<double>(s.v_H_mps[0]);
    const auto vy = static_cast<double>(s.v_H_mps[1]);
    x += (std::cos(yaw) * vx - std::sin(yaw) * vy) * dt_s;
    y += (std::sin(yaw) * vx + std::cos(yaw) * vy) * dt_s;
  }
};

void write_data_row(std::ofstream& data, double t_s, const hq::console::RecordedState& s,
                    const hq::console::RecordedCommand* c, const DeadReckoning& track,
                    std::size_t session) {
  const std::array<float, 3> v_cmd = c ? c->v_H_mps : std::array<float, 3>{};
  const float yaw_cmd = c ? c->yaw_rate_radps : 0.0F;
  data << t_s << ' ' << s.v_H_mps[0] << ' ' << s.v_H_mps[1] << ' ' << s.v_H_mps[2] << ' '
       << v_cmd[0] << ' ' << v_cmd[1] << ' ' << v_cmd[2] << ' ' << s.v_obs_H_mps[0] << ' '
       << s.v_obs_H_mps[1] << ' ' << s.v_obs_H_mps[2] << ' ' << yaw_cmd << ' ' << s.omega_B_radps[2]
       << ' ' << track.x << ' ' << track.y << ' ' << number_or_nan(s.closest_obstacle_m) << ' '
       << s.latency_ms;
  // gnuplot leaves NaN points out, so absent truth or position breaks the trace there.
  for (std::size_t a = 0; a < 3; ++a) {
    data << ' ' << (s.truth_valid ? std::to_string(s.v_truth_H_mps[a]) : "NaN");
  }
  for (std::size_t a = 0; a < 2; ++a) {
    data << ' ' << (s.position_valid ? std::to_string(s.p_W_m[a]) : "NaN");
  }
  data << ' ' << number_or_nan(s.height_m) << ' ' << number_or_nan(s.clearance_m) << ' ' << session
       << '\n';
}

// One data file for gnuplot: a blank line between vehicle sessions breaks every trace there
// (a restarted vehicle's track is not joined to its predecessor's). Times on the replay's
// timeline (from the recording's earliest stamp), so that the page and hq-ground --replay name
// the same instant alike. Returns the summary figures over the states.
Summary write_data_file(const hq::console::Recording& r, const hq::console::ReportFigures& fig,
                        const std::string& data_path) {
  const std::int64_t t0_ns = fig.timeline.t0_ns;
  std::ofstream data(data_path);
  if (!data) throw hq::InputError(data_path + ": cannot open for writing");
  data << "# t_s v_est_x v_est_y v_est_z v_cmd_x v_cmd_y v_cmd_z v_obs_x v_obs_y v_obs_z "
          "yaw_cmd yaw_meas x_W y_W cloud_nearest_m latency_ms v_truth_x v_truth_y v_truth_z "
          "p_W_x p_W_y height_m clearance_m session (NaN: absent)\n";
  Summary sum;
  DeadReckoning track;
  std::size_t session = 0;
  for (std::size_t i = 0; i < r.states.size(); ++i) {
    const hq::console::RecordedState& s = r.states[i];
    const bool new_session =
        session + 1 < fig.sessions.size() &&
        s.receipt_ns - t0_ns >=
            static_cast<std::int64_t>(std::llround(fig.sessions[session + 1].start_s * 1e9));
    if (new_session) {
      ++session;
      track = {};
      data << '\n';
    } else if (i > 0) {
      // A gap of more than a second is not bridged.
      track.step(s, std::min(hq::to_seconds(s.receipt_ns - r.states[i - 1].receipt_ns), 1.0));
    }
    const hq::console::RecordedCommand* c = command_at(r.commands, s.receipt_ns);
    accumulate(s, c, sum);
    write_data_row(data, hq::to_seconds(s.receipt_ns - t0_ns), s, c, track, session);
  }
  data.close();
  if (!data) throw hq::InputError(data_path + ": write failed (disk full?)");
  finish(sum);
  return sum;
}

const char* const kFigures[] = {"velocity_H", "v_obs",   "yaw_rate", "height",
                                "clearance",  "latency", "top_view"};

// gnuplot refuses a plot whose points are all undefined: an empty frame that says so.
constexpr const char* kNoData =
    "set label 99 'not in this recording' at graph 0.4, graph 0.5\nset yrange [0:1]\n"
    "plot -1 notitle\nunset label 99\nset autoscale y\n";

void write_time_plots(std::ofstream& gp, const std::string& format,
                      const hq::console::ReportFigures& fig, const Summary& sum) {
  const bool have_clearance = std::isfinite(fig.closest_clearance_m);
  const bool have_height = fig.height_states > 0;
  const bool have_cloud = std::isfinite(fig.closest_cloud_point_m);
  gp << "set output '" << ("velocity_H." + format) << "'\n"
     << "set multiplot layout 3,1 title 'Velocity in H: estimated vs commanded"
     << (sum.truth_samples > 0 ? " vs simulator truth" : "") << " (Fig. 6-8)'\n";
  const char* axes[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    gp << "set ylabel 'v_" << axes[a] << " [m/s]'\n"
       << (a == 2 ? "set xlabel 't [s]'\n" : "") << "plot d u 1:" << 2 + a
       << " w l lw 2 t 'estimated', d u 1:" << 5 + a << " w l lw 2 dt 2 t 'commanded'";
    if (sum.truth_samples > 0) gp << ", d u 1:" << 17 + a << " w l lw 1 t 'truth'";
    gp << '\n';
  }
  gp << "unset multiplot\n";
  gp << "set output '" << ("v_obs." + format) << "'\n"
     << "set title 'Obstacle repulsion v_{obs} in H (Fig. 8)'\nset xlabel 't [s]'\n"
     << "set ylabel '[m/s]'\nplot d u 1:8 w l lw 2 t 'x', d u 1:9 w l lw 2 t 'y', d u 1:10 w l "
        "lw 2 t 'z'\n";
  gp << "set output '" << ("yaw_rate." + format) << "'\n"
     << "set title 'Yaw rate: commanded vs measured'\nset ylabel '[rad/s]'\n"
     << "plot d u 1:11 w l lw 2 dt 2 t 'commanded', d u 1:12 w l lw 2 t 'measured (gyro z)'\n";
  gp << "set output '" << ("height." + format) << "'\n"
     << "set title 'Height above the floor (vehicle)" << (have_height ? "" : ": not recorded")
     << "'\nset ylabel '[m]'\n"
     << (have_height ? "plot d u 1:22 w l lw 2 t 'height_m'\n" : kNoData);
  gp << "set output '" << ("clearance." + format) << "'\n"
     << "set title 'Closest obstacle'\nset ylabel '[m]'\n"
     << (have_clearance && have_cloud
             ? "plot d u 1:23 w l lw 2 t 'clearance (vehicle)', d u 1:15 w p pt 7 ps 0.3 t "
               "'nearest cloud point from the body origin'\n"
         : have_clearance ? "plot d u 1:23 w l lw 2 t 'clearance (vehicle)'\n"
         : have_cloud     ? "plot d u 1:15 w p pt 7 ps 0.3 t 'nearest cloud point from the body "
                            "origin (the vehicle sent no clearance)'\n"
                          : kNoData);
  gp << "set output '" << ("latency." + format) << "'\n"
     << "set title 'Vehicle state latency (one way)'\nset ylabel '[ms]'\n"
     << "plot d u 1:16 w l t 'latency'\n";
}

void write_top_view(std::ofstream& gp, const std::string& format, const Summary& sum) {
  gp << "unset object\nunset arrow\nunset label\nset autoscale x\nunset xrange\n";
  gp << "set output '" << ("top_view." + format)
     << "'\n"
     // Two lines (a gnuplot double-quoted "\\n"): on one, the square plot's narrow canvas
     // cut the title off at both ends.
     << "set title \"Top view, dead-reckoned from v_H and gyro yaw (drifts)\\none track per "
        "vehicle session"
     << (sum.position_samples > 0 ? "; vehicle position from the marker filter" : "") << "\"\n"
     << "set size ratio -1\nset xlabel 'east y_W [m]'\nset ylabel 'north x_W [m]'\n"
     << "set autoscale\n"
     << "plot d u 14:13 w l lw 2 t 'track (dead-reckoned)', d u (column(14)):(column(13)) "
        "every ::0::0 w p pt 7 ps 2 t 'start'";
  if (sum.position_samples > 0) gp << ", d u 21:20 w p pt 7 ps 0.4 t 'vehicle position p_W'";
  gp << '\n';
}

// The gnuplot script (time plots over the mode bands, event marks and restarts; the top view)
// run in out_dir.
void draw_figures(const std::string& out_dir, const std::string& format,
                  const std::string& data_name, const hq::console::ReportFigures& fig,
                  const Summary& sum) {
  const std::string terminal = format == "png" ? "pngcairo size 1000,700" : "svg size 1000,700";
  const std::string script_path = (fs::path(out_dir) / "report.gp").string();
  {
    std::ofstream gp(script_path);
    if (!gp) throw hq::InputError(script_path + ": cannot open for writing");
    gp << "set terminal " << terminal << "\nset grid\nset key outside top center horizontal\n"
       << "d = '" << data_name << "'\nset xrange [0:" << std::max(fig.timeline.duration_s, 1e-3)
       << "]\n"
       << "# Mode bands (teleop green, hover blue, land orange, marker purple, explore teal),\n"
       << "# event ticks (grey info, amber warning, red error), vehicle restarts (red).\n"
       << band_script(fig.timeline);
    write_time_plots(gp, format, fig, sum);
    write_top_view(gp, format, sum);
  }
  const int rc = run_in({"gnuplot", "report.gp"}, out_dir, "gnuplot.log");
  if (rc != 0) {
    throw hq::InputError(script_path + ": gnuplot failed (exit " + std::to_string(rc) + "), see " +
                         (fs::path(out_dir) / "gnuplot.log").string());
  }
}

using Rows = std::vector<std::pair<std::string, std::string>>;

template <typename... Values>
void add_row(Rows& rows, const char* name, fmt::format_string<Values...> format_text,
             Values&&... values) {
  rows.emplace_back(name, fmt::format(format_text, std::forward<Values>(values)...));
}

std::string sessions_text(const hq::console::ReportFigures& fig) {
  std::string list;
  for (std::size_t i = 0; i < fig.sessions.size(); ++i) {
    const hq::console::SessionFigures& s = fig.sessions[i];
    fmt::format_to(
        std::back_inserter(list),
        "{}{} {}: {:.1f}-{:.1f} s, {} states, {:.1f} s on the vehicle's clock, {} lost{}",
        list.empty() ? "" : "; ", i == 0 ? "session" : "vehicle restarted, session", i + 1,
        s.start_s, s.end_s, s.states, s.vehicle_duration_s, s.states_lost,
        s.session_id != 0 ? "" : " (no session id)");
  }
  return std::to_string(fig.sessions.size()) + ": " + list;
}

std::string mode_changes_text(const hq::console::ReportFigures& fig) {
  std::string list;
  for (const hq::console::ModeChange& c : fig.mode_changes) {
    fmt::format_to(std::back_inserter(list), "{}{:.2f} s: {} -> {}", list.empty() ? "" : "; ",
                   c.t_s, c.from, c.to);
  }
  return fmt::format("{} (initial mode {}){}{}", fig.mode_changes.size(), fig.initial_mode,
                     list.empty() ? "" : ": ", list);
}

std::string link_incidents_text(const hq::console::ReportFigures& fig, std::size_t problems) {
  std::string lost;
  for (const double t_s : fig.link_lost_events_s) {
    fmt::format_to(std::back_inserter(lost), "{}{:.1f} s", lost.empty() ? "" : ", ", t_s);
  }
  return fmt::format(
      "{} states lost (within sessions), largest gap {:.0f} ms at {:.1f} s, {} "
      "ground-heartbeat-lost event(s){}{}, {} warning/error events, {} unreadable recording lines",
      fig.states_lost, 1e3 * fig.largest_gap_s, fig.largest_gap_at_s, fig.link_lost_events_s.size(),
      lost.empty() ? "" : " at ", lost, fig.warnings, problems);
}

void add_obstacle_rows(Rows& rows, const hq::console::ReportFigures& fig) {
  if (std::isfinite(fig.closest_clearance_m)) {
    add_row(rows, "closest obstacle (vehicle's clearance)", "{:.3f} m at {:.1f} s",
            fig.closest_clearance_m, fig.closest_clearance_at_s);
  } else {
    rows.emplace_back("closest obstacle (vehicle's clearance)",
                      "not recorded (the vehicle sent no clearance)");
  }
  if (std::isfinite(fig.closest_cloud_point_m)) {
    add_row(rows, "nearest cloud point from the body origin (not a clearance)", "{:.3f} m",
            fig.closest_cloud_point_m);
  }
  if (fig.height_states > 0) {
    add_row(rows, "height above the floor", "max {:.2f} m over {} states", fig.max_height_m,
            fig.height_states);
  } else {
    rows.emplace_back("height above the floor", "not recorded");
  }
}

// The page's rows, the same in Markdown and HTML.
Rows report_rows(const hq::console::Recording& r, const hq::console::ReportFigures& fig,
                 const Summary& sum) {
  Rows rows;
  add_row(rows, "duration",
          "{:.1f} s (ground receipt, first to last state), {} states, {} commands, {} camera "
          "frames",
          fig.duration_s, r.states.size(), r.commands.size(), r.rgb.size());
  rows.emplace_back("vehicle sessions (restarts)", sessions_text(fig));
  add_row(rows, "tracking error RMS (teleop, v_est - v_cmd in H)",
          "x {:.3f}, y {:.3f}, z {:.3f} m/s over {} states", sum.rms_tracking_mps[0],
          sum.rms_tracking_mps[1], sum.rms_tracking_mps[2], sum.tracking_samples);
  if (sum.truth_samples > 0) {
    add_row(rows, "velocity estimate RMSE vs truth (simulator, v_est - v_truth in H)",
            "x {:.3f}, y {:.3f}, z {:.3f} m/s over {} states", sum.rmse_truth_mps[0],
            sum.rmse_truth_mps[1], sum.rmse_truth_mps[2], sum.truth_samples);
  } else {
    rows.emplace_back("velocity estimate RMSE vs truth", "no truth in this recording");
  }
  add_obstacle_rows(rows, fig);
  add_row(rows, "largest v_obs", "{:.3f} m/s", sum.max_v_obs_mps);
  rows.emplace_back("mode changes", mode_changes_text(fig));
  rows.emplace_back("link incidents", link_incidents_text(fig, r.problem_count));
  add_row(rows, "latency (one way)", "p50 {:.2f} ms, p99 {:.2f} ms, max {:.2f} ms",
          fig.latency_p50_ms, fig.latency_p99_ms, fig.latency_max_ms);
  return rows;
}

void write_markdown(const std::string& md_path, const std::string& title,
                    const hq::console::Recording& r, const Rows& rows, const std::string& format) {
  std::FILE* md = std::fopen(md_path.c_str(), "w");
  if (md == nullptr) throw hq::InputError(md_path + ": cannot open for writing");
  fmt::print(md, "# Flight report: {}\n\n", title.c_str());
  fmt::print(md, "| figure | value |\n| --- | --- |\n");
  for (const auto& [name, value] : rows) {
    fmt::print(md, "| {} | {} |\n", name.c_str(), value.c_str());
  }
  fmt::print(md,
             "\nPlots: mode bands behind the traces (teleop green, hover blue, land "
             "orange, marker purple, explore teal), event ticks at the top (grey info, "
             "amber warning, red error), vehicle restarts as red lines.\n\n");
  for (const char* name : kFigures) fmt::print(md, "![{}]({}.{})\n\n", name, name, format.c_str());
  if (!r.absent_columns.empty()) {
    fmt::print(md, "## Columns absent (older recording layout)\n\n");
    for (const std::string& c : r.absent_columns) fmt::print(md, "- {}\n", c.c_str());
    fmt::print(md, "\n");
  }
  if (!r.problems.empty()) {
    fmt::print(md, "## Recording problems\n\n");
    for (const std::string& p : r.problems) fmt::print(md, "- {}\n", p.c_str());
  }
  if (std::fclose(md) != 0) throw hq::InputError(md_path + ": write failed");
}

std::string html_escape(const std::string& in) {
  std::string out;
  for (const char ch : in) {
    if (ch == '<') {
      out += "&lt;";
    } else if (ch == '>') {
      out += "&gt;";
    } else if (ch == '&') {
      out += "&amp;";
    } else {
      out += ch;
    }
  }
  return out;
}

// The same table and figures, one page to open in a browser.
void write_html(const std::string& html_path, const std::string& title, const Rows& rows,
                const std::string& format) {
  std::ofstream html(html_path);
  html << "<!doctype html><html><head><meta charset='utf-8'><title>Flight report</title>"
          "<style>body{font-family:sans-serif;max-width:1050px;margin:auto}td,th{border:1px solid "
          "#ccc;padding:4px}table{border-collapse:collapse}</style></head><body>\n<h1>Flight "
          "report: "
       << html_escape(title) << "</h1>\n<table><tr><th>figure</th><th>value</th></tr>\n";
  for (const auto& [name, value] : rows) {
    html << "<tr><td>" << html_escape(name) << "</td><td>" << html_escape(value) << "</td></tr>\n";
  }
  html << "</table>\n";
  for (const char* name : kFigures) {
    html << "<p><img src='" << name << "." << format << "' alt='" << name << "'></p>\n";
  }
  html << "</body></html>\n";
  html.close();
  if (!html) throw hq::InputError(html_path + ": write failed");
}

int write_report(const Options& o) {
  const hq::console::Recording r = load_checked(o.recording);
  const std::string out_dir = !o.out_dir.empty() ? o.out_dir
                              : fs::is_regular_file(o.recording)
                                  ? (fs::path(o.recording).parent_path() / "report").string()
                                  : (fs::path(o.recording) / "report").string();
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) throw hq::InputError("--out " + out_dir + ": cannot create: " + ec.message());
  const hq::console::ReportFigures fig = hq::console::compute_report(r);
  const std::string data_name = "flight.dat";
  const Summary sum = write_data_file(r, fig, (fs::path(out_dir) / data_name).string());
  draw_figures(out_dir, o.format, data_name, fig, sum);
  const Rows rows = report_rows(r, fig, sum);
  const std::string md_path = (fs::path(out_dir) / "report.md").string();
  write_markdown(md_path, o.recording, r, rows, o.format);
  write_html((fs::path(out_dir) / "report.html").string(), o.recording, rows, o.format);
  hq::log::info("hq-report: {} (and report.html; figures {} in {}; read from {})\n",
                md_path.c_str(), o.format.c_str(), out_dir.c_str(),
                r.from_mcap ? r.directory.c_str() : "the CSV files");
  return 0;
}

// The flight record's samples written by the CSV recorder itself: the columns are its own.
class CsvExport : public hq::console::FlightSampleSink {
 public:
  explicit CsvExport(const std::string& dir) : recorder_(dir) {}
  void on_state(std::int64_t log_ns, std::int64_t publish_ns,
                const hq::link::VehicleState& s) override {
    recorder_.state(log_ns, log_ns - publish_ns, s, state_age_ns_, round_trip_ns_);
  }
  // The ground's figures at its latest tick before a state stand for that state's, as replay
  // takes them (recording_mcap.cpp).
  void on_ground_link(std::int64_t /*t_ns*/, float state_age_ms, float round_trip_ms) override {
    state_age_ns_ = std::llround(1e6 * static_cast<double>(state_age_ms));
    round_trip_ns_ = std::llround(1e6 * static_cast<double>(round_trip_ms));
  }
  void on_camera(std::int64_t log_ns, const hq::link::CameraFrame& f) override {
    recorder_.camera(log_ns, f);
  }
  void on_event(std::int64_t log_ns, const hq::link::Event& e) override {
    recorder_.event(log_ns, e);
  }
  void on_mode_request(std::int64_t log_ns, const hq::link::ModeRequest& m) override {
    recorder_.mode_request(log_ns, m.requested_mode);
  }
  void on_command(std::int64_t t_ns, bool valid, const std::array<float, 3>& v_H_mps,
                  float yaw_rate_radps) override {
    hq::haptics::VelocityCommand c;
    c.v_H_mps = {v_H_mps[0], v_H_mps[1], v_H_mps[2]};
    c.yaw_rate_radps = yaw_rate_radps;
    recorder_.command(t_ns, c, valid);
  }
  void on_problem(const std::string& text) override {
    hq::log::note("hq-report: {}\n", text.c_str());
  }
  hq::ground::TelemetryRecorder& recorder() { return recorder_; }

 private:
  hq::ground::TelemetryRecorder recorder_;
  std::int64_t state_age_ns_ = -1;
  std::int64_t round_trip_ns_ = -1;
};

// What a damaged file cost, on stderr: each warning names the file and the offset.
void print_damage(const hq::mcap::ReadReport& r) {
  for (const std::string& w : r.warnings) hq::log::warn("hq-report: warning: {}\n", w.c_str());
  if (!r.damaged()) return;
  hq::log::warn(
      "hq-report: warning: damaged file: {} chunks dropped ({} messages{}), {} "
      "records and {} bytes skipped; the rest is kept\n",
      static_cast<unsigned long long>(r.chunks_dropped),
      static_cast<unsigned long long>(r.messages_dropped),
      r.chunks_dropped_uncounted > 0 ? " or more" : "",
      static_cast<unsigned long long>(r.records_skipped),
      static_cast<unsigned long long>(r.bytes_skipped));
}

int export_csv(const Options& o) {
  const std::string mcap_path = hq::console::find_flight_mcap(o.recording);
  if (mcap_path.empty()) {
    throw hq::InputError(o.recording +
                         ": no flight.mcap to export (--csv reads a flight record; "
                         "a CSV recording is already CSV)");
  }
  const hq::mcap::McapReader reader(mcap_path);
  print_damage(reader.report());
  CsvExport out(o.csv_dir);
  const hq::console::FlightCounts n = hq::console::read_flight(reader, mcap_path, out);
  if (!out.recorder().close()) throw hq::InputError("--csv: " + out.recorder().error());
  hq::log::info(
      "hq-report: {} -> {}: {} states, {} commands, {} mode requests, {} events, "
      "{} camera frames{}\n",
      mcap_path.c_str(), o.csv_dir.c_str(), n.states, n.commands, n.mode_requests, n.events,
      n.frames, reader.report().has_summary ? "" : " (no summary: recovered by scanning)");
  return n.undecodable == 0 ? 0 : 1;
}

int recover_file(const Options& o) {
  const hq::mcap::RecoveryReport r = hq::mcap::recover(o.recover[0], o.recover[1]);
  print_damage(r.read);
  hq::log::info("hq-report: {} -> {}: {}\n", o.recover[0].c_str(), o.recover[1].c_str(),
                r.read.has_summary ? "had a summary already (rewritten as it was)"
                                   : "no summary (writer killed?), recovered by scanning");
  hq::log::info("  messages   {} recovered, {} channels, {} attachments, {} metadata\n",
                r.written.message_count, r.written.channel_count, r.written.attachment_count,
                r.written.metadata_count);
  hq::log::info("  time span  {:.3f} s (log time {} .. {} ns)\n",
                hq::to_seconds(r.last_log_time_ns - r.first_log_time_ns), r.first_log_time_ns,
                r.last_log_time_ns);
  hq::log::info(
      "  dropped    {} bytes at the tail (an incomplete record){}\n", r.bytes_dropped,
      r.messages_without_channel > 0
          ? fmt::format(", {} messages without a channel record", r.messages_without_channel)
          : std::string());
  if (r.read.damaged()) {
    hq::log::info(
        "  damaged    {} chunks dropped ({}{} messages), {} records and {} bytes skipped\n",
        r.read.chunks_dropped, r.read.messages_dropped,
        r.read.chunks_dropped_uncounted > 0 ? " or more" : "", r.read.records_skipped,
        r.read.bytes_skipped);
  }
  hq::log::info("  written    {} bytes, {} chunks, with summary and indexes\n", r.bytes_written,
                r.written.chunk_count);
  return 0;
}

int run(int argc, char** argv) {
  Options o;
  if (const std::optional<int> exit_code = parse_options(argc, argv, o)) return *exit_code;
  if (!o.recover.empty()) return recover_file(o);
  if (!o.csv_dir.empty()) return export_csv(o);
  return write_report(o);
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-report", argc, argv, run); }
