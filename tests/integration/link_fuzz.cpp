// hq-link-fuzz: a broken or hostile station (and a forged vehicle) for the integration tests.
// For --duration-s it attacks the link with the attacks named in --attacks (comma-separated):
//   malformed  topics a vehicle reads, with samples it must reject: NaN, Inf, huge and
//              out-of-envelope velocities, out-of-range mode and role enums, huge sequence numbers
//              and stamps, and plausible samples for other vehicle ids (the default);
//   commands   in-envelope, fresh, well-formed commands from this station (--station-id,
//              --station-strength): 1 s at 90 % of the envelope straight ahead (towards whatever
//              obstacle is there), then 1 s oscillating side to side at 4 Hz, and so on. A
//              stronger station than the operator's takes the vehicle (DDS ownership): the
//              vehicle must fly them and stay clear of obstacles on its own, unless link.stations
//              keeps this station out;
//   requests   well-formed mode requests for the vehicle's current session (learned from its
//              states) from this station, alternating hover and land at 2 Hz: the vehicle must
//              ignore them unless this station commands it;
//   replay     mode requests for an older or made-up session and commands stamped 5 s ago;
//   heartbeats well-formed ground heartbeats from this station at 10 Hz (alive but not
//              commanding: they must not keep a vehicle whose commander died from landing);
//   states     to the ground: forged vehicle states (another session, NaN, huge magnitudes,
//              attitudes beyond pi, the current session with a sequence going backwards or jumping
//              ahead) and forged events of another session.
// What a process sends is all it can know directly; what the vehicle made of it is read back
// from the vehicle's own states (who commands it) and events (its rejections), and printed in a
// table of sent / refused by the writer / seen accepted / seen rejected per topic and attack.
//   hq-link-fuzz --domain-id N [--vehicle-id 1] [--station-id 666] [--station-strength 200]
//                [--attacks malformed] [--duration-s 4] [--rate-hz 2000] [--seed 1]
#include "hq/base/tool_main.hpp"
#include "hq/link/config.hpp"
#include "hq/link/link.hpp"

#include <CLI/CLI.hpp>

#include <time.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <set>
#include <sstream>
#include <string>

namespace {

std::int64_t now_ns() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec * 1'000'000'000LL + t.tv_nsec;
}

// One row of the report.
struct Tally {
  const char* topic;
  const char* attack;
  std::uint64_t sent = 0;
  std::uint64_t refused = 0;  // by our own writer (Cyclone's serialiser refuses bad enums)
  std::int64_t accepted = -1;  // as seen from the vehicle's states/events; -1: not observable
  std::int64_t rejected = -1;
  void count(bool ok) { ok ? ++sent : ++refused; }
};

int run(int argc, char** argv) {
  CLI::App app{"hq-link-fuzz: malformed and hostile samples on a vehicle's link, both ways"};
  hq::link::LinkOverrides overrides;
  hq::link::add_link_options(app, overrides);
  double duration_s = 4.0;
  double rate_hz = 2000.0;
  unsigned seed = 1;
  std::string attacks_text = "malformed";
  app.add_option("--duration-s", duration_s)->check(CLI::Range(0.1, 600.0));
  app.add_option("--rate-hz", rate_hz, "malformed samples per second per topic")
      ->check(CLI::Range(1.0, 1e5));
  app.add_option("--seed", seed);
  app.add_option("--attacks", attacks_text,
                 "comma-separated: malformed, commands, requests, replay, heartbeats, states");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  std::set<std::string> attacks;
  {
    std::stringstream ss(attacks_text);
    std::string a;
    const std::set<std::string> known = {"malformed", "commands",   "requests",
                                         "replay",    "heartbeats", "states"};
    while (std::getline(ss, a, ',')) {
      if (known.count(a) == 0) {
        throw hq::InputError("--attacks: unknown attack '" + a +
                             "', expected malformed, commands, requests, replay, heartbeats or "
                             "states");
      }
      attacks.insert(a);
    }
  }
  const auto on = [&](const char* a) { return attacks.count(a) > 0; };
  hq::link::LinkConfig config;
  config.station_id = 666;
  config.station_strength = 200;
  hq::link::apply_overrides(overrides, config);

  hq::link::Participant participant(config.domain_id);
  hq::link::Topics topics(participant);
  hq::link::Writer<hq::link::VelocityCommand> commands(
      participant, topics.command, hq::link::command_qos(config, hq::link::End::kWriter));
  hq::link::Writer<hq::link::ModeRequest> modes(participant, topics.mode_request,
                                                hq::link::mode_request_qos());
  hq::link::Writer<hq::link::Heartbeat> heartbeats(participant, topics.heartbeat,
                                                   hq::link::heartbeat_qos(config));
  hq::link::Writer<hq::link::VehicleState> forged_states(participant, topics.vehicle_state,
                                                         hq::link::vehicle_state_qos());
  hq::link::Writer<hq::link::Event> forged_events(participant, topics.event,
                                                  hq::link::event_qos());
  // What the vehicle says: its session, who commands it, and its rejections.
  hq::link::Reader<hq::link::VehicleState> states(participant, topics.vehicle_state,
                                                  hq::link::vehicle_state_qos());
  hq::link::Reader<hq::link::Event> events(participant, topics.event, hq::link::event_qos());
  hq::link::Sample<hq::link::VehicleState> state;
  hq::link::reserve(state->obstacle_points_body_m, hq_msgs_kMaxObstaclePoints);

  Tally malformed_commands{"command", "malformed"};
  Tally malformed_requests{"mode request", "malformed"};
  Tally malformed_heartbeats{"heartbeat", "malformed"};
  Tally hostile_commands{"command", "in-envelope, hostile"};
  Tally owner_requests{"mode request", "right session, not commander"};
  Tally replayed_requests{"mode request", "replay: old session"};
  Tally replayed_commands{"command", "replay: stamped 5 s ago"};
  Tally foreign_heartbeats{"heartbeat", "alive, not commander"};
  Tally state_forgeries{"vehicle state", "forged (session/NaN/range/seq)"};
  Tally event_forgeries{"event", "forged (other session)"};

  std::mt19937_64 rng(seed);
  const float specials[] = {std::numeric_limits<float>::quiet_NaN(),
                            std::numeric_limits<float>::infinity(),
                            -std::numeric_limits<float>::infinity(),
                            std::numeric_limits<float>::max(),
                            -std::numeric_limits<float>::max(),
                            std::numeric_limits<float>::denorm_min(),
                            1e9F,
                            -50.0F};
  std::uniform_int_distribution<int> pick(0, 7);
  std::uniform_real_distribution<float> small(-0.3F, 0.3F);
  const auto other_vehicle = [&] {
    std::uint32_t id = static_cast<std::uint32_t>(rng());
    return id == config.vehicle_id ? id + 1 : id;
  };
  const auto huge_sequence = [&] {
    return std::numeric_limits<std::uint64_t>::max() - (rng() % 4);
  };

  std::uint64_t session = 0;  // the vehicle's, once heard
  std::uint64_t last_sequence = 0;
  std::uint64_t states_seen = 0;
  std::uint64_t states_followed = 0;  // states naming this station as the commander
  std::uint64_t requests_rejected_seen = 0;
  std::uint64_t commander_events = 0;
  std::uint64_t mode_sequence = 0;
  std::uint64_t command_sequence = 0;
  std::uint64_t heartbeat_sequence = 0;
  std::uint64_t forged_sequence = 0;
  char own_request_tag[48];
  std::snprintf(own_request_tag, sizeof own_request_tag, "mode request of station %u ",
                config.station_id);
  char own_commander_tag[48];
  std::snprintf(own_commander_tag, sizeof own_commander_tag, "station %u commands",
                config.station_id);

  constexpr float kForgedMark = -7.77F;  // height_m of our forged states (plausible on its own)
  const bool malformed = on("malformed");
  const std::int64_t malformed_period_ns = static_cast<std::int64_t>(1e9 / rate_hz);
  const std::int64_t tick_ns = malformed ? std::min<std::int64_t>(malformed_period_ns, 10'000'000)
                                         : 10'000'000;  // 100 Hz otherwise
  const std::int64_t start_ns = now_ns();
  std::int64_t next_slow_ns = start_ns;  // the well-formed attacks' 100 Hz tick
  std::uint64_t slow_ticks = 0;
  const std::int64_t end_ns = start_ns + static_cast<std::int64_t>(duration_s * 1e9);
  std::int64_t next_ns = start_ns;
  for (std::uint64_t i = 0; now_ns() < end_ns; ++i) {
    const std::int64_t t_ns = now_ns();
    dds_sample_info_t info{};
    while (states.take(*state, info)) {
      if (state->vehicle_id != config.vehicle_id) continue;
      // Our own forged states come back too (same participant): they carry kForgedMark.
      if (state->session_id == 0 || state->height_m == kForgedMark) continue;
      if (session == 0 || (state->session_id == session && state->sequence_number > last_sequence)) {
        session = state->session_id;
        last_sequence = state->sequence_number;
        ++states_seen;
        if (state->commanding_station_id == config.station_id) ++states_followed;
      }
    }
    hq::link::Event event{};
    while (events.take(event, info)) {
      if (event.vehicle_id != config.vehicle_id || event.session_id != session) continue;
      if (std::strstr(event.text, own_request_tag) != nullptr) ++requests_rejected_seen;
      if (std::strstr(event.text, own_commander_tag) != nullptr) ++commander_events;
    }

    if (malformed) {
      hq::link::VelocityCommand c{};
      c.station_id = static_cast<std::uint32_t>(rng());
      c.sequence_number = huge_sequence();
      c.t_ns = static_cast<std::int64_t>(rng());
      c.v_H_mps = {small(rng), small(rng), small(rng)};
      if (i % 4 == 0) {
        c.vehicle_id = other_vehicle();  // plausible values, wrong vehicle
      } else {
        c.vehicle_id = config.vehicle_id;
        const float bad = specials[pick(rng)];
        switch (i % 4) {
          case 1: c.v_H_mps.x = bad; break;
          case 2: c.v_H_mps.z = bad; break;
          default: c.yaw_rate_radps = bad; break;
        }
      }
      malformed_commands.count(commands.write(c));

      hq::link::ModeRequest m{};
      m.station_id = c.station_id;
      m.sequence_number = huge_sequence();
      if (i % 3 == 0) {
        m.vehicle_id = other_vehicle();
        m.requested_mode = hq_msgs_MODE_LAND;  // valid, but not for this vehicle
      } else {
        m.vehicle_id = config.vehicle_id;
        m.requested_mode = static_cast<hq_msgs_Mode>(
            i % 2 == 0 ? 5 + static_cast<int>(rng() % 1000) : -1 - static_cast<int>(rng() % 1000));
      }
      if (i % 20 == 0) malformed_requests.count(modes.write(m));  // reliable: keep the rate sane

      hq::link::Heartbeat h{};
      h.vehicle_id = i % 2 == 0 ? other_vehicle() : config.vehicle_id;
      h.role = static_cast<hq_msgs_Role>(2 + static_cast<int>(rng() % 100));
      h.sender_id = c.station_id;
      h.sequence_number = huge_sequence();
      malformed_heartbeats.count(heartbeats.write(h));
    }

    // The well-formed attacks run at 100 Hz (commands) and slower (the rest).
    const bool tick_100hz = t_ns >= next_slow_ns;
    if (tick_100hz) {
      next_slow_ns = std::max(next_slow_ns + 10'000'000, t_ns);
      ++slow_ticks;
    }
    const std::int64_t phase_ms = (t_ns - start_ns) / 1'000'000;
    if (tick_100hz && on("commands")) {
      hq::link::VelocityCommand c{};
      c.vehicle_id = config.vehicle_id;
      c.station_id = config.station_id;
      c.sequence_number = ++command_sequence;
      c.t_ns = t_ns;
      const float v_x = 0.9F * static_cast<float>(config.envelope.max_v_x_mps);
      const float v_y = 0.9F * static_cast<float>(config.envelope.max_v_y_mps);
      if ((phase_ms / 1000) % 2 == 0) {
        c.v_H_mps = {v_x, 0.0F, 0.0F};  // straight ahead, into whatever is there
      } else {
        c.v_H_mps = {0.0F, (phase_ms / 125) % 2 == 0 ? v_y : -v_y, 0.0F};  // 4 Hz side to side
      }
      hostile_commands.count(commands.write(c));
    }
    if (tick_100hz && on("replay") && slow_ticks % 10 == 0) {
      hq::link::VelocityCommand c{};
      c.vehicle_id = config.vehicle_id;
      c.station_id = config.station_id;
      c.sequence_number = ++command_sequence;
      c.t_ns = t_ns - 5'000'000'000;  // recorded 5 s ago
      c.v_H_mps = {0.5F, 0.0F, 0.0F};
      replayed_commands.count(commands.write(c));
    }
    if (tick_100hz && on("heartbeats") && slow_ticks % 10 == 0) {
      hq::link::Heartbeat h{};
      h.vehicle_id = config.vehicle_id;
      h.role = hq_msgs_ROLE_GROUND;
      h.sender_id = config.station_id;
      h.sequence_number = ++heartbeat_sequence;
      h.t_ns = t_ns;
      h.session_id = 0x666;
      foreign_heartbeats.count(heartbeats.write(h));
    }
    const bool tick_2hz = tick_100hz && slow_ticks % 50 == 0;
    if (tick_2hz && on("requests") && session != 0) {
      hq::link::ModeRequest m{};
      m.vehicle_id = config.vehicle_id;
      m.station_id = config.station_id;
      m.sequence_number = ++mode_sequence;
      m.t_ns = t_ns;
      m.requested_mode = (slow_ticks / 50) % 2 == 0 ? hq_msgs_MODE_HOVER : hq_msgs_MODE_LAND;
      m.vehicle_session_id = session;
      owner_requests.count(modes.write(m));
    }
    if (tick_2hz && on("replay")) {
      hq::link::ModeRequest m{};
      m.vehicle_id = config.vehicle_id;
      m.station_id = 1;  // as if the operator's, made to an earlier instance
      m.sequence_number = ++mode_sequence;
      m.t_ns = t_ns - 6'000'000'000;
      m.requested_mode = hq_msgs_MODE_LAND;
      m.vehicle_session_id = session != 0 ? session ^ 0x5a5a5a5a5a5a5a5aULL : 12345;
      replayed_requests.count(modes.write(m));
    }
    if (tick_100hz && on("states") && slow_ticks % 2 == 0) {
      hq::link::VehicleState& s = *state;
      s = {};
      s.vehicle_id = config.vehicle_id;
      s.t_ns = t_ns;
      s.mode = hq_msgs_MODE_TELEOP;
      s.clearance_m = -1.0F;
      s.height_m = kForgedMark;
      ++forged_sequence;
      // Each would pull the operator's hand hard if the ground believed it.
      switch (forged_sequence % 6) {
        case 0:  // plausible values (17 m/s) from another session
          s.session_id = session ^ 0xdeadbeefULL;
          s.sequence_number = forged_sequence;
          s.v_H_mps = {12.0F, -12.0F, 0.0F};
          break;
        case 1:
          s.session_id = session;
          s.sequence_number = last_sequence + 1'000'000;  // jumps ahead: would lock the real out
          s.v_H_mps = {12.0F, 0.0F, 0.0F};
          break;
        case 2:
          s.session_id = session;
          s.sequence_number = 1;  // backwards
          s.v_H_mps = {-12.0F, 0.0F, 0.0F};
          break;
        case 3:
          s.session_id = session;
          s.sequence_number = last_sequence + 1;
          s.v_H_mps = {std::numeric_limits<float>::quiet_NaN(), 0.0F, 0.0F};
          break;
        case 4:
          s.session_id = session;
          s.sequence_number = last_sequence + 1;
          s.v_H_mps = {1e6F, 1e6F, 0.0F};
          break;
        default:
          s.session_id = session;
          s.sequence_number = last_sequence + 1;
          s.roll_rad = 7.0F;
          s.v_obs_H_mps = {0.0F, 900.0F, 0.0F};
          break;
      }
      if (s.session_id == 0) s.session_id = 0xbad;
      state_forgeries.count(forged_states.write(s));
      if (forged_sequence % 25 == 0) {
        hq::link::Event e{};
        e.vehicle_id = config.vehicle_id;
        e.session_id = session ^ 0xfeedULL;
        e.sequence_number = forged_sequence;
        e.t_ns = t_ns;
        e.severity = hq_msgs_SEVERITY_ERROR;
        std::snprintf(e.text, sizeof e.text, "FORGED: motors failing, land now");
        event_forgeries.count(forged_events.write(e));
      }
    }

    next_ns += tick_ns;
    timespec deadline{};
    deadline.tv_sec = next_ns / 1'000'000'000LL;
    deadline.tv_nsec = next_ns % 1'000'000'000LL;
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, nullptr) == EINTR) {
    }
  }

  // What can be seen of the vehicle's verdicts.
  hostile_commands.accepted = static_cast<std::int64_t>(states_followed);
  owner_requests.rejected = static_cast<std::int64_t>(requests_rejected_seen);
  std::printf("hq-link-fuzz: attacks %s as station %u (strength %d) on vehicle %u, session "
              "%016llx; the vehicle named this station its commander in %llu of %llu states "
              "(%llu change events)\n",
              attacks_text.c_str(), config.station_id, config.station_strength,
              config.vehicle_id, static_cast<unsigned long long>(session),
              static_cast<unsigned long long>(states_followed),
              static_cast<unsigned long long>(states_seen),
              static_cast<unsigned long long>(commander_events));
  std::printf("  %-14s %-32s %10s %8s %16s %16s\n", "topic", "attack", "sent", "refused",
              "seen accepted", "seen rejected");
  std::uint64_t sent = 0;
  std::uint64_t refused = 0;
  const auto cell = [](std::int64_t v) { return v < 0 ? std::string("-") : std::to_string(v); };
  for (const Tally* t : {&malformed_commands, &malformed_requests, &malformed_heartbeats,
                         &hostile_commands, &owner_requests, &replayed_requests,
                         &replayed_commands, &foreign_heartbeats, &state_forgeries,
                         &event_forgeries}) {
    sent += t->sent;
    refused += t->refused;
    if (t->sent + t->refused == 0) continue;
    std::printf("  %-14s %-32s %10llu %8llu %16s %16s\n", t->topic, t->attack,
                static_cast<unsigned long long>(t->sent),
                static_cast<unsigned long long>(t->refused), cell(t->accepted).c_str(),
                cell(t->rejected).c_str());
  }
  // "malformed samples sent" is the line earlier tests and scripts read.
  std::printf("hq-link-fuzz: %llu malformed samples sent, %llu refused by the writer (%s)\n",
              static_cast<unsigned long long>(sent), static_cast<unsigned long long>(refused),
              heartbeats.last_error());
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-link-fuzz", argc, argv, run); }
