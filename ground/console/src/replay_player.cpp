#include "hq/console/replay_player.hpp"

#include "hq/base/format_into.hpp"
#include "hq/console/state_feed.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <limits>

namespace hq::console {

namespace {

constexpr std::array<double, 6> kSpeeds = {0.25, 0.5, 1.0, 2.0, 4.0, 8.0};
constexpr std::int64_t kRateWindowNs = 1'000'000'000;

double seconds_between(std::int64_t from_ns, std::int64_t to_ns) {
  return 1e-9 * static_cast<double>(to_ns - from_ns);
}

// Items of a stream (in time order) stamped at or before t_ns.
template <typename T, typename Stamp>
std::size_t count_until(const std::vector<T>& items, std::int64_t t_ns, Stamp stamp) {
  return static_cast<std::size_t>(
      std::upper_bound(items.begin(), items.end(), t_ns,
                       [&](std::int64_t t, const T& x) { return t < stamp(x); }) -
      items.begin());
}

std::int64_t state_ns(const RecordedState& s) { return s.receipt_ns; }
std::int64_t command_ns(const RecordedCommand& c) { return c.t_ns; }
std::int64_t event_ns(const RecordedEvent& e) { return e.receipt_ns; }
std::int64_t frame_ns(const RecordedFrame& f) { return f.t_ns; }

}  // namespace

std::vector<SessionStart> find_sessions(const std::vector<RecordedState>& states,
                                        std::int64_t t0_ns) {
  std::vector<SessionStart> out;
  for (std::size_t i = 0; i < states.size(); ++i) {
    const RecordedState& s = states[i];
    const char* why = nullptr;
    if (i == 0) {
      why = "first";
    } else {
      const RecordedState& p = states[i - 1];
      if (s.session_id != 0 && p.session_id != 0) {
        if (s.session_id != p.session_id) why = "new session_id";
      } else if (s.sequence < p.sequence && s.sequence <= kRestartSequence) {
        why = "sequence restarted";
      } else if (s.vehicle_t_ns < p.vehicle_t_ns) {
        why = "vehicle clock went back";
      }
    }
    if (why != nullptr) out.push_back({seconds_between(t0_ns, s.receipt_ns), i, s.session_id, why});
  }
  return out;
}

Timeline make_timeline(const Recording& r) {
  Timeline t;
  constexpr std::int64_t kNone = std::numeric_limits<std::int64_t>::max();
  std::int64_t first = kNone;
  std::int64_t last = std::numeric_limits<std::int64_t>::min();
  const auto span = [&](std::int64_t a, std::int64_t b) {
    first = std::min(first, a);
    last = std::max(last, b);
  };
  if (!r.states.empty()) span(r.states.front().receipt_ns, r.states.back().receipt_ns);
  if (!r.commands.empty()) span(r.commands.front().t_ns, r.commands.back().t_ns);
  if (!r.events.empty()) span(r.events.front().receipt_ns, r.events.back().receipt_ns);
  if (!r.rgb.empty()) span(r.rgb.front().t_ns, r.rgb.back().t_ns);
  if (first == kNone) return t;
  t.t0_ns = first;
  t.duration_s = seconds_between(first, last);
  // A band ends where the mode changes, or at the last state before a silence of more than
  // kBandGapS (no state: no mode to show, the bar stays empty there).
  constexpr double kBandGapS = 1.0;
  double previous_s = -1;
  for (const RecordedState& s : r.states) {
    const double at_s = seconds_between(first, s.receipt_ns);
    const bool silence = previous_s >= 0 && at_s - previous_s > kBandGapS;
    if (t.bands.empty() || t.bands.back().mode != s.mode || silence) {
      if (!t.bands.empty() && !silence) t.bands.back().end_s = at_s;
      t.bands.push_back({at_s, at_s, s.mode});
    }
    t.bands.back().end_s = at_s;
    previous_s = at_s;
  }
  for (const RecordedEvent& e : r.events) {
    t.marks.push_back({seconds_between(first, e.receipt_ns), e.severity});
  }
  t.sessions = find_sessions(r.states, first);
  return t;
}

ReplayPlayer::ReplayPlayer(const Recording& recording)
    : recording_(recording), timeline_(make_timeline(recording)) {
  const std::vector<RecordedState>& states = recording.states;
  gaps_before_.resize(states.size(), 0);
  session_of_.resize(states.size(), 0);
  std::size_t session = 0;
  for (std::size_t i = 0; i < states.size(); ++i) {
    while (session + 1 < timeline_.sessions.size() &&
           timeline_.sessions[session + 1].first_state <= i) {
      ++session;
    }
    session_of_[i] = session;
    std::uint64_t gaps = i > 0 ? gaps_before_[i - 1] : 0;
    // Within a session only: a restart is not a loss.
    if (i > 0 && session_of_[i - 1] == session && states[i].sequence > states[i - 1].sequence + 1) {
      gaps += states[i].sequence - states[i - 1].sequence - 1;
    }
    gaps_before_[i] = gaps;
  }
  latency_window_.reserve(states.size());
  jpeg_.reserve(262144);
  depth_.reserve(131072);
}

void ReplayPlayer::play() {
  if (at_end()) position_s_ = 0;
  playing_ = true;
}

void ReplayPlayer::toggle_play() {
  if (playing_) {
    pause();
  } else {
    play();
  }
}

void ReplayPlayer::set_speed(double speed) {
  if (!std::isfinite(speed)) return;
  speed_ = std::clamp(speed, kMinSpeed, kMaxSpeed);
}

void ReplayPlayer::faster() {
  for (const double s : kSpeeds) {
    if (s > speed_ * 1.001) {
      speed_ = s;
      return;
    }
  }
  speed_ = kMaxSpeed;
}

void ReplayPlayer::slower() {
  for (auto it = kSpeeds.rbegin(); it != kSpeeds.rend(); ++it) {
    if (*it < speed_ * 0.999) {
      speed_ = *it;
      return;
    }
  }
  speed_ = kMinSpeed;
}

void ReplayPlayer::seek(double t_s) {
  if (!std::isfinite(t_s)) return;
  position_s_ = std::clamp(t_s, 0.0, timeline_.duration_s);
}

void ReplayPlayer::advance(double wall_dt_s) {
  if (!playing_ || !(wall_dt_s > 0)) return;
  position_s_ = std::min(position_s_ + speed_ * wall_dt_s, timeline_.duration_s);
  if (at_end()) playing_ = false;
}

std::int64_t ReplayPlayer::position_ns() const {
  return timeline_.t0_ns + static_cast<std::int64_t>(std::llround(position_s_ * 1e9));
}

ReplayCounts ReplayPlayer::counts() const {
  const Recording& r = recording_;
  const std::int64_t t = position_ns();
  ReplayCounts c;
  c.states = count_until(r.states, t, state_ns);
  c.commands = count_until(r.commands, t, command_ns);
  c.frames = count_until(r.rgb, t, frame_ns);
  std::size_t sessions = 0;
  for (const SessionStart& s : timeline_.sessions) {
    if (s.first_state < c.states) ++sessions;
  }
  c.sessions = sessions;
  // The "vehicle restarted" lines feed() adds are shown like the recorded events.
  c.events = count_until(r.events, t, event_ns) + (sessions > 0 ? sessions - 1 : 0);
  const std::size_t states_before = count_until(r.states, t - kRateWindowNs, state_ns);
  const std::size_t frames_before = count_until(r.rgb, t - kRateWindowNs, frame_ns);
  // Over the last second, or what there is of it since the recording began.
  const double window_s = std::min(1.0, position_s_);
  if (window_s > 0.05) {
    c.state_rate_hz = static_cast<double>(c.states - states_before) / window_s;
    c.camera_rate_hz = static_cast<double>(c.frames - frames_before) / window_s;
  }
  if (c.states > 0) {
    c.sequence_gaps = gaps_before_[c.states - 1];
    c.latency_last_ms = r.states[c.states - 1].latency_ms;
    c.state_age_s = seconds_between(r.states[c.states - 1].receipt_ns, t);
    latency_window_.clear();
    for (std::size_t i = states_before; i < c.states; ++i) {
      latency_window_.push_back(r.states[i].latency_ms);
    }
    if (!latency_window_.empty()) {
      const auto mid =
          latency_window_.begin() + static_cast<std::ptrdiff_t>(latency_window_.size() / 2);
      std::nth_element(latency_window_.begin(), mid, latency_window_.end());
      c.latency_p50_ms = *mid;
    }
  }
  return c;
}

ReplayStatus ReplayPlayer::status() const {
  ReplayStatus s;
  s.active = true;
  s.position_s = position_s_;
  s.duration_s = timeline_.duration_s;
  s.speed = speed_;
  s.playing = playing_;
  s.at_end = at_end();
  s.sessions = counts().sessions;
  return s;
}

void ReplayPlayer::rewind_if_behind(ConsoleModel& model, std::int64_t t_ns) {
  if (fed_any_ && t_ns < fed_ns_) {
    model.reset();
    is_ = ic_ = ie_ = ir_ = 0;
    next_session_ = 0;
    vehicle_ended_ = false;
    vehicle_ended_text_[0] = '\0';
  }
  fed_any_ = true;
  fed_ns_ = t_ns;
}

void ReplayPlayer::feed_state(ConsoleModel& model) {
  const RecordedState& s = recording_.states[is_];
  if (next_session_ < timeline_.sessions.size() &&
      timeline_.sessions[next_session_].first_state == is_) {
    const SessionStart& start = timeline_.sessions[next_session_++];
    if (start.first_state > 0) {
      // As the live station: a new session ends the old one's goodbye banner.
      vehicle_ended_ = false;
      vehicle_ended_text_[0] = '\0';
      model.start_new_track();
      char text[160];
      hq::format_into(text, "vehicle restarted at {:.1f} s ({}): a new session", start.t_s,
                      start.why);
      model.on_event(s.receipt_ns, 1, text);
    }
  }
  ++is_;
  // The live link's path (state_feed.hpp): the replayed frame derives what the live one did,
  // with the link figures the ground recorded beside the state (0: unknown, older records).
  hq::console::feed_state(model, s);
}

void ReplayPlayer::feed_streams(ConsoleModel& model, std::int64_t t_ns) {
  const Recording& r = recording_;
  constexpr std::int64_t kNone = std::numeric_limits<std::int64_t>::max();
  // States, commands and events in their merged time order (a command sets the plot's v_cmd
  // for the states after it).
  for (;;) {
    const std::int64_t ts = is_ < r.states.size() ? r.states[is_].receipt_ns : kNone;
    const std::int64_t tc = ic_ < r.commands.size() ? r.commands[ic_].t_ns : kNone;
    const std::int64_t te = ie_ < r.events.size() ? r.events[ie_].receipt_ns : kNone;
    const std::int64_t next = std::min({ts, tc, te});
    if (next == kNone || next > t_ns) break;
    if (next == tc) {
      const RecordedCommand& c = r.commands[ic_++];
      model.on_command(c.t_ns, c.v_H_mps, c.yaw_rate_radps);
    } else if (next == ts) {
      feed_state(model);
    } else {
      const RecordedEvent& e = r.events[ie_++];
      model.on_event(e.receipt_ns, e.severity, e.text.c_str());
      if (e.code == static_cast<int>(link::kEventCodeVehicleEnded)) {
        vehicle_ended_ = true;
        hq::format_into(vehicle_ended_text_.data(), vehicle_ended_text_.size(), "{}", e.text);
      }
    }
  }
}

namespace {

// The image in memory (an MCAP recording) or its file (a CSV one), into a reused buffer.
void load_image(const RecordedFrame& f, std::vector<std::uint8_t>& out) {
  if (!f.data.empty()) {
    out.assign(f.data.begin(), f.data.end());
    return;
  }
  std::ifstream in(f.path, std::ios::binary);
  out.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

}  // namespace

void ReplayPlayer::feed_camera(ConsoleModel& model, std::int64_t t_ns,
                               std::uint64_t& frames_missing) {
  const Recording& r = recording_;
  // Only the newest frame passed is read and shown.
  const std::size_t frames = count_until(r.rgb, t_ns, frame_ns);
  if (frames <= ir_) return;
  ir_ = frames;
  const RecordedFrame& f = r.rgb[frames - 1];
  load_image(f, jpeg_);
  if (jpeg_.empty()) {
    ++frames_missing;
    return;
  }
  depth_.clear();
  // The depth preview received with this frame, if any (same receipt stamp).
  const auto d =
      std::lower_bound(r.depth_preview.begin(), r.depth_preview.end(), f.t_ns,
                       [](const RecordedFrame& a, std::int64_t x) { return a.t_ns < x; });
  if (d != r.depth_preview.end() && d->t_ns == f.t_ns) load_image(*d, depth_);
  model.on_camera(f.t_ns, jpeg_.data(), jpeg_.size(), depth_.empty() ? nullptr : depth_.data(),
                  depth_.size());
}

void ReplayPlayer::publish_status(ConsoleModel& model) const {
  const ReplayCounts c = counts();
  LinkHealth link;
  link.states = c.states;
  link.camera_frames = c.frames;
  link.events = c.events;
  link.state_rate_hz = c.state_rate_hz;
  link.camera_rate_hz = c.camera_rate_hz;
  link.sequence_gaps = c.sequence_gaps;
  link.last_latency_ms = c.latency_last_ms;
  link.latency_p50_ms = c.latency_p50_ms;
  link.state_age_s = c.state_age_s;
  // The ground's own figures at the latest state, as recorded (< 0: unknown, as live before the
  // first heartbeat echo).
  if (c.states > 0) {
    const RecordedState& last = recording_.states[c.states - 1];
    link.round_trip_ms = last.round_trip_ms > 0 ? static_cast<double>(last.round_trip_ms) : -1.0;
    link.state_one_way_ms = last.state_age_ms > 0 ? static_cast<double>(last.state_age_ms) : -1.0;
  }
  link.vehicle_ended = vehicle_ended_;
  link.vehicle_ended_text = vehicle_ended_text_;
  link.state_loss_percent = c.states + c.sequence_gaps > 0
                                ? 100.0 * static_cast<double>(c.sequence_gaps) /
                                      static_cast<double>(c.states + c.sequence_gaps)
                                : 0.0;
  model.on_link(link);
  ReplayStatus status;
  status.active = true;
  status.position_s = position_s_;
  status.duration_s = timeline_.duration_s;
  status.speed = speed_;
  status.playing = playing_;
  status.at_end = at_end();
  status.sessions = c.sessions;  // as status(), without counting twice
  model.on_replay(status);
}

void ReplayPlayer::feed(ConsoleModel& model, std::uint64_t& frames_missing) {
  const std::int64_t t_ns = position_ns();
  rewind_if_behind(model, t_ns);
  feed_streams(model, t_ns);
  feed_camera(model, t_ns, frames_missing);
  publish_status(model);
}

void format_clock(double t_s, char* out, std::size_t size) {
  const double t = std::max(t_s, 0.0);
  const int minutes = static_cast<int>(t / 60.0);
  hq::format_into(out, size, "{:02}:{:04.1f}", minutes, t - 60.0 * minutes);
}

void ReplayControl::apply(ReplayPlayer& player) {
  for (int n = toggles.exchange(0); n > 0; --n) player.toggle_play();
  for (int n = speed_steps.exchange(0); n != 0; n += n > 0 ? -1 : 1) {
    if (n > 0) {
      player.faster();
    } else {
      player.slower();
    }
  }
  const double to_s = seek_to_s.exchange(-1);
  if (to_s >= 0) player.seek(to_s);
  const double by_s = seek_by_s.exchange(0);
  if (by_s != 0) player.step(by_s);
}

}  // namespace hq::console
