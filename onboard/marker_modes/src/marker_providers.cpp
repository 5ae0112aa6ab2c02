#include "hq/marker_modes/marker_providers.hpp"

#include "hq/base/format_into.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>

namespace hq::marker_modes {
namespace {

constexpr double kPi = 3.14159265358979323846;

double wrap_rad(double a) { return std::remainder(a, 2.0 * kPi); }

modes::ModeCommand invalid(const char* reason) {
  modes::ModeCommand c;
  c.valid = false;
  c.reason = reason;
  return c;
}

/// v_W clipped to max_speed_mps, turned into H (v_H = R_WH^T v_W).
Eigen::Vector3d to_horizontal(const Eigen::Vector3d& v_W_mps, double yaw_rad,
                              double max_speed_mps) {
  Eigen::Vector3d v = v_W_mps;
  const double speed = v.norm();
  if (speed > max_speed_mps) v *= max_speed_mps / speed;
  return Eigen::AngleAxisd(-yaw_rad, Eigen::Vector3d::UnitZ()) * v;
}

double yaw_rate_towards(double yaw_target_rad, double yaw_rad, double kp, double max_radps) {
  return std::clamp(kp * wrap_rad(yaw_target_rad - yaw_rad), -max_radps, max_radps);
}

}  // namespace

const char* to_string(MarkerTask task) {
  switch (task) {
    case MarkerTask::kHold:
      return "hold";
    case MarkerTask::kGoTo:
      return "goto";
    case MarkerTask::kLand:
      return "land";
  }
  return "?";
}

const char* to_string(ExplorePhase phase) {
  switch (phase) {
    case ExplorePhase::kLiftOff:
      return "liftoff";
    case ExplorePhase::kSearch:
      return "search";
    case ExplorePhase::kExplore:
      return "explore";
    case ExplorePhase::kEdge:
      return "edge";
    case ExplorePhase::kNavigate:
      return "navigate";
    case ExplorePhase::kLand:
      return "land";
    case ExplorePhase::kDone:
      return "done";
  }
  return "?";
}

MarkerModeProvider::MarkerModeProvider(const MarkerModeConfig& config,
                                       const MarkerNavigation& navigation)
    : config_(config), navigation_(navigation), marker_id_(config.target_id) {}

void MarkerModeProvider::set_task(MarkerTask task, int marker_id) {
  task_ = task;
  marker_id_ = marker_id;
  descending_ = false;
  wants_land_ = false;
}

modes::ModeCommand MarkerModeProvider::desired(std::int64_t t_ns) {
  // A gap in the calls means the mode was (re-)entered: hold the heading it finds.
  if (t_ns - t_last_ns_ > 200'000'000) have_yaw_ = false;
  t_last_ns_ = t_ns;
  // Never flown on an invalid pose: the controller hovers on the velocity estimate instead,
  // and this provider resumes by itself once the pose is valid again (MarkerStage says so).
  if (!navigation_.pose_usable(t_ns)) {
    return invalid("marker mode: position lost, holding");
  }
  const std::optional<Eigen::Vector3d> p_marker = navigation_.p_W_M_m(marker_id_);
  const double yaw = navigation_.yaw_rad();
  if (!have_yaw_) {
    yaw_hold_rad_ = yaw;
    have_yaw_ = true;
  }
  const Eigen::Vector3d p = navigation_.p_W_m();
  if (!p_marker) return search(yaw, p);
  const Eigen::Vector3d offset = *p_marker - p;
  horizontal_error_m_ = offset.head<2>().norm();
  const double height_m = p_marker->z() - p.z();  // NED: the floor marker is below.

  Eigen::Vector3d v_W = config_.kp_position_per_s * offset;
  v_W.z() = config_.kp_position_per_s * (height_m - config_.hold_height_m);
  // Going far: the camera faces the marker so that the map stays in view; close, the heading
  // found on arrival is held (turning over the target would only disturb the pose).
  if (task_ != MarkerTask::kHold && horizontal_error_m_ > config_.face_target_beyond_m) {
    yaw_hold_rad_ = std::atan2(offset.y(), offset.x()) - navigation_.camera_heading_rad();
  }
  if (task_ == MarkerTask::kLand) {
    if (!descending_ && horizontal_error_m_ < config_.land_align_m) descending_ = true;
    if (descending_) {
      v_W.z() = config_.land_descent_mps;
      if (height_m < config_.land_handover_height_m) wants_land_ = true;
    }
  }
  modes::ModeCommand c;
  c.valid = true;
  c.v_H_mps = to_horizontal(v_W, yaw, config_.max_speed_mps);
  if (task_ == MarkerTask::kLand && descending_) c.v_H_mps.z() = config_.land_descent_mps;
  c.yaw_rate_radps =
      yaw_rate_towards(yaw_hold_rad_, yaw, config_.kp_yaw_per_s, config_.max_yaw_rate_radps);
  return c;
}

modes::ModeCommand MarkerModeProvider::search(double yaw_rad, const Eigen::Vector3d& p_m) {
  // The target is not mapped yet: it is most likely in the field already seen, so fly to the
  // middle of the mapped markers with the camera facing it, then turn there until it shows.
  Eigen::Vector2d lo;
  Eigen::Vector2d hi;
  if (!navigation_.map_box(lo, hi)) return invalid("target marker not mapped");
  const Eigen::Vector2d to_centre = 0.5 * (lo + hi) - p_m.head<2>();
  modes::ModeCommand c;
  c.valid = true;
  c.reason = "searching the target marker";
  Eigen::Vector3d v_W(0.0, 0.0, 0.0);
  const double beyond_m = 0.3;
  if (to_centre.norm() > beyond_m) {
    v_W.head<2>() = config_.kp_position_per_s * to_centre;
    yaw_hold_rad_ = std::atan2(to_centre.y(), to_centre.x()) - navigation_.camera_heading_rad();
  } else {
    yaw_hold_rad_ = yaw_rad + config_.search_yaw_rate_radps / config_.kp_yaw_per_s;
  }
  c.v_H_mps = to_horizontal(v_W, yaw_rad, config_.max_speed_mps);
  c.yaw_rate_radps =
      yaw_rate_towards(yaw_hold_rad_, yaw_rad, config_.kp_yaw_per_s, config_.max_yaw_rate_radps);
  return c;
}

ExploreProvider::ExploreProvider(const ExploreConfig& config, const MarkerNavigation& navigation,
                                 MarkerModeProvider& marker_mode)
    : config_(config), navigation_(navigation), marker_mode_(marker_mode) {}

double ExploreProvider::exploring_for_s(std::int64_t t_ns) const {
  return exploring_started_ ? 1e-9 * static_cast<double>(t_ns - t_explore_ns_) : 0.0;
}

int ExploreProvider::cells_seen() const {
  return static_cast<int>(std::count(seen_.begin(), seen_.end(), 1));
}

bool ExploreProvider::cell_index(const Eigen::Vector2d& p_m, int& i, int& j) const {
  i = static_cast<int>(std::lround(p_m.x() / config_.cell_m)) + kCells / 2;
  j = static_cast<int>(std::lround(p_m.y() / config_.cell_m)) + kCells / 2;
  return i >= 0 && i < kCells && j >= 0 && j < kCells;
}

Eigen::Vector2d ExploreProvider::cell_centre(int i, int j) const {
  return Eigen::Vector2d(i - kCells / 2, j - kCells / 2) * config_.cell_m;
}

bool ExploreProvider::map_box(Eigen::Vector2d& lo, Eigen::Vector2d& hi) const {
  return navigation_.map_box(lo, hi);
}

void ExploreProvider::mark_seen() {
  const double z = 0.0;  // Floor markers lie in z = 0 of W.
  for (int i = 0; i < kCells; ++i) {
    for (int j = 0; j < kCells; ++j) {
      const std::size_t k = static_cast<std::size_t>(i * kCells + j);
      if (seen_[k]) continue;
      const Eigen::Vector2d c = cell_centre(i, j);
      if (navigation_.in_view(Eigen::Vector3d(c.x(), c.y(), z), config_.max_view_range_m)) {
        seen_[k] = 1;
      }
    }
  }
}

bool ExploreProvider::choose_goal(const Eigen::Vector2d& p_m) {
  // Frontier: unseen cells inside the mapped box grown by one cell. The box grows as markers
  // are found, so the coverage spreads until a ring of empty floor closes it (the seed's
  // "unvisited cells next to the known grid").
  Eigen::Vector2d lo;
  Eigen::Vector2d hi;
  if (!map_box(lo, hi)) return false;
  lo -= Eigen::Vector2d::Constant(config_.cell_m);
  hi += Eigen::Vector2d::Constant(config_.cell_m);
  double best = 1e300;
  have_goal_ = false;
  for (int i = 0; i < kCells; ++i) {
    for (int j = 0; j < kCells; ++j) {
      if (seen_[static_cast<std::size_t>(i * kCells + j)]) continue;
      const Eigen::Vector2d c = cell_centre(i, j);
      if ((c.array() < lo.array() - 1e-6).any() || (c.array() > hi.array() + 1e-6).any()) continue;
      // Cells about a view distance away are seen by flying forwards; nearer ones would need
      // backing up blind (the camera looks forwards and down), farther ones a longer flight.
      const double cost = std::abs((c - p_m).norm() - config_.view_distance_m);
      if (cost < best) {
        best = cost;
        goal_i_ = i;
        goal_j_ = j;
        have_goal_ = true;
      }
    }
  }
  return have_goal_;
}

modes::ModeCommand ExploreProvider::fly_to(const Eigen::Vector3d& p_target_m,
                                           double yaw_target_rad) const {
  const MarkerModeConfig& gains = marker_mode_.config();
  const Eigen::Vector3d p = navigation_.p_W_m();
  const double yaw = navigation_.yaw_rad();
  modes::ModeCommand c;
  c.valid = true;
  c.v_H_mps = to_horizontal(gains.kp_position_per_s * (p_target_m - p), yaw, gains.max_speed_mps);
  c.yaw_rate_radps =
      yaw_rate_towards(yaw_target_rad, yaw, gains.kp_yaw_per_s, gains.max_yaw_rate_radps);
  return c;
}

void ExploreProvider::enter(ExplorePhase phase, std::int64_t t_ns) {
  phase_ = phase;
  t_phase_ns_ = t_ns;
}

modes::ModeCommand ExploreProvider::desired(std::int64_t t_ns) {
  if (!started_) {
    started_ = true;
    enter(ExplorePhase::kLiftOff, t_ns);
  }
  // A phase either commands or hands over (a new phase, or a goal given up), and the new state
  // is asked in the same call, so a phase change costs no step. Every hand-over chain ends
  // within a few passes (a phase entered now has spent 0 s in it); the bound only keeps a
  // future cycle from spinning.
  constexpr int kMaxPasses = 8;
  for (int pass = 0; pass < kMaxPasses; ++pass) {
    if (std::optional<modes::ModeCommand> c = step(t_ns)) return *c;
  }
  return invalid("explore: phase changes did not settle");
}

std::optional<modes::ModeCommand> ExploreProvider::step(std::int64_t t_ns) {
  StepInputs in;
  in.in_phase_s = 1e-9 * static_cast<double>(t_ns - t_phase_ns_);
  in.have_pose = navigation_.pose_usable(t_ns);
  in.p_W_m = navigation_.p_W_m();
  in.z_target_m = -config_.height_m;
  in.alpha_rad = navigation_.camera_heading_rad();
  switch (phase_) {
    case ExplorePhase::kLiftOff:
      return lift_off(t_ns, in);
    case ExplorePhase::kSearch: {
      if (in.have_pose) {
        enter(ExplorePhase::kExplore, t_ns);
        return std::nullopt;
      }
      modes::ModeCommand c;
      c.valid = true;
      c.yaw_rate_radps = config_.search_yaw_rate_radps;
      return c;
    }
    case ExplorePhase::kExplore:
      return explore(t_ns, in);
    case ExplorePhase::kEdge:
      return counter_steer(t_ns, in);
    case ExplorePhase::kNavigate: {
      const modes::ModeCommand c = marker_mode_.desired(t_ns);
      if (c.valid && marker_mode_.horizontal_error_m() < 0.1) {
        enter(ExplorePhase::kLand, t_ns);
        marker_mode_.set_task(MarkerTask::kLand, marker_mode_.config().target_id);
      }
      return c;
    }
    case ExplorePhase::kLand:
      return marker_mode_.desired(t_ns);
    case ExplorePhase::kDone: {
      if (!in.have_pose) return invalid("explore: no marker pose");
      return fly_to(Eigen::Vector3d(in.p_W_m.x(), in.p_W_m.y(), in.z_target_m),
                    navigation_.yaw_rad());
    }
  }
  return invalid("explore: unknown phase");
}

std::optional<modes::ModeCommand> ExploreProvider::lift_off(std::int64_t t_ns,
                                                            const StepInputs& in) {
  // Seed: climb to the working height; on the RGB-D velocity alone until a marker anchors.
  const double height_m = -in.p_W_m.z();  // W: floor markers at z = 0, NED.
  if ((in.have_pose && height_m > config_.height_m - 0.1) ||
      in.in_phase_s > config_.liftoff_max_s) {
    enter(in.have_pose ? ExplorePhase::kExplore : ExplorePhase::kSearch, t_ns);
    return std::nullopt;
  }
  modes::ModeCommand c;
  c.valid = true;
  c.v_H_mps.z() = -config_.liftoff_climb_mps;
  return c;
}

std::optional<modes::ModeCommand> ExploreProvider::explore(std::int64_t t_ns,
                                                           const StepInputs& in) {
  const Eigen::Vector3d& p = in.p_W_m;
  if (!exploring_started_) {
    exploring_started_ = true;
    t_explore_ns_ = t_ns;
  }
  // Lost the markers for long (e.g. facing empty floor beyond the field): the edge phase
  // steers back while the pose is valid, and holds once it is not.
  if (!in.have_pose) {
    ++edge_events_;
    enter(ExplorePhase::kEdge, t_ns);
    return std::nullopt;
  }
  mark_seen();
  Eigen::Vector2d lo;
  Eigen::Vector2d hi;
  if (map_box(lo, hi) && navigation_.time_since_detection_s(t_ns) > config_.edge_timeout_s) {
    const Eigen::Vector2d margin = Eigen::Vector2d::Constant(config_.edge_margin_m);
    if ((p.head<2>().array() < (lo - margin).array()).any() ||
        (p.head<2>().array() > (hi + margin).array()).any()) {
      ++edge_events_;
      enter(ExplorePhase::kEdge, t_ns);
      return std::nullopt;
    }
  }
  const int previous_goal = have_goal_ ? goal_i_ * kCells + goal_j_ : -1;
  if (exploring_for_s(t_ns) > config_.budget_s || !choose_goal(p.head<2>())) {
    enter(config_.land_at_end ? ExplorePhase::kNavigate : ExplorePhase::kDone, t_ns);
    marker_mode_.set_task(MarkerTask::kGoTo, marker_mode_.config().target_id);
    return std::nullopt;
  }
  if (goal_i_ * kCells + goal_j_ != previous_goal) t_goal_ns_ = t_ns;
  // Stand off from the goal cell with the camera facing it: the forward, down-tilted camera
  // sees the floor from about a metre ahead.
  const Eigen::Vector2d goal = cell_centre(goal_i_, goal_j_);
  const Eigen::Vector2d to_goal = goal - p.head<2>();
  const double distance = to_goal.norm();
  const Eigen::Vector2d dir =
      distance > 1e-3 ? Eigen::Vector2d(to_goal / distance) : Eigen::Vector2d::UnitX();
  // A goal not seen within goal_timeout_s is given up (e.g. in the blind zone below), and the
  // next one chosen on the next pass.
  if (1e-9 * static_cast<double>(t_ns - t_goal_ns_) > config_.goal_timeout_s) {
    seen_[static_cast<std::size_t>(goal_i_ * kCells + goal_j_)] = 2;
    return std::nullopt;
  }
  // Never back up: behind the forward camera nothing is seen (nor the obstacle field's
  // depth). The stand-off stays within the mapped box grown by a cell, away from the walls.
  Eigen::Vector2d stand = distance > config_.view_distance_m
                              ? Eigen::Vector2d(goal - config_.view_distance_m * dir)
                              : Eigen::Vector2d(p.head<2>());
  if (map_box(lo, hi)) {
    stand = stand.cwiseMax(lo - Eigen::Vector2d::Constant(config_.cell_m))
                .cwiseMin(hi + Eigen::Vector2d::Constant(config_.cell_m));
  }
  const double yaw_target = std::atan2(dir.y(), dir.x()) - in.alpha_rad;
  return fly_to(Eigen::Vector3d(stand.x(), stand.y(), in.z_target_m), yaw_target);
}

std::optional<modes::ModeCommand> ExploreProvider::counter_steer(std::int64_t t_ns,
                                                                 const StepInputs& in) {
  // Seed: the edge of the map -> counter-steer back towards its centre until a marker shows.
  if (navigation_.time_since_detection_s(t_ns) < 0.1 && in.in_phase_s > 0.3) {
    enter(ExplorePhase::kExplore, t_ns);
    return std::nullopt;
  }
  // The pose invalid (no marker for position_max_age_s, ...): steering on it would fly dead
  // reckoning; hover on the velocity estimate until a marker shows again.
  if (!in.have_pose) return invalid("explore: position lost, holding");
  Eigen::Vector2d lo;
  Eigen::Vector2d hi;
  if (!map_box(lo, hi)) return invalid("explore: no map");
  const Eigen::Vector2d centre = 0.5 * (lo + hi);
  Eigen::Vector2d back = centre - in.p_W_m.head<2>();
  if (back.norm() > 1e-6) back *= config_.counter_steer_mps / back.norm();
  modes::ModeCommand c;
  c.valid = true;
  const double yaw = navigation_.yaw_rad();
  const MarkerModeConfig& gains = marker_mode_.config();
  const Eigen::Vector3d v_W(back.x(), back.y(),
                            gains.kp_position_per_s * (in.z_target_m - in.p_W_m.z()));
  c.v_H_mps = to_horizontal(v_W, yaw, gains.max_speed_mps);
  c.yaw_rate_radps = yaw_rate_towards(std::atan2(back.y(), back.x()) - in.alpha_rad, yaw,
                                      gains.kp_yaw_per_s, gains.max_yaw_rate_radps);
  return c;
}

}  // namespace hq::marker_modes

namespace hq::marker_modes {

MarkerStage::MarkerStage(const MarkerModesConfig& config, const geometry::PinholeCamera& camera,
                         const Eigen::Matrix3d& R_B_C, const Eigen::Vector3d& p_B_C_m)
    : navigation_(config, camera, R_B_C, p_B_C_m),
      marker_mode_(config.marker_mode, navigation_),
      explore_(config.explore, navigation_, marker_mode_) {}

const char* MarkerStage::position_event(modes::Mode mode, std::int64_t t_ns) {
  if (mode != modes::Mode::kMarker && mode != modes::Mode::kExplore) {
    flying_on_pose_ = false;
    holding_ = false;
    return nullptr;
  }
  const navigation::PositionCheck check = navigation_.position_check(t_ns);
  const bool usable = check.valid;
  const char* who = mode == modes::Mode::kMarker ? "marker mode" : "explore";
  if (usable) {
    const bool resumed = holding_;
    flying_on_pose_ = true;
    holding_ = false;
    if (!resumed) return nullptr;
    hq::format_into(event_text_, "{}: position valid again, resuming", who);
    return event_text_;
  }
  // Only a loss is news: before the first marker the mode is searching, not holding.
  if (!flying_on_pose_ || holding_) return nullptr;
  holding_ = true;
  char reason[96];
  navigation::PositionCheck shown = check;
  if (check.valid) {
    // Valid for the filter but older than the mode's own limit.
    shown.reason = navigation::PositionInvalid::kNoMarker;
  }
  describe_position(shown, navigation_.config().navigation, reason, sizeof reason);
  hq::format_into(event_text_, "{}: {}, holding", who, reason);
  return event_text_;
}

bool MarkerStage::wants_land(modes::Mode mode) const {
  if (mode == modes::Mode::kMarker) return marker_mode_.wants_land();
  if (mode == modes::Mode::kExplore) return explore_.wants_land();
  return false;
}

}  // namespace hq::marker_modes
