#include "hq/config/strict_yaml.hpp"

#include "hq/config/data_path.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <unordered_map>
#include <vector>

namespace hq::config {

namespace {
std::string to_text(const YAML::Node& node);

std::string join_key(const std::string& prefix, const std::string& key) {
  return prefix.empty() ? key : prefix + "." + key;
}

std::string kind_of(const YAML::Node& node) {
  return node.IsSequence() ? "a list" : node.IsMap() ? "a mapping" : "not a scalar";
}
}  // namespace

void check_keys(const YAML::Node& node, const std::string& where, const std::string& prefix,
                bool recursive) {
  if (node.IsSequence() && recursive) {
    for (std::size_t i = 0; i < node.size(); ++i) {
      check_keys(node[i], where, prefix + "[" + std::to_string(i) + "]", true);
    }
    return;
  }
  if (!node.IsMap()) return;
  std::unordered_map<std::string, int> keys;  // key -> line (1-based)
  for (auto it = node.begin(); it != node.end(); ++it) {
    const YAML::Node key = it->first;
    const int line = key.Mark().line + 1;
    if (!key.IsScalar()) {
      throw InputError(where + ":" + std::to_string(line) + ": " +
                       (prefix.empty() ? std::string("top level") : prefix) + " has key " +
                       to_text(key) + ", which is " + kind_of(key) + ", expected a scalar key");
    }
    const std::string& name = key.Scalar();
    const auto [first, inserted] = keys.emplace(name, line);
    if (!inserted) {
      // yaml-cpp keeps the first of two equal keys without a word; a config must not.
      throw InputError(where + ":" + std::to_string(line) + ": " + join_key(prefix, name) + " = " +
                       to_text(it->second) + " duplicates the key on line " +
                       std::to_string(first->second) + ", expected each key once");
    }
    if (recursive) check_keys(it->second, where, join_key(prefix, name), true);
  }
}

namespace {
std::string line_of(const YAML::Mark& mark) {
  std::string text;
  if (!mark.is_null()) text.append(":").append(std::to_string(mark.line + 1));
  return text;
}

constexpr const char* kNullSectionText =
    " is empty (null), expected a mapping (leave the key out for its defaults)";

// Walks the tree as every loader will, an alias's subtree again wherever it is used, and stops
// at kMaxYamlNodes: refusing a bomb costs no more than the budget, and a node that contains
// itself (`a: &a [*a]`) ends the walk instead of the stack. The error names the top-level entry
// whose expansion crosses the budget.
void check_node_budget(const YAML::Node& root, const std::string& path) {
  std::size_t count = 1;
  std::vector<YAML::Node> pending;
  for (auto entry = root.begin(); entry != root.end(); ++entry) {
    pending = {entry->first, entry->second};
    count += 2;
    while (!pending.empty() && count <= kMaxYamlNodes) {
      const YAML::Node node = pending.back();
      pending.pop_back();
      if (!node.IsMap() && !node.IsSequence()) continue;
      for (auto child = node.begin(); child != node.end() && count <= kMaxYamlNodes; ++child) {
        if (node.IsMap()) {
          pending.push_back(child->first);
          pending.push_back(child->second);
          count += 2;
        } else {
          pending.push_back(*child);
          ++count;
        }
      }
    }
    if (count > kMaxYamlNodes) {
      const std::string key = entry->first.IsScalar() ? entry->first.Scalar() : "an entry";
      throw InputError(path + line_of(entry->first.Mark()) + ": " + key + " expands past " +
                       std::to_string(kMaxYamlNodes) +
                       " YAML nodes (each alias counted wherever it is used), expected at most " +
                       std::to_string(kMaxYamlNodes) + "; an alias bomb?");
    }
  }
}

// The one mapping a config file holds. yaml-cpp's Load reads the first document only and gives
// an empty file as null, which read as "every setting at its default".
YAML::Node single_mapping(const std::vector<YAML::Node>& documents, const std::string& path) {
  if (documents.empty()) {
    throw InputError(path + ": has no YAML document (empty or only comments), expected a mapping");
  }
  if (documents.size() > 1) {
    throw InputError(path + line_of(documents[1].Mark()) +
                     ": a second YAML document, expected one (`---` starts another)");
  }
  const YAML::Node& root = documents.front();
  if (root.IsNull()) throw InputError(path + ": top level is null, expected a YAML mapping");
  if (!root.IsMap()) throw InputError(path + ": expected a YAML mapping at the top level");
  return root;
}
}  // namespace

YAML::Node load_yaml_file(const std::string& given_path) {
  const std::string path = resolve_data_path(given_path);
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status)) {
    throw InputError(path + ": file not found (" + data_dirs_text() + ")");
  }
  if (std::filesystem::is_directory(status)) {
    throw InputError(path + ": is a directory, expected a YAML file");
  }
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot read: " + std::strerror(errno));
  try {
    // yaml-cpp shares an aliased node rather than copying it, so parsing is linear in the file;
    // the walks after it are what a bomb makes long, hence the budget before any of them.
    YAML::Node root = single_mapping(YAML::LoadAll(in), path);
    check_node_budget(root, path);
    check_keys(root, path, "", true);
    return root;
  } catch (const YAML::Exception& e) {
    std::ostringstream message;
    message << path << ":" << (e.mark.line + 1) << ": not valid YAML: " << e.msg;
    throw InputError(message.str());
  } catch (const std::ios_base::failure& e) {
    throw InputError(path + ": cannot read: " + e.what());
  }
}

StrictMap::StrictMap(const YAML::Node& node, std::string where, std::string prefix)
    : node_(node), where_(std::move(where)), prefix_(std::move(prefix)) {
  const std::string name = prefix_.empty() ? std::string("top level") : prefix_;
  if (node_.IsDefined() && node_.IsNull()) {
    // `odometry:` with nothing under it read as "all defaults"; more likely lost indentation.
    throw InputError(where_ + ": " + name + kNullSectionText);
  }
  if (node_.IsDefined() && !node_.IsMap()) {
    throw InputError(where_ + ": " + name + " = " + to_text(node_) + ", expected a mapping");
  }
  // Maps built in memory (YAML::Load) have not been through load_yaml_file's check.
  check_keys(node_, where_, prefix_, false);
}

std::string StrictMap::describe(const std::string& key) const {
  return where_ + ": " + (prefix_.empty() ? key : prefix_ + "." + key);
}

bool StrictMap::has(const std::string& key) const {
  const YAML::Node& map = node_;
  return map.IsMap() && map[key].IsDefined();
}

std::optional<YAML::Node> StrictMap::find(const std::string& key) {
  seen_.push_back(key);
  if (!node_.IsMap()) return std::nullopt;
  // Indexing a const node never inserts, unlike operator[] on a mutable one.
  const YAML::Node& map = node_;
  YAML::Node value = map[key];
  if (!value.IsDefined()) return std::nullopt;
  return value;
}

void StrictMap::skip(const std::string& key) { seen_.push_back(key); }

namespace {
std::string to_text(const YAML::Node& node) {
  if (!node.IsDefined()) return "(absent)";
  if (node.IsScalar()) return node.Scalar();
  YAML::Emitter out;
  out << YAML::Flow << node;
  return out.c_str();
}

double parse_double(const YAML::Node& node, const std::string& where) {
  double value = 0.0;
  if (!node.IsScalar() || !YAML::convert<double>::decode(node, value)) {
    throw InputError(where + " = " + to_text(node) + ", expected a number");
  }
  if (!std::isfinite(value)) throw InputError(where + " = " + to_text(node) + ", expected finite");
  return value;
}

std::string range_text(double min, double max) {
  std::ostringstream s;
  s << "expected in [" << min << ", " << max << "]";
  return s.str();
}
}  // namespace

void StrictMap::read(const std::string& key, double& value, double min, double max) {
  const std::optional<YAML::Node> node = find(key);
  if (!node) return;
  const double v = parse_double(*node, describe(key));
  if (v < min || v > max)
    throw InputError(describe(key) + " = " + to_text(*node) + ", " + range_text(min, max));
  value = v;
}

void StrictMap::read_positive(const std::string& key, double& value, double max) {
  const std::optional<YAML::Node> node = find(key);
  if (!node) return;
  const double v = parse_double(*node, describe(key));
  if (!(v > 0.0)) throw InputError(describe(key) + " = " + to_text(*node) + ", expected > 0");
  if (v > max)
    throw InputError(describe(key) + " = " + to_text(*node) + ", " + range_text(0.0, max));
  value = v;
}

void StrictMap::read(const std::string& key, int& value, int min, int max) {
  const std::optional<YAML::Node> node = find(key);
  if (!node) return;
  int v = 0;
  if (!node->IsScalar() || !YAML::convert<int>::decode(*node, v)) {
    throw InputError(describe(key) + " = " + to_text(*node) + ", expected an integer");
  }
  if (v < min || v > max) {
    throw InputError(describe(key) + " = " + to_text(*node) + ", " + range_text(min, max));
  }
  value = v;
}

void StrictMap::read(const std::string& key, bool& value) {
  const std::optional<YAML::Node> node = find(key);
  if (!node) return;
  bool v = false;
  if (!node->IsScalar() || !YAML::convert<bool>::decode(*node, v)) {
    throw InputError(describe(key) + " = " + to_text(*node) + ", expected true or false");
  }
  value = v;
}

void StrictMap::read(const std::string& key, std::string& value,
                     const std::vector<std::string>& allowed) {
  const std::optional<YAML::Node> node = find(key);
  if (!node) return;
  if (!node->IsScalar())
    throw InputError(describe(key) + " = " + to_text(*node) + ", expected a string");
  const std::string v = node->Scalar();
  if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), v) == allowed.end()) {
    std::string options;
    for (const auto& a : allowed) options += (options.empty() ? "" : " | ") + a;
    throw InputError(describe(key) + " = " + v + ", expected one of " + options);
  }
  value = v;
}

void StrictMap::read_deg_as_rad(const std::string& key, double& value_rad, double min_deg,
                                double max_deg) {
  double deg = value_rad * 180.0 / M_PI;
  read(key, deg, min_deg, max_deg);
  value_rad = deg * M_PI / 180.0;
}

void StrictMap::read_list(const std::string& key, double* values, int count) {
  const std::optional<YAML::Node> node = find(key);
  if (!node) return;
  if (!node->IsSequence() || static_cast<int>(node->size()) != count) {
    std::ostringstream message;
    message << describe(key) << " has "
            << (node->IsSequence() ? std::to_string(node->size()) + " values" : "no list")
            << ", expected " << count;
    throw InputError(message.str());
  }
  for (int i = 0; i < count; ++i) {
    values[i] = parse_double((*node)[i], describe(key) + "[" + std::to_string(i) + "]");
  }
}

void StrictMap::read_int_list(const std::string& key, std::vector<int>& values, int min, int max,
                              int max_count) {
  const std::optional<YAML::Node> node = find(key);
  if (!node) return;
  if (!node->IsSequence() || static_cast<int>(node->size()) > max_count) {
    throw InputError(describe(key) + " = " + to_text(*node) + ", expected a list of at most " +
                     std::to_string(max_count) + " integers");
  }
  std::vector<int> out;
  for (std::size_t i = 0; i < node->size(); ++i) {
    const std::string where = describe(key) + "[" + std::to_string(i) + "]";
    int v = 0;
    if (!(*node)[i].IsScalar() || !YAML::convert<int>::decode((*node)[i], v)) {
      throw InputError(where + " = " + to_text((*node)[i]) + ", expected an integer");
    }
    if (v < min || v > max) {
      throw InputError(where + " = " + to_text((*node)[i]) + ", " + range_text(min, max));
    }
    out.push_back(v);
  }
  values = std::move(out);
}

void StrictMap::require(const std::string& key, double& value, double min, double max) {
  if (!has(key)) throw InputError(describe(key) + " is missing");
  read(key, value, min, max);
}

void StrictMap::require(const std::string& key, int& value, int min, int max) {
  if (!has(key)) throw InputError(describe(key) + " is missing");
  read(key, value, min, max);
}

void StrictMap::require_list(const std::string& key, double* values, int count) {
  if (!has(key)) throw InputError(describe(key) + " is missing");
  read_list(key, values, count);
}

StrictMap StrictMap::child(const std::string& key) {
  const std::optional<YAML::Node> node = find(key);
  const std::string path = prefix_.empty() ? key : prefix_ + "." + key;
  if (!node) return StrictMap(YAML::Node(YAML::NodeType::Map), where_, path);
  if (node->IsNull()) {
    // The key's line: a null value's own mark is wherever the next token starts.
    std::string line;
    for (auto it = node_.begin(); it != node_.end(); ++it) {
      if (it->first.Scalar() == key) line = line_of(it->first.Mark());
    }
    throw InputError(where_ + line + ": " + path + kNullSectionText);
  }
  return StrictMap(*node, where_, path);
}

namespace {
// Levenshtein distance, for "did you mean" on a misspelled key.
std::size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}
}  // namespace

void StrictMap::finish() const { finish_except({}); }

void StrictMap::finish_sections() const { finish_except(kSharedFileSections); }

void StrictMap::finish_except(const std::vector<std::string>& read_elsewhere) const {
  if (!node_.IsMap()) return;
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    const std::string key = it->first.Scalar();
    const auto known = [&](const std::vector<std::string>& keys) {
      return std::find(keys.begin(), keys.end(), key) != keys.end();
    };
    if (known(seen_) || known(read_elsewhere)) continue;
    std::string message = describe(key) + " is not a known key (value " + to_text(it->second);
    std::string closest;
    std::size_t best = 3;  // suggest only near misses (odometri -> odometry)
    for (const auto* keys : {&seen_, &read_elsewhere}) {
      for (const std::string& k : *keys) {
        const std::size_t d = edit_distance(key, k);
        if (d < best) {
          best = d;
          closest = k;
        }
      }
    }
    message += closest.empty() ? ")" : "; did you mean " + closest + "?)";
    throw InputError(message);
  }
}

}  // namespace hq::config
