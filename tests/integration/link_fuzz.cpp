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
// --claim-station N makes the well-formed samples claim station N while the writers stay this
// identity's (--station-id): an allowed station speaking for another. On a secured link the
// vehicle refuses them as intrusions and reports so (counted from its events).
// What a process sends is all it can know directly; what the vehicle made of it is read back
// from the vehicle's own states (who commands it) and events (its rejections), and printed in a
// table of sent / refused / sent with no reader matched / seen accepted / seen rejected per topic
// and attack.
// Security as hq-ground: --insecure for plain DDS, or --security-dir KEYS [--identity NAME] to
// attack as a station holding those credentials (default identity station_<station id>). What
// the secured link refuses is counted, not fatal: a writer or reader its permissions deny (every
// sample that writer would have sent counts as refused), and samples sent while no reader
// matched (authentication failed, or a partition the permissions keep us out of). A run in
// which no sample reached any reader did not test the vehicle: it says so and exits with
// kExitNotReached, never 0.
//   hq-link-fuzz --domain-id N (--insecure | --security-dir KEYS [--identity station_666])
//                [--vehicle-id 1] [--station-id 666] [--station-strength 200]
//                [--attacks malformed] [--duration-s 4] [--rate-hz 2000] [--seed 1]
//                [--claim-station N]
#include "hq/base/format_into.hpp"
#include "hq/base/monotonic_clock.hpp"
#include "hq/base/tool_main.hpp"
#include "hq/link/config.hpp"
#include "hq/link/link.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fmt/format.h>
#include <limits>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <utility>

namespace {

// The exit status of a run whose samples reached no reader at all: the vehicle was not tested,
// which must not read as a pass (2 is bad input, as for every tool).
constexpr int kExitNotReached = 3;

// One row of the report.
struct Tally {
  const char* topic;
  const char* attack;
  std::uint64_t sent = 0;
  // Not put on the wire: by our own writer (Cyclone's serialiser refuses bad enums), or because
  // the secured link denied the writer.
  std::uint64_t refused = 0;
  std::uint64_t unmatched = 0;  // sent while no reader was matched: delivered to nobody
  std::int64_t accepted = -1;   // as seen from the vehicle's states/events; -1: not observable
  std::int64_t rejected = -1;
  [[nodiscard]] std::uint64_t reached() const { return sent - unmatched; }
};

// A writer the secured link may refuse to create (permissions): then the attack still runs and
// every sample it would have written counts as refused, with the reason kept for the report.
template <typename T>
class AttackWriter {
 public:
  AttackWriter(const hq::link::Participant& participant, const hq::link::Topic<T>& topic,
               const hq::link::Qos& qos) {
    try {
      writer_.emplace(participant, topic, qos);
    } catch (const hq::InputError& e) {
      refusal_ = e.what();
    }
  }

  void write(const T& sample, Tally& tally) {
    if (!writer_) {
      ++tally.refused;
      return;
    }
    // Asked before writing: a best-effort sample written with no reader matched went nowhere.
    const bool matched = writer_->matched_readers() > 0;
    if (!writer_->write(sample)) {
      ++tally.refused;
      return;
    }
    ++tally.sent;
    if (!matched) ++tally.unmatched;
  }

  [[nodiscard]] const std::string& refusal() const { return refusal_; }
  [[nodiscard]] const char* last_error() const { return writer_ ? writer_->last_error() : ""; }

 private:
  std::optional<hq::link::Writer<T>> writer_;
  std::string refusal_;  // empty: created
};

// `qos` for a reader that ignores this participant's own writers: our forged states and events
// must neither come back as the vehicle's nor count as having reached a reader.
hq::link::Qos ignoring_own_writers(hq::link::Qos qos) {
  dds_qset_ignorelocal(qos.get(), DDS_IGNORELOCAL_PARTICIPANT);
  return qos;
}

// A reader the secured link may refuse to create: then what the vehicle made of the attack is
// not observable, and the report says so instead of showing zeros.
template <typename T>
class WatchReader {
 public:
  WatchReader(const hq::link::Participant& participant, const hq::link::Topic<T>& topic,
              const hq::link::Qos& qos) {
    try {
      reader_.emplace(participant, topic, qos);
    } catch (const hq::InputError& e) {
      refusal_ = e.what();
    }
  }
  bool take(T& sample, dds_sample_info_t& info) { return reader_ && reader_->take(sample, info); }
  [[nodiscard]] const std::string& refusal() const { return refusal_; }

 private:
  std::optional<hq::link::Reader<T>> reader_;
  std::string refusal_;
};

struct FuzzOptions {
  hq::link::LinkOverrides overrides;
  double duration_s = 4.0;
  double rate_hz = 2000.0;
  unsigned seed = 1;
  std::string attacks_text = "malformed";
  std::set<std::string> attacks;
  std::uint32_t claim_station = 0;  ///< The station id the well-formed samples claim; 0: ours.
};

// The command line; an exit status when told to stop (--help, a parse error).
std::optional<int> parse_options(int argc, char** argv, FuzzOptions& o) {
  CLI::App app{"hq-link-fuzz: malformed and hostile samples on a vehicle's link, both ways"};
  hq::link::add_link_options(app, o.overrides);
  app.add_option("--duration-s", o.duration_s)->check(CLI::Range(0.1, 600.0));
  app.add_option("--rate-hz", o.rate_hz, "malformed samples per second per topic")
      ->check(CLI::Range(1.0, 1e5));
  app.add_option("--seed", o.seed);
  app.add_option("--claim-station", o.claim_station,
                 "station id the well-formed samples claim (default: --station-id)")
      ->check(CLI::Range(1U, 0xFFFFFFFFU));
  app.add_option("--attacks", o.attacks_text,
                 "comma-separated: malformed, commands, requests, replay, heartbeats, states");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  // hq-link-fuzz reads no link YAML, so an identity can only come from --security-dir.
  if (o.overrides.identity && !o.overrides.security_dir) {
    throw hq::InputError("--identity " + *o.overrides.identity +
                         ": needs --security-dir KEYS (the directory made by hq-keys)");
  }
  if (o.overrides.ros2 || o.overrides.link_impair || o.overrides.stations) {
    throw hq::InputError(
        "--ros2, --link-impair and --stations configure a vehicle or a receiving end: "
        "hq-link-fuzz does not use them");
  }
  std::stringstream ss(o.attacks_text);
  std::string a;
  const std::set<std::string> known = {"malformed", "commands",   "requests",
                                       "replay",    "heartbeats", "states"};
  while (std::getline(ss, a, ',')) {
    if (known.count(a) == 0) {
      throw hq::InputError("--attacks: unknown attack '" + a +
                           "', expected malformed, commands, requests, replay, heartbeats or "
                           "states");
    }
    o.attacks.insert(a);
  }
  return std::nullopt;
}

constexpr float kForgedMark = -7.77F;  // height_m of our forged states (plausible on its own)

// The hostile station: its writers, what it has learned of the vehicle, and its tallies.
class Fuzzer {
 public:
  Fuzzer(const FuzzOptions& o, const hq::link::LinkConfig& config)
      : o_(o),
        config_(config),
        participant_(config, hq::security::Role::kStation),
        topics_(participant_),
        commands_(participant_, topics_.command,
                  hq::link::command_qos(config, hq::link::End::kWriter)),
        modes_(participant_, topics_.mode_request, hq::link::mode_request_qos()),
        heartbeats_(participant_, topics_.heartbeat, hq::link::heartbeat_qos(config)),
        forged_states_(participant_, topics_.vehicle_state, hq::link::vehicle_state_qos()),
        forged_events_(participant_, topics_.event, hq::link::event_qos()),
        states_(participant_, topics_.vehicle_state,
                ignoring_own_writers(hq::link::vehicle_state_qos())),
        events_(participant_, topics_.event, ignoring_own_writers(hq::link::event_qos())),
        rng_(o.seed) {
    hq::link::reserve(state_->obstacle_points_B_m, hq_msgs_kMaxObstaclePoints);
    hq::format_into(own_request_tag_, "mode request of station {} ", claimed_station());
    hq::format_into(own_commander_tag_, "station {} commands", claimed_station());
  }

  void run();
  [[nodiscard]] int report() const;
  void report_refusals() const;

 private:
  bool on(const char* attack) const { return o_.attacks.count(attack) > 0; }
  [[nodiscard]] std::uint32_t claimed_station() const {
    return o_.claim_station != 0 ? o_.claim_station : config_.station_id;
  }
  [[nodiscard]] bool impersonating() const { return claimed_station() != config_.station_id; }
  std::uint32_t other_vehicle() {
    const auto id = static_cast<std::uint32_t>(rng_());
    return id == config_.vehicle_id ? id + 1 : id;
  }
  std::uint64_t huge_sequence() { return std::numeric_limits<std::uint64_t>::max() - (rng_() % 4); }
  void listen();
  void send_malformed(std::uint64_t i);
  void send_well_formed(std::int64_t t_ns, std::int64_t start_ns);
  void send_hostile_command(std::int64_t t_ns, std::int64_t phase_ms);
  void send_replayed_command(std::int64_t t_ns);
  void send_heartbeat(std::int64_t t_ns);
  void send_owner_request(std::int64_t t_ns);
  void send_replayed_request(std::int64_t t_ns);
  void send_forged_state(std::int64_t t_ns);

  const FuzzOptions& o_;
  hq::link::LinkConfig config_;
  hq::link::Participant participant_;
  hq::link::Topics topics_;
  AttackWriter<hq::link::VelocityCommand> commands_;
  AttackWriter<hq::link::ModeRequest> modes_;
  AttackWriter<hq::link::Heartbeat> heartbeats_;
  AttackWriter<hq::link::VehicleState> forged_states_;
  AttackWriter<hq::link::Event> forged_events_;
  // What the vehicle says: its session, who commands it, and its rejections.
  WatchReader<hq::link::VehicleState> states_;
  WatchReader<hq::link::Event> events_;
  hq::link::Sample<hq::link::VehicleState> state_;

  Tally malformed_commands_{"command", "malformed"};
  Tally malformed_requests_{"mode request", "malformed"};
  Tally malformed_heartbeats_{"heartbeat", "malformed"};
  Tally hostile_commands_{"command", "in-envelope, hostile"};
  Tally owner_requests_{"mode request", "right session, not commander"};
  Tally replayed_requests_{"mode request", "replay: old session"};
  Tally replayed_commands_{"command", "replay: stamped 5 s ago"};
  Tally foreign_heartbeats_{"heartbeat", "alive, not commander"};
  Tally state_forgeries_{"vehicle state", "forged (session/NaN/range/seq)"};
  Tally event_forgeries_{"event", "forged (other session)"};

  std::mt19937_64 rng_;
  std::uniform_int_distribution<int> pick_{0, 7};
  std::uniform_real_distribution<float> small_{-0.3F, 0.3F};
  static constexpr std::array<float, 8> kSpecials = {std::numeric_limits<float>::quiet_NaN(),
                                                     std::numeric_limits<float>::infinity(),
                                                     -std::numeric_limits<float>::infinity(),
                                                     std::numeric_limits<float>::max(),
                                                     -std::numeric_limits<float>::max(),
                                                     std::numeric_limits<float>::denorm_min(),
                                                     1e9F,
                                                     -50.0F};

  std::uint64_t session_ = 0;  // the vehicle's, once heard
  std::uint64_t last_sequence_ = 0;
  std::uint64_t states_seen_ = 0;
  std::uint64_t states_followed_ = 0;  // states naming this station as the commander
  std::uint64_t requests_rejected_seen_ = 0;
  std::uint64_t commander_events_ = 0;
  std::uint64_t intrusion_reports_ = 0;  // the vehicle's intrusion events
  std::uint64_t mode_sequence_ = 0;
  std::uint64_t command_sequence_ = 0;
  std::uint64_t heartbeat_sequence_ = 0;
  std::uint64_t forged_sequence_ = 0;
  std::int64_t next_slow_ns_ = 0;  // the well-formed attacks' 100 Hz tick
  std::uint64_t slow_ticks_ = 0;
  char own_request_tag_[48] = {};
  char own_commander_tag_[48] = {};
};

void Fuzzer::run() {
  const bool malformed = on("malformed");
  const auto malformed_period_ns = static_cast<std::int64_t>(1e9 / o_.rate_hz);
  const std::int64_t tick_ns = malformed ? std::min<std::int64_t>(malformed_period_ns, 10'000'000)
                                         : 10'000'000;  // 100 Hz otherwise
  const std::int64_t start_ns = hq::monotonic_now_ns();
  next_slow_ns_ = start_ns;
  const std::int64_t end_ns = start_ns + static_cast<std::int64_t>(o_.duration_s * 1e9);
  std::int64_t next_ns = start_ns;
  for (std::uint64_t i = 0; hq::monotonic_now_ns() < end_ns; ++i) {
    const std::int64_t t_ns = hq::monotonic_now_ns();
    listen();
    if (malformed) send_malformed(i);
    send_well_formed(t_ns, start_ns);
    next_ns += tick_ns;
    hq::sleep_until_monotonic_ns(next_ns);
  }
}

// The vehicle's states (its session, whom it obeys) and its events naming this station.
void Fuzzer::listen() {
  dds_sample_info_t info{};
  while (states_.take(*state_, info)) {
    if (state_->vehicle_id != config_.vehicle_id) continue;
    // Ours are ignored by the reader; the mark also drops those of another fuzzer alongside.
    if (state_->session_id == 0 || state_->height_m == kForgedMark) continue;
    if (session_ == 0 ||
        (state_->session_id == session_ && state_->sequence_number > last_sequence_)) {
      session_ = state_->session_id;
      last_sequence_ = state_->sequence_number;
      ++states_seen_;
      if (state_->commanding_station_id == claimed_station()) ++states_followed_;
    }
  }
  hq::link::Event event{};
  while (events_.take(event, info)) {
    if (event.vehicle_id != config_.vehicle_id || event.session_id != session_) continue;
    if (std::strstr(event.text, own_request_tag_) != nullptr) ++requests_rejected_seen_;
    if (std::strstr(event.text, own_commander_tag_) != nullptr) ++commander_events_;
    if (event.code == hq::link::kEventCodeIntrusion) ++intrusion_reports_;
  }
}

void Fuzzer::send_malformed(std::uint64_t i) {
  hq::link::VelocityCommand c{};
  c.station_id = static_cast<std::uint32_t>(rng_());
  c.sequence_number = huge_sequence();
  c.t_ns = static_cast<std::int64_t>(rng_());
  c.v_H_mps = {small_(rng_), small_(rng_), small_(rng_)};
  if (i % 4 == 0) {
    c.vehicle_id = other_vehicle();  // plausible values, wrong vehicle
  } else {
    c.vehicle_id = config_.vehicle_id;
    const float bad = kSpecials[static_cast<std::size_t>(pick_(rng_))];
    switch (i % 4) {
      case 1:
        c.v_H_mps.x = bad;
        break;
      case 2:
        c.v_H_mps.z = bad;
        break;
      default:
        c.yaw_rate_radps = bad;
        break;
    }
  }
  commands_.write(c, malformed_commands_);

  hq::link::ModeRequest m{};
  m.station_id = c.station_id;
  m.sequence_number = huge_sequence();
  if (i % 3 == 0) {
    m.vehicle_id = other_vehicle();
    m.requested_mode = hq_msgs_MODE_LAND;  // valid, but not for this vehicle
  } else {
    m.vehicle_id = config_.vehicle_id;
    m.requested_mode = static_cast<hq_msgs_Mode>(i % 2 == 0 ? 5 + static_cast<int>(rng_() % 1000)
                                                            : -1 - static_cast<int>(rng_() % 1000));
  }
  if (i % 20 == 0) modes_.write(m, malformed_requests_);  // reliable: keep the rate sane

  hq::link::Heartbeat h{};
  h.vehicle_id = i % 2 == 0 ? other_vehicle() : config_.vehicle_id;
  h.role = static_cast<hq_msgs_Role>(2 + static_cast<int>(rng_() % 100));
  h.sender_id = c.station_id;
  h.sequence_number = huge_sequence();
  heartbeats_.write(h, malformed_heartbeats_);
}

// The well-formed attacks run at 100 Hz (commands) and slower (the rest).
void Fuzzer::send_well_formed(std::int64_t t_ns, std::int64_t start_ns) {
  if (t_ns < next_slow_ns_) return;
  next_slow_ns_ = std::max(next_slow_ns_ + 10'000'000, t_ns);
  ++slow_ticks_;
  if (on("commands")) send_hostile_command(t_ns, (t_ns - start_ns) / 1'000'000);
  if (on("replay") && slow_ticks_ % 10 == 0) send_replayed_command(t_ns);
  if (on("heartbeats") && slow_ticks_ % 10 == 0) send_heartbeat(t_ns);
  const bool tick_2hz = slow_ticks_ % 50 == 0;
  if (tick_2hz && on("requests") && session_ != 0) send_owner_request(t_ns);
  if (tick_2hz && on("replay")) send_replayed_request(t_ns);
  if (on("states") && slow_ticks_ % 2 == 0) send_forged_state(t_ns);
}

void Fuzzer::send_hostile_command(std::int64_t t_ns, std::int64_t phase_ms) {
  hq::link::VelocityCommand c{};
  c.vehicle_id = config_.vehicle_id;
  c.station_id = claimed_station();
  c.sequence_number = ++command_sequence_;
  c.t_ns = t_ns;
  const float v_x = 0.9F * static_cast<float>(config_.envelope.max_v_x_mps);
  const float v_y = 0.9F * static_cast<float>(config_.envelope.max_v_y_mps);
  if ((phase_ms / 1000) % 2 == 0) {
    c.v_H_mps = {v_x, 0.0F, 0.0F};  // straight ahead, into whatever is there
  } else {
    c.v_H_mps = {0.0F, (phase_ms / 125) % 2 == 0 ? v_y : -v_y, 0.0F};  // 4 Hz side to side
  }
  commands_.write(c, hostile_commands_);
}

void Fuzzer::send_replayed_command(std::int64_t t_ns) {
  hq::link::VelocityCommand c{};
  c.vehicle_id = config_.vehicle_id;
  c.station_id = claimed_station();
  c.sequence_number = ++command_sequence_;
  c.t_ns = t_ns - 5'000'000'000;  // recorded 5 s ago
  c.v_H_mps = {0.5F, 0.0F, 0.0F};
  commands_.write(c, replayed_commands_);
}

void Fuzzer::send_heartbeat(std::int64_t t_ns) {
  hq::link::Heartbeat h{};
  h.vehicle_id = config_.vehicle_id;
  h.role = hq_msgs_ROLE_GROUND;
  h.sender_id = claimed_station();
  h.sequence_number = ++heartbeat_sequence_;
  h.t_ns = t_ns;
  h.session_id = 0x666;
  heartbeats_.write(h, foreign_heartbeats_);
}

void Fuzzer::send_owner_request(std::int64_t t_ns) {
  hq::link::ModeRequest m{};
  m.vehicle_id = config_.vehicle_id;
  m.station_id = claimed_station();
  m.sequence_number = ++mode_sequence_;
  m.t_ns = t_ns;
  m.requested_mode = (slow_ticks_ / 50) % 2 == 0 ? hq_msgs_MODE_HOVER : hq_msgs_MODE_LAND;
  m.vehicle_session_id = session_;
  modes_.write(m, owner_requests_);
}

void Fuzzer::send_replayed_request(std::int64_t t_ns) {
  hq::link::ModeRequest m{};
  m.vehicle_id = config_.vehicle_id;
  m.station_id = 1;  // as if the operator's, made to an earlier instance
  m.sequence_number = ++mode_sequence_;
  m.t_ns = t_ns - 6'000'000'000;
  m.requested_mode = hq_msgs_MODE_LAND;
  m.vehicle_session_id = session_ != 0 ? session_ ^ 0x5a5a5a5a5a5a5a5aULL : 12345;
  modes_.write(m, replayed_requests_);
}

// Forged vehicle states to the ground, each of which would pull the operator's hand hard if the
// ground believed it, and now and then a forged event.
void Fuzzer::send_forged_state(std::int64_t t_ns) {
  hq::link::VehicleState& s = *state_;
  s = {};
  s.vehicle_id = config_.vehicle_id;
  s.t_ns = t_ns;
  s.mode = hq_msgs_MODE_TELEOP;
  s.clearance_m = -1.0F;
  s.height_m = kForgedMark;
  ++forged_sequence_;
  s.session_id = session_;
  s.sequence_number = last_sequence_ + 1;
  switch (forged_sequence_ % 6) {
    case 0:  // plausible values (17 m/s) from another session
      s.session_id = session_ ^ 0xdeadbeefULL;
      s.sequence_number = forged_sequence_;
      s.v_H_mps = {12.0F, -12.0F, 0.0F};
      break;
    case 1:
      s.sequence_number = last_sequence_ + 1'000'000;  // jumps ahead: would lock the real out
      s.v_H_mps = {12.0F, 0.0F, 0.0F};
      break;
    case 2:
      s.sequence_number = 1;  // backwards
      s.v_H_mps = {-12.0F, 0.0F, 0.0F};
      break;
    case 3:
      s.v_H_mps = {std::numeric_limits<float>::quiet_NaN(), 0.0F, 0.0F};
      break;
    case 4:
      s.v_H_mps = {1e6F, 1e6F, 0.0F};
      break;
    default:
      s.roll_rad = 7.0F;
      s.v_obs_H_mps = {0.0F, 900.0F, 0.0F};
      break;
  }
  if (s.session_id == 0) s.session_id = 0xbad;
  forged_states_.write(s, state_forgeries_);
  if (forged_sequence_ % 25 == 0) {
    hq::link::Event e{};
    e.vehicle_id = config_.vehicle_id;
    e.session_id = session_ ^ 0xfeedULL;
    e.sequence_number = forged_sequence_;
    e.t_ns = t_ns;
    e.severity = hq_msgs_SEVERITY_ERROR;
    hq::format_into(e.text, "FORGED: motors failing, land now");
    forged_events_.write(e, event_forgeries_);
  }
}

// What can be seen of the vehicle's verdicts, per topic and attack; the exit status: 0 if some
// sample reached a reader, kExitNotReached if none did (the vehicle was not tested).
int Fuzzer::report() const {
  Tally hostile_commands = hostile_commands_;
  // Speaking for another station, our commands cannot be told from its own in the states.
  hostile_commands.accepted = impersonating() ? -1 : static_cast<std::int64_t>(states_followed_);
  Tally owner_requests = owner_requests_;
  owner_requests.rejected = static_cast<std::int64_t>(requests_rejected_seen_);
  fmt::print(
      "hq-link-fuzz: attacks {} as station {} (strength {}) on vehicle {} over {}, session "
      "{:016x}; the vehicle named this station its commander in {} of {} states ({} change "
      "events)\n",
      o_.attacks_text, config_.station_id, config_.station_strength, config_.vehicle_id,
      hq::link::describe_security(config_, hq::security::Role::kStation).c_str(),
      static_cast<unsigned long long>(session_), static_cast<unsigned long long>(states_followed_),
      static_cast<unsigned long long>(states_seen_),
      static_cast<unsigned long long>(commander_events_));
  if (impersonating()) {
    fmt::print(
        "hq-link-fuzz: the samples claimed station {}; the vehicle reported {} intrusion events\n",
        claimed_station(), static_cast<unsigned long long>(intrusion_reports_));
  }
  fmt::print("  {:<14} {:<32} {:>10} {:>8} {:>10} {:>16} {:>16}\n", "topic", "attack", "sent",
             "refused", "no reader", "seen accepted", "seen rejected");
  Tally total{"", ""};
  const auto cell = [](std::int64_t v) { return v < 0 ? std::string("-") : std::to_string(v); };
  const std::array<const Tally*, 10> rows = {
      &malformed_commands_, &malformed_requests_, &malformed_heartbeats_, &hostile_commands,
      &owner_requests,      &replayed_requests_,  &replayed_commands_,    &foreign_heartbeats_,
      &state_forgeries_,    &event_forgeries_};
  for (const Tally* t : rows) {
    total.sent += t->sent;
    total.refused += t->refused;
    total.unmatched += t->unmatched;
    if (t->sent + t->refused == 0) continue;
    fmt::print("  {:<14} {:<32} {:10} {:8} {:10} {:>16} {:>16}\n", t->topic, t->attack,
               static_cast<unsigned long long>(t->sent),
               static_cast<unsigned long long>(t->refused),
               static_cast<unsigned long long>(t->unmatched), cell(t->accepted).c_str(),
               cell(t->rejected).c_str());
  }
  report_refusals();
  // "malformed samples sent" is the line earlier tests and scripts read.
  const std::string last_error = heartbeats_.last_error();
  fmt::print(
      "hq-link-fuzz: {} malformed samples sent, {} refused{}, {} of them sent with no reader "
      "matched\n",
      static_cast<unsigned long long>(total.sent), static_cast<unsigned long long>(total.refused),
      last_error.empty() ? "" : (" (writer: " + last_error + ")").c_str(),
      static_cast<unsigned long long>(total.unmatched));
  if (total.reached() == 0) {
    fmt::print(
        "hq-link-fuzz: NOT REACHED: no sample reached any reader and {} vehicle states were seen; "
        "the vehicle was not tested (no vehicle on domain {}, or the secured link refused this "
        "participant: see the refusals above and Cyclone's log)\n",
        static_cast<unsigned long long>(states_seen_), config_.domain_id);
    return kExitNotReached;
  }
  fmt::print("hq-link-fuzz: {} samples reached a reader\n",
             static_cast<unsigned long long>(total.reached()));
  return 0;
}

// The writers and readers the secured link would not let this participant create; each reason
// names the call and topic, e.g. "dds_create_writer(hq_vehicle_state): Not Allowed By Security".
void Fuzzer::report_refusals() const {
  const auto refused = [](const std::string& reason, const char* consequence) {
    if (!reason.empty()) {
      fmt::print("  refused by the secured link: {}{}\n", reason, consequence);
    }
  };
  refused(commands_.refusal(), "");
  refused(modes_.refusal(), "");
  refused(heartbeats_.refusal(), "");
  refused(forged_states_.refusal(), "");
  refused(forged_events_.refusal(), "");
  refused(states_.refusal(), " (the vehicle's verdicts are not observable)");
  refused(events_.refusal(), " (the vehicle's rejections are not observable)");
}

int run(int argc, char** argv) {
  FuzzOptions o;
  if (const std::optional<int> status = parse_options(argc, argv, o)) return *status;
  hq::link::LinkConfig config;
  config.station_id = 666;
  config.station_strength = 200;
  hq::link::apply_overrides(o.overrides, config);
  Fuzzer fuzzer(o, config);
  fuzzer.run();
  return fuzzer.report();
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-link-fuzz", argc, argv, run); }
