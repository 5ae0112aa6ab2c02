#pragma once
/// Link settings: from the `link:` section of a YAML file, then overridden on the command line.
///   link: {domain_id: 0, vehicle_id: 1, station_id: 1, station_strength: 100,
///          command_deadline_ms: 100, command_lease_ms: 500, heartbeat_lease_ms: 1000,
///          stations: [1, 2],   # station ids allowed to command this vehicle; absent/[]: any
///          envelope: {max_v_x_mps: 2.0, max_v_y_mps: 2.0, max_v_z_mps: 1.0,
///                     max_yaw_rate_radps: 1.5},
///          impair: {delay_ms: 0, jitter_ms: 0, loss: 0, seed: 1}}   # tests and demos only

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "hq/config/strict_yaml.hpp"
#include "hq/link/impairment.hpp"
#include "hq/link/messages.hpp"

namespace hq::link {

/// DDS domain ids usable with the default port mapping (Cyclone rejects larger ones).
inline constexpr int kMaxDomainId = 232;

struct LinkConfig {
  int domain_id = 0;                ///< DDS domain, 0..kMaxDomainId.
  std::uint32_t vehicle_id = 1;     ///< Key of every topic: which vehicle this is / commands.
  std::uint32_t station_id = 1;     ///< This ground station (unused on board).
  int station_strength = 100;       ///< EXCLUSIVE ownership strength of this station's commands.
  std::int64_t command_deadline_ns = 100'000'000;  ///< Expected command period bound.
  std::int64_t command_lease_ns = 500'000'000;     ///< Liveliness lease of a command writer.
  std::int64_t heartbeat_lease_ns = 1'000'000'000; ///< Liveliness lease of heartbeat writers.
  /// On board: station ids whose commands, mode requests and heartbeats count; empty = any.
  std::vector<std::uint32_t> stations;
  CommandEnvelope envelope;         ///< Limits applied by validate(VelocityCommand).
  ImpairmentConfig impairment;      ///< Receive-side link impairment (none by default).
};

/// Reads a `link:` mapping strictly (unknown keys, out-of-range values throw hq::InputError
/// naming file, key, value and expectation) and calls section.finish().
void read_config(config::StrictMap& section, LinkConfig& out);

/// Reads the `link:` section of a YAML file into a LinkConfig (defaults for absent keys);
/// other top-level sections belong to other components and are left alone.
LinkConfig load_link_config(const std::string& path);

/// Command-line values that override the YAML ones; unset options keep the file's value.
struct LinkOverrides {
  std::optional<int> domain_id;
  std::optional<std::uint32_t> vehicle_id;
  std::optional<std::uint32_t> station_id;
  std::optional<int> station_strength;
  std::optional<double> command_deadline_ms;
  std::optional<std::vector<int>> stations;  ///< --stations 1,2
  std::optional<std::string> link_impair;  ///< "delay_ms=150,jitter_ms=30,loss=0.05[,seed=N]"
};

/// Adds --domain-id, --vehicle-id, --station-id, --station-strength, --stations, --command-deadline-ms
/// (range-checked by CLI11), --link-impair (checked by apply_overrides) to `app`, storing into
/// `overrides` (which must outlive parsing).
void add_link_options(CLI::App& app, LinkOverrides& overrides);

/// Applies the options that were given, then checks the ranges again (hq::InputError).
void apply_overrides(const LinkOverrides& overrides, LinkConfig& config);

/// Throws hq::InputError naming the field if any setting is out of range.
void check_config(const LinkConfig& config);

}  // namespace hq::link
