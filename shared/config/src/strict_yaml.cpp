#include "hq/config/strict_yaml.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <sstream>

namespace hq::config {

YAML::Node load_yaml_file(const std::string& path) {
  if (!std::filesystem::exists(path)) throw InputError(path + ": file not found");
  try {
    YAML::Node node = YAML::LoadFile(path);
    if (!node.IsDefined() || node.IsNull()) return YAML::Node(YAML::NodeType::Map);
    if (!node.IsMap()) throw InputError(path + ": expected a YAML mapping at the top level");
    return node;
  } catch (const YAML::Exception& e) {
    std::ostringstream message;
    message << path << ":" << (e.mark.line + 1) << ": not valid YAML: " << e.msg;
    throw InputError(message.str());
  }
}

StrictMap::StrictMap(const YAML::Node& node, std::string where, std::string prefix)
    : node_(node), where_(std::move(where)), prefix_(std::move(prefix)) {
  if (node_.IsDefined() && !node_.IsNull() && !node_.IsMap()) {
    throw InputError(where_ + ": " + (prefix_.empty() ? std::string("top level") : prefix_) +
                     " is not a mapping");
  }
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
  if (v < min || v > max) throw InputError(describe(key) + " = " + to_text(*node) + ", " +
                                           range_text(min, max));
  value = v;
}

void StrictMap::read_positive(const std::string& key, double& value, double max) {
  const std::optional<YAML::Node> node = find(key);
  if (!node) return;
  const double v = parse_double(*node, describe(key));
  if (!(v > 0.0)) throw InputError(describe(key) + " = " + to_text(*node) + ", expected > 0");
  if (v > max) throw InputError(describe(key) + " = " + to_text(*node) + ", " +
                                range_text(0.0, max));
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
  if (!node->IsScalar()) throw InputError(describe(key) + " = " + to_text(*node) +
                                          ", expected a string");
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
  return StrictMap(*node, where_, path);
}

void StrictMap::finish() const {
  if (!node_.IsMap()) return;
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    const std::string key = it->first.as<std::string>();
    if (std::find(seen_.begin(), seen_.end(), key) == seen_.end()) {
      throw InputError(describe(key) + " is not a known key");
    }
  }
}

}  // namespace hq::config
