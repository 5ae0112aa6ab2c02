#include "hq/link/impairment.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace hq::link {
namespace {

[[noreturn]] void fail(const std::string& where, const std::string& key, const std::string& value,
                       const char* expected) {
  throw InputError(where + " " + key + "=" + value + ": expected " + expected);
}

std::string number(double value) {
  std::ostringstream text;
  text << value;
  return text.str();
}

}  // namespace

void check_impairment(const ImpairmentConfig& c, const std::string& where) {
  if (!(c.delay_ms >= 0.0 && c.delay_ms <= 10'000.0)) {
    fail(where, "delay_ms", number(c.delay_ms), "0..10000");
  }
  if (!(c.jitter_ms >= 0.0 && c.jitter_ms <= 10'000.0)) {
    fail(where, "jitter_ms", number(c.jitter_ms), "0..10000");
  }
  if (!(c.loss >= 0.0 && c.loss <= 1.0)) fail(where, "loss", number(c.loss), "0..1");
}

ImpairmentConfig parse_impairment(const std::string& spec) {
  const std::string where = "--link-impair";
  ImpairmentConfig config;
  std::size_t start = 0;
  while (start <= spec.size()) {
    const std::size_t comma = spec.find(',', start);
    const std::string item =
        spec.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    start = comma == std::string::npos ? spec.size() + 1 : comma + 1;
    if (item.empty()) continue;
    const std::size_t equals = item.find('=');
    if (equals == std::string::npos) {
      throw InputError(where + " " + item +
                       ": expected key=value (keys delay_ms, jitter_ms, loss, seed)");
    }
    const std::string key = item.substr(0, equals);
    const std::string value = item.substr(equals + 1);
    char* end = nullptr;
    const double parsed = std::strtod(value.c_str(), &end);
    if (value.empty() || end == nullptr || *end != '\0' || !std::isfinite(parsed)) {
      fail(where, key, value, "a number");
    }
    if (key == "delay_ms") {
      config.delay_ms = parsed;
    } else if (key == "jitter_ms") {
      config.jitter_ms = parsed;
    } else if (key == "loss") {
      config.loss = parsed;
    } else if (key == "seed") {
      if (parsed < 0.0 || parsed > 4294967295.0 || parsed != std::floor(parsed)) {
        fail(where, key, value, "an integer 0..4294967295");
      }
      config.seed = static_cast<std::uint32_t>(parsed);
    } else {
      throw InputError(where + " " + item + ": unknown key '" + key +
                       "', expected delay_ms, jitter_ms, loss or seed");
    }
  }
  check_impairment(config, where);
  return config;
}

std::string describe(const ImpairmentConfig& c) {
  if (!c.active()) return "none";
  char text[160];
  hq::format_into(text, "delay {:.0f} ms, jitter +-{:.0f} ms, loss {:.1f} %, seed {}", c.delay_ms,
                  c.jitter_ms, 100.0 * c.loss, c.seed);
  return text;
}

Impairment::Impairment(const ImpairmentConfig& config, std::uint32_t salt)
    : config_(config), rng_(config.seed * 2654435761u + salt) {}

bool Impairment::admit(std::int64_t t_ns, std::int64_t& release_ns) {
  ++received_;
  if (config_.loss > 0.0 && unit_(rng_) < config_.loss) {
    ++dropped_;
    return false;
  }
  double delay_ms = config_.delay_ms;
  if (config_.jitter_ms > 0.0) delay_ms += config_.jitter_ms * (2.0 * unit_(rng_) - 1.0);
  if (delay_ms < 0.0) delay_ms = 0.0;
  release_ns = t_ns + static_cast<std::int64_t>(std::llround(delay_ms * 1e6));
  return true;
}

}  // namespace hq::link
