#pragma once
/// Link settings: from the `link:` section of a YAML file, then overridden on the command line.
///   link: {domain_id: 0, vehicle_id: 1, station_id: 1, station_strength: 100,
///          command_deadline_ms: 100, command_lease_ms: 500, heartbeat_lease_ms: 1000,
///          stations: [1, 2],   # station ids allowed to command this vehicle; absent/[]: any
///          envelope: {max_v_x_mps: 2.0, max_v_y_mps: 2.0, max_v_z_mps: 1.0,
///                     max_yaw_rate_radps: 1.5},
///          impair: {delay_ms: 0, jitter_ms: 0, loss: 0, seed: 1},   # tests and demos only
///          security: {enabled: true, keys_dir: keys, identity: vehicle_1},
///          ros2: {enabled: false, namespace: hq1, station_id: 250, record: true,
///                node_name: haptiquad_1}}
/// security: DDS Security (hq/security/keys.hpp) is on unless `enabled: false` or --insecure;
/// keys come from `keys_dir` laid out by hq-keys (identity defaults to vehicle_<vehicle_id> on
/// board, station_<station_id> on the ground) and/or the single paths identity_ca, certificate,
/// private_key, governance, permissions, permissions_ca (relative to the working directory),
/// which override the keys_dir ones. library_dir is where Cyclone's plugins are.
/// ros2 (on board only): ROS 2-compatible topics beside the link's (onboard/ros2_bridge), and
/// TwistStamped commands taken as the station `station_id` of the lowest priority. Needs plain
/// DDS (--insecure): a secured vehicle puts its endpoints in its vehicle partition and its
/// permissions grant only the hq_* topics, so no ROS 2 node could match them.

#include "hq/config/strict_yaml.hpp"
#include "hq/link/impairment.hpp"
#include "hq/link/messages.hpp"

#include <CLI/CLI.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace hq::link {

/// DDS domain ids usable with the default port mapping (Cyclone rejects larger ones).
inline constexpr int kMaxDomainId = 232;

/// Where the DDS Security plugins of Debian's Cyclone DDS are (found by CMake).
extern const char* const kDefaultSecurityLibraryDir;

struct SecurityConfig {
  bool enabled = true;      ///< Off only for the loopback demo and tests (--insecure).
  std::string keys_dir;     ///< A directory made by hq-keys.
  std::string identity;     ///< Folder in keys_dir; empty: from the role and id.
  std::string identity_ca;  ///< Each file below overrides the keys_dir one when set.
  std::string certificate;
  std::string private_key;
  std::string governance;
  std::string permissions;
  std::string permissions_ca;
  std::string library_dir = kDefaultSecurityLibraryDir;

  /// Whether any key file or keys_dir is configured.
  [[nodiscard]] bool has_keys() const;
};

struct Ros2Config {
  bool enabled = false;  ///< Publish rt/<namespace>/... and take cmd_vel_in (--ros2).
  /// ROS namespace of the topics (rt/<namespace>/odom); empty: "hq<vehicle_id>". Segments of
  /// [A-Za-z_][A-Za-z0-9_]* joined by '/', no leading or trailing '/'.
  std::string ros_namespace;
  /// The station id ROS 2 commands are taken as (in link.stations when that list is given).
  std::uint32_t station_id = 250;
  /// With --record on board: also DIR/ros2.mcap, the flight as a ROS 2 bag (the messages this
  /// bridge publishes, whether or not it runs; onboard/onboard_log). On by default: a ROS user
  /// expects `ros2 bag info` to take the record; off saves the disk its second image copy takes.
  bool record = true;
  /// The ROS node the vehicle is in `ros2 node list` (ros_discovery_info, namespace "/"); empty:
  /// "haptiquad_<vehicle_id>". A ROS name segment [A-Za-z_][A-Za-z0-9_]*.
  std::string node_name;
};

/// The ROS namespace in use: config.ros2.ros_namespace, or "hq<vehicle_id>" when empty.
struct LinkConfig;
std::string ros2_namespace(const LinkConfig& config);
/// The ROS node name in use: config.ros2.node_name, or "haptiquad_<vehicle_id>" when empty.
std::string ros2_node_name(const LinkConfig& config);

struct LinkConfig {
  int domain_id = 0;             ///< DDS domain, 0..kMaxDomainId.
  std::uint32_t vehicle_id = 1;  ///< Key of every topic: which vehicle this is / commands.
  std::uint32_t station_id = 1;  ///< This ground station (unused on board).
  int station_strength = 100;    ///< EXCLUSIVE ownership strength of this station's commands.
  std::int64_t command_deadline_ns = 100'000'000;   ///< Expected command period bound.
  std::int64_t command_lease_ns = 500'000'000;      ///< Liveliness lease of a command writer.
  std::int64_t heartbeat_lease_ns = 1'000'000'000;  ///< Liveliness lease of heartbeat writers.
  /// On board: station ids whose commands, mode requests and heartbeats count; empty = any.
  std::vector<std::uint32_t> stations;
  CommandEnvelope envelope;     ///< Limits applied by validate(VelocityCommand).
  ImpairmentConfig impairment;  ///< Receive-side link impairment (none by default).
  SecurityConfig security;      ///< DDS Security (on by default).
  Ros2Config ros2;              ///< ROS 2 topics beside the link's (off by default).
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
  std::optional<std::string> link_impair;    ///< "delay_ms=150,jitter_ms=30,loss=0.05[,seed=N]"
  std::optional<std::string> security_dir;   ///< keys_dir
  std::optional<std::string> identity;       ///< identity in keys_dir
  bool insecure = false;                     ///< security.enabled = false
  bool ros2 = false;                         ///< ros2.enabled = true
};

/// Adds --domain-id, --vehicle-id, --station-id, --station-strength, --stations,
/// --command-deadline-ms (range-checked by CLI11), --link-impair (checked by apply_overrides),
/// --security-dir, --identity, --insecure and --ros2 to `app`, storing into
/// `overrides` (which must outlive parsing).
/// Which end of the link a program is: options of the other end only are not offered, so a
/// station given --ros2 or --stations (or a vehicle --station-id) is refused, not ignored.
enum class LinkSide { kVehicle, kStation, kEither };
void add_link_options(CLI::App& app, LinkOverrides& overrides, LinkSide side = LinkSide::kEither);

/// Applies the options that were given, then checks the ranges again (hq::InputError).
void apply_overrides(const LinkOverrides& overrides, LinkConfig& config);

/// Throws hq::InputError naming the field if any setting is out of range.
void check_config(const LinkConfig& config);

}  // namespace hq::link
