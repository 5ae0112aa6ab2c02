// hq-link-fuzz: a hostile or broken station for the integration tests. For --duration-s it
// floods the topics a vehicle reads with malformed samples: NaN, Inf, huge and out-of-envelope
// velocities, out-of-range mode and role enums, huge sequence numbers and stamps, and otherwise
// plausible samples for other vehicle ids. It never sends a sample the vehicle should act on, so
// a vehicle that is working keeps flying as its real operator commands (or holds, if the fuzzer's
// higher ownership strength takes the command instance away from the real station).
//   hq-link-fuzz --domain-id N [--vehicle-id 1] [--station-strength 200] [--duration-s 4]
//                [--rate-hz 2000] [--seed 1]
#include "hq/base/tool_main.hpp"
#include "hq/link/config.hpp"
#include "hq/link/link.hpp"

#include <CLI/CLI.hpp>

#include <time.h>

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>

namespace {

std::int64_t now_ns() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec * 1'000'000'000LL + t.tv_nsec;
}

int run(int argc, char** argv) {
  CLI::App app{"hq-link-fuzz: malformed samples for a vehicle's link"};
  hq::link::LinkOverrides overrides;
  hq::link::add_link_options(app, overrides);
  double duration_s = 4.0;
  double rate_hz = 2000.0;
  unsigned seed = 1;
  app.add_option("--duration-s", duration_s)->check(CLI::Range(0.1, 600.0));
  app.add_option("--rate-hz", rate_hz, "samples per second per topic")->check(CLI::Range(1.0, 1e5));
  app.add_option("--seed", seed);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  hq::link::LinkConfig config;
  config.station_id = 666;
  config.station_strength = 200;
  hq::link::apply_overrides(overrides, config);

  hq::link::Participant participant(config.domain_id);
  hq::link::Topic<hq::link::VelocityCommand> command_topic(participant);
  hq::link::Topic<hq::link::ModeRequest> mode_topic(participant);
  hq::link::Topic<hq::link::Heartbeat> heartbeat_topic(participant);
  hq::link::Writer<hq::link::VelocityCommand> commands(
      participant, command_topic, hq::link::command_qos(config, hq::link::End::kWriter));
  hq::link::Writer<hq::link::ModeRequest> modes(participant, mode_topic,
                                                hq::link::mode_request_qos());
  hq::link::Writer<hq::link::Heartbeat> heartbeats(participant, heartbeat_topic,
                                                   hq::link::heartbeat_qos(config));

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

  // Cyclone's serialiser refuses some of these (enum values outside the type), so they never
  // reach the wire: counted apart, so the summary says what was actually delivered.
  std::uint64_t sent = 0;
  std::uint64_t refused = 0;
  const auto count = [&](bool ok) { ok ? ++sent : ++refused; };
  const std::int64_t period_ns = static_cast<std::int64_t>(1e9 / rate_hz);
  const std::int64_t end_ns = now_ns() + static_cast<std::int64_t>(duration_s * 1e9);
  std::int64_t next_ns = now_ns();
  for (std::uint64_t i = 0; now_ns() < end_ns; ++i) {
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
    count(commands.write(c));

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
    if (i % 20 == 0) count(modes.write(m));  // reliable: keep the rate sane

    hq::link::Heartbeat h{};
    h.vehicle_id = i % 2 == 0 ? other_vehicle() : config.vehicle_id;
    h.role = static_cast<hq_msgs_Role>(2 + static_cast<int>(rng() % 100));
    h.sender_id = c.station_id;
    h.sequence_number = huge_sequence();
    count(heartbeats.write(h));

    next_ns += period_ns;
    timespec deadline{};
    deadline.tv_sec = next_ns / 1'000'000'000LL;
    deadline.tv_nsec = next_ns % 1'000'000'000LL;
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, nullptr) == EINTR) {
    }
  }
  std::printf("hq-link-fuzz: %llu malformed samples sent, %llu refused by the writer (%s)\n",
              static_cast<unsigned long long>(sent), static_cast<unsigned long long>(refused),
              heartbeats.last_error());
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return hq::run_tool("hq-link-fuzz", argc, argv, run); }
