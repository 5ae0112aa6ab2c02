#pragma once
// hq-ground's --state-json as the console tests read it: parsed as JSON (nlohmann), so numbers
// with exponents, escaped texts and the nested "window" and "replay" objects read as written,
// and each figure is named by its JSON pointer ("/window/x_px"), never found by a text search
// that could match the same key in another object. An absent or mistyped figure reads as NaN
// (every comparison fails), an absent text as "", an absent flag as -1.
#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

namespace hq::console_test {

/// The state file's text parsed; a discarded value (every lookup absent) if it is not JSON.
inline nlohmann::json parse_state(const std::string& text) {
  return nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
}

inline const nlohmann::json* state_value(const nlohmann::json& state, const std::string& pointer) {
  const nlohmann::json::json_pointer p(pointer);
  return state.is_object() && state.contains(p) ? &state.at(p) : nullptr;
}

inline double state_number(const nlohmann::json& state, const std::string& pointer) {
  const nlohmann::json* v = state_value(state, pointer);
  return v != nullptr && v->is_number() ? v->get<double>() : std::nan("");
}

inline std::string state_text(const nlohmann::json& state, const std::string& pointer) {
  const nlohmann::json* v = state_value(state, pointer);
  return v != nullptr && v->is_string() ? v->get<std::string>() : std::string();
}

/// 1 true, 0 false, -1 absent or not a boolean.
inline int state_flag(const nlohmann::json& state, const std::string& pointer) {
  const nlohmann::json* v = state_value(state, pointer);
  return v != nullptr && v->is_boolean() ? (v->get<bool>() ? 1 : 0) : -1;
}

}  // namespace hq::console_test
