#pragma once
/// Strict YAML reading for component configs: every key read, unknown keys rejected, every
/// value range-checked, `_deg` keys converted to radians once. Errors are hq::InputError
/// naming file, key path, value and expectation, e.g.
///   config/onboard.yaml: obstacles.influence_distance_m = -1.2, expected > 0

#include "hq/base/error.hpp"

#include <yaml-cpp/yaml.h>

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace hq::config {

/// Most nodes a file may hold, an alias counted again (with its whole subtree) wherever it is
/// used. yaml-cpp shares an aliased node instead of copying it, so a "billion laughs" file of a
/// dozen lines parses at once but is 10^10 nodes to every walk over it (minutes in each loader).
/// The largest shipped file has about 450 nodes; a world at its 10000-primitive limit about
/// 300000. Counting stops at the budget: 10^6 nodes are walked in about 0.1 s.
constexpr std::size_t kMaxYamlNodes = 1000000;

/// Loads a YAML file; throws hq::InputError naming the file (and line where there is one) if it
/// is missing, a directory, unreadable, not valid YAML, empty or only comments, null (`~`), not
/// a mapping, holds more than one document, expands past kMaxYamlNodes, or has a key that is
/// not a scalar or appears twice in one mapping (check_keys).
YAML::Node load_yaml_file(const std::string& path);

/// Throws hq::InputError naming file:line, key path and value if a mapping in `node` has a key
/// that is a list or mapping, or a key twice (yaml-cpp silently keeps the first).
/// @param recursive  also every mapping nested in `node`.
void check_keys(const YAML::Node& node, const std::string& where, const std::string& prefix,
                bool recursive);

/// The top-level sections of files that several loaders share (config/onboard.yaml, a file
/// given to --link-config): a loader that reads one of them accepts the others, read
/// elsewhere, and rejects any other top-level key (StrictMap::finish_sections).
inline const std::vector<std::string> kSharedFileSections = {
    "odometry", "estimator", "obstacles", "memory", "control",    "hover_thrust",
    "modes",    "chain",     "markers",   "link",   "navigation", "seen_space"};

/// A YAML mapping read strictly. Create it, read keys with the typed getters (a missing key
/// keeps the default passed in), then call finish() to reject keys that were never read.
class StrictMap {
 public:
  /// @param where  file name used in messages; @param prefix  key path of this map ("" at root).
  /// Throws hq::InputError if `node` is neither absent nor a mapping; a null one (`odometry:`
  /// with nothing under it, `odometry: ~`) included: a section meant as defaults is left out.
  StrictMap(const YAML::Node& node, std::string where, std::string prefix = "");

  /// Optional keys: absent keeps `value`. Range is inclusive unless stated.
  void read(const std::string& key, double& value, double min, double max);
  /// Requires value > min_exclusive (and <= max).
  void read_positive(const std::string& key, double& value, double max = 1e300);
  void read(const std::string& key, int& value, int min, int max);
  void read(const std::string& key, bool& value);
  void read(const std::string& key, std::string& value, const std::vector<std::string>& allowed);
  /// A key ending in `_deg`: reads degrees, stores radians.
  void read_deg_as_rad(const std::string& key, double& value_rad, double min_deg, double max_deg);
  /// Fixed-length numeric list, e.g. `p_B_C_m: [0.1, 0, 0]`.
  void read_list(const std::string& key, double* values, int count);
  /// A list of any length (up to max_count) of integers in [min, max]; absent: left alone.
  void read_int_list(const std::string& key, std::vector<int>& values, int min, int max,
                     int max_count);

  /// Required variants: throw if the key is absent.
  void require(const std::string& key, double& value, double min, double max);
  void require(const std::string& key, int& value, int min, int max);
  void require_list(const std::string& key, double* values, int count);

  [[nodiscard]] bool has(const std::string& key) const;
  /// A nested mapping (must be a map if present; absent gives an empty map).
  [[nodiscard]] StrictMap child(const std::string& key);

  /// Marks a key as known without reading it (keys of a foreign layout that carry nothing).
  void skip(const std::string& key);

  /// Throws on any key of this map that no getter asked for (Drake-style strictness), naming
  /// the closest known key when it looks misspelled.
  void finish() const;
  /// finish() for a file several loaders share: keys in `read_elsewhere` are sections another
  /// loader reads; any other unread key (a misspelled `odometri:`) is rejected.
  void finish_except(const std::vector<std::string>& read_elsewhere) const;
  /// finish_except(kSharedFileSections): for the root of a file whose one section is read.
  void finish_sections() const;

  /// "file: prefix.key" for messages.
  [[nodiscard]] std::string describe(const std::string& key) const;

 private:
  std::optional<YAML::Node> find(const std::string& key);
  YAML::Node node_;
  std::string where_;
  std::string prefix_;
  std::vector<std::string> seen_;
};

}  // namespace hq::config
