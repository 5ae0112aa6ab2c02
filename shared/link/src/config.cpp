#include "hq/link/config.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <utility>

namespace hq::link {

namespace {

// Deadlines and leases are written in milliseconds in files and on the command line.
constexpr double kMinPeriodMs = 1.0;
constexpr double kMaxPeriodMs = 60'000.0;
constexpr int kMaxId = std::numeric_limits<int>::max();
constexpr int kMaxStations = 16;

std::int64_t ms_to_ns(double ms) { return static_cast<std::int64_t>(std::llround(ms * 1e6)); }
double ns_to_ms(std::int64_t ns) { return static_cast<double>(ns) * 1e-6; }

void read_ms(config::StrictMap& map, const std::string& key, std::int64_t& value_ns) {
  double ms = ns_to_ms(value_ns);
  map.read(key, ms, kMinPeriodMs, kMaxPeriodMs);
  value_ns = ms_to_ns(ms);
}

bool valid_ros_namespace(const std::string& ns) {
  if (ns.empty() || ns.front() == '/' || ns.back() == '/') return false;
  bool segment_start = true;
  for (const char c : ns) {
    if (c == '/') {
      if (segment_start) return false;  // "a//b"
      segment_start = true;
      continue;
    }
    const bool letter = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_';
    const bool digit = c >= '0' && c <= '9';
    if (!letter && !(digit && !segment_start)) return false;
    segment_start = false;
  }
  return true;
}

template <typename Fail>
void check_ros2(const LinkConfig& config, const Fail& fail) {
  const Ros2Config& r = config.ros2;
  if (!r.ros_namespace.empty() && !valid_ros_namespace(r.ros_namespace)) {
    fail("ros2.namespace", "\"" + r.ros_namespace + "\"",
         "ROS name segments [A-Za-z_][A-Za-z0-9_]* joined by '/' (no leading '/')");
  }
  if (!r.node_name.empty() &&
      (!valid_ros_namespace(r.node_name) || r.node_name.find('/') != std::string::npos)) {
    fail("ros2.node_name", "\"" + r.node_name + "\"",
         "one ROS name segment [A-Za-z_][A-Za-z0-9_]*");
  }
  if (r.station_id == 0) fail("ros2.station_id", "0", ">= 1 (0 means no station)");
  if (!r.enabled) return;
  if (config.security.enabled) {
    throw InputError(
        "link.ros2.enabled with DDS Security on: the ROS 2 topics need plain DDS (--insecure, "
        "link.security.enabled: false). A secured vehicle keeps its endpoints in its vehicle "
        "partition and its permissions grant only the hq_* topics, so no ROS 2 node could "
        "read or command it");
  }
  if (!config.stations.empty() && std::find(config.stations.begin(), config.stations.end(),
                                            r.station_id) == config.stations.end()) {
    fail("ros2.station_id", std::to_string(r.station_id),
         "one of link.stations (the ROS 2 commands come as this station)");
  }
}

}  // namespace

std::string ros2_namespace(const LinkConfig& config) {
  return config.ros2.ros_namespace.empty() ? "hq" + std::to_string(config.vehicle_id)
                                           : config.ros2.ros_namespace;
}

std::string ros2_node_name(const LinkConfig& config) {
  return config.ros2.node_name.empty() ? "haptiquad_" + std::to_string(config.vehicle_id)
                                       : config.ros2.node_name;
}

const char* const kDefaultSecurityLibraryDir = HQ_DDS_SECURITY_LIBRARY_DIR;

bool SecurityConfig::has_keys() const {
  return !keys_dir.empty() || !identity_ca.empty() || !certificate.empty() ||
         !private_key.empty() || !governance.empty() || !permissions.empty() ||
         !permissions_ca.empty();
}

void read_config(config::StrictMap& section, LinkConfig& out) {
  section.read("domain_id", out.domain_id, 0, kMaxDomainId);
  int vehicle_id = static_cast<int>(out.vehicle_id);
  section.read("vehicle_id", vehicle_id, 0, kMaxId);
  out.vehicle_id = static_cast<std::uint32_t>(vehicle_id);
  int station_id = static_cast<int>(out.station_id);
  section.read("station_id", station_id, 0, kMaxId);
  out.station_id = static_cast<std::uint32_t>(station_id);
  section.read("station_strength", out.station_strength, 0, kMaxId);
  std::vector<int> stations(out.stations.begin(), out.stations.end());
  section.read_int_list("stations", stations, 1, kMaxId, kMaxStations);
  out.stations.assign(stations.begin(), stations.end());
  read_ms(section, "command_deadline_ms", out.command_deadline_ns);
  read_ms(section, "command_lease_ms", out.command_lease_ns);
  read_ms(section, "heartbeat_lease_ms", out.heartbeat_lease_ns);
  config::StrictMap envelope = section.child("envelope");
  envelope.read_positive("max_v_x_mps", out.envelope.max_v_x_mps, 20.0);
  envelope.read_positive("max_v_y_mps", out.envelope.max_v_y_mps, 20.0);
  envelope.read_positive("max_v_z_mps", out.envelope.max_v_z_mps, 10.0);
  envelope.read_positive("max_yaw_rate_radps", out.envelope.max_yaw_rate_radps, 10.0);
  envelope.finish();
  config::StrictMap impair = section.child("impair");
  impair.read("delay_ms", out.impairment.delay_ms, 0.0, 10'000.0);
  impair.read("jitter_ms", out.impairment.jitter_ms, 0.0, 10'000.0);
  impair.read("loss", out.impairment.loss, 0.0, 1.0);
  int seed = static_cast<int>(out.impairment.seed);
  impair.read("seed", seed, 0, kMaxId);
  out.impairment.seed = static_cast<std::uint32_t>(seed);
  impair.finish();
  config::StrictMap security = section.child("security");
  security.read("enabled", out.security.enabled);
  for (auto [key, value] : {std::pair{"keys_dir", &out.security.keys_dir},
                            std::pair{"identity", &out.security.identity},
                            std::pair{"identity_ca", &out.security.identity_ca},
                            std::pair{"certificate", &out.security.certificate},
                            std::pair{"private_key", &out.security.private_key},
                            std::pair{"governance", &out.security.governance},
                            std::pair{"permissions", &out.security.permissions},
                            std::pair{"permissions_ca", &out.security.permissions_ca},
                            std::pair{"library_dir", &out.security.library_dir}}) {
    security.read(key, *value, {});
  }
  security.finish();
  config::StrictMap ros2 = section.child("ros2");
  ros2.read("enabled", out.ros2.enabled);
  ros2.read("namespace", out.ros2.ros_namespace, {});
  int ros2_station = static_cast<int>(out.ros2.station_id);
  ros2.read("station_id", ros2_station, 1, kMaxId);
  out.ros2.station_id = static_cast<std::uint32_t>(ros2_station);
  ros2.read("record", out.ros2.record);
  ros2.read("node_name", out.ros2.node_name, {});
  ros2.finish();
  section.finish();
}

LinkConfig load_link_config(const std::string& path) {
  const YAML::Node node = config::load_yaml_file(path);
  config::StrictMap root(node, path);
  // The file may hold anything else (one file for several tools), but a --link-config without
  // a link: section is a mistake (a misspelled lnik:) that would fly on the defaults.
  if (!root.has("link")) {
    std::string keys;
    for (auto it = node.begin(); it != node.end(); ++it) {
      keys += (keys.empty() ? "" : ", ") + it->first.Scalar();
    }
    throw InputError(path + ": link section missing, expected a `link:` mapping (top-level keys: " +
                     (keys.empty() ? std::string("none") : keys) + ")");
  }
  config::StrictMap section = root.child("link");
  LinkConfig config;
  read_config(section, config);
  return config;
}

void add_link_options(CLI::App& app, LinkOverrides& overrides, LinkSide side) {
  const bool vehicle = side != LinkSide::kStation;
  const bool station = side != LinkSide::kVehicle;
  app.add_option("--domain-id", overrides.domain_id, "DDS domain id")
      ->check(CLI::Range(0, kMaxDomainId));
  app.add_option("--vehicle-id", overrides.vehicle_id, "vehicle id (key of every topic)");
  if (station) {
    app.add_option("--station-id", overrides.station_id, "ground station id");
    app.add_option("--station-strength", overrides.station_strength,
                   "ownership strength of this station's commands (higher wins)")
        ->check(CLI::Range(0, kMaxId));
  }
  if (vehicle) {
    app.add_option("--stations", overrides.stations,
                   "on board: station ids allowed to command, e.g. 1,2 (default: any)")
        ->delimiter(',')
        ->check(CLI::Range(1, kMaxId));
  }
  app.add_option("--command-deadline-ms", overrides.command_deadline_ms,
                 "command deadline in milliseconds")
      ->check(CLI::Range(kMinPeriodMs, kMaxPeriodMs));
  app.add_option("--security-dir", overrides.security_dir,
                 "DDS Security keys made by hq-keys (link.security.keys_dir)");
  app.add_option(
      "--identity", overrides.identity,
      "identity in --security-dir (default vehicle_<vehicle id> / station_<station id>)");
  app.add_flag("--insecure", overrides.insecure,
               "plain DDS without authentication or encryption: loopback demo and tests only");
  if (vehicle) {
    app.add_flag(
        "--ros2", overrides.ros2,
        "also publish ROS 2 topics rt/<link.ros2.namespace>/odom, imu, camera, obstacles, "
        "rt/tf, take Twist on cmd_vel, TwistStamped on cmd_vel_in and mode texts on mode_request "
        "(link.ros2.enabled; needs --insecure)");
  }
  app.add_option("--link-impair", overrides.link_impair,
                 "impair received samples for tests and demos: "
                 "delay_ms=150,jitter_ms=30,loss=0.05[,seed=N] (one way, this process's side)");
}

void apply_overrides(const LinkOverrides& overrides, LinkConfig& config) {
  if (overrides.domain_id) config.domain_id = *overrides.domain_id;
  if (overrides.vehicle_id) config.vehicle_id = *overrides.vehicle_id;
  if (overrides.station_id) config.station_id = *overrides.station_id;
  if (overrides.station_strength) config.station_strength = *overrides.station_strength;
  if (overrides.stations)
    config.stations.assign(overrides.stations->begin(), overrides.stations->end());
  if (overrides.command_deadline_ms) {
    if (!std::isfinite(*overrides.command_deadline_ms)) {
      throw InputError("--command-deadline-ms: expected a finite number");
    }
    config.command_deadline_ns = ms_to_ns(*overrides.command_deadline_ms);
  }
  if (overrides.link_impair) config.impairment = parse_impairment(*overrides.link_impair);
  if (overrides.security_dir) config.security.keys_dir = *overrides.security_dir;
  if (overrides.identity) config.security.identity = *overrides.identity;
  if (overrides.insecure) {
    if (overrides.security_dir || overrides.identity) {
      throw InputError("--insecure: contradicts --security-dir/--identity");
    }
    config.security.enabled = false;
  }
  if (overrides.ros2) config.ros2.enabled = true;
  check_config(config);
}

void check_config(const LinkConfig& config) {
  const auto fail = [](const std::string& field, const std::string& value,
                       const std::string& expected) {
    throw InputError("link." + field + " = " + value + ", expected " + expected);
  };
  if (config.domain_id < 0 || config.domain_id > kMaxDomainId) {
    fail("domain_id", std::to_string(config.domain_id), "in [0, 232]");
  }
  if (config.station_strength < 0) {
    fail("station_strength", std::to_string(config.station_strength), ">= 0");
  }
  const auto check_period = [&](const char* field, std::int64_t ns) {
    if (ns < ms_to_ns(kMinPeriodMs) || ns > ms_to_ns(kMaxPeriodMs)) {
      std::ostringstream ms;
      ms << ns_to_ms(ns);
      fail(field, ms.str(), "in [1, 60000] ms");
    }
  };
  if (config.stations.size() > static_cast<std::size_t>(kMaxStations)) {
    fail("stations", std::to_string(config.stations.size()) + " ids",
         "at most " + std::to_string(kMaxStations));
  }
  for (const std::uint32_t id : config.stations) {
    if (id == 0) fail("stations", "[.. 0 ..]", "ids >= 1 (0 means no station)");
  }
  check_period("command_deadline_ms", config.command_deadline_ns);
  check_period("command_lease_ms", config.command_lease_ns);
  check_period("heartbeat_lease_ms", config.heartbeat_lease_ns);
  check_impairment(config.impairment, "link.impair");
  check_ros2(config, fail);
}

}  // namespace hq::link
