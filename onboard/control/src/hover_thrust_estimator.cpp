#include "hq/control/hover_thrust_estimator.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/control/velocity_controller.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace hq::control {
namespace {

// A gap in the accelerometer longer than this restarts the low-pass: what it held is stale.
constexpr double kMaxSampleGapS = 0.1;
// The filters have settled after this many time constants airborne (e^-3: 5 % of a step left).
constexpr double kSettleTimeConstants = 3.0;
// Innovations rejected without a break for this long: the vehicle changed (a payload dropped or
// added), not a bump; the gain's variance goes back to its initial value so it is learnt again.
constexpr double kRelearnAfterS = 1.0;

}  // namespace

void HoverThrustConfig::validate(const std::string& where) const {
  auto fail = [&](const char* key, double value, const char* expected) {
    char text[160];
    hq::format_into(text, "{}{} = {:g}, expected {}", where, key, value, expected);
    throw InputError(text);
  };
  if (!(filter_time_constant_s > 0.0 && filter_time_constant_s <= 2.0)) {
    fail("filter_time_constant_s", filter_time_constant_s, "> 0 and <= 2");
  }
  if (!(update_period_s > 0.0 && update_period_s <= 1.0)) {
    fail("update_period_s", update_period_s, "> 0 and <= 1");
  }
  if (!(initial_sigma > 0.0 && initial_sigma <= 1.0)) {
    fail("initial_sigma", initial_sigma, "> 0 and <= 1");
  }
  if (!(random_walk_per_sqrt_s >= 0.0 && random_walk_per_sqrt_s <= 1.0)) {
    fail("random_walk_per_sqrt_s", random_walk_per_sqrt_s, ">= 0 and <= 1");
  }
  if (!(specific_force_sigma_mps2 > 0.0 && specific_force_sigma_mps2 <= 20.0)) {
    fail("specific_force_sigma_mps2", specific_force_sigma_mps2, "> 0 and <= 20");
  }
  if (!(gate_sigma >= 1.0 && gate_sigma <= 10.0)) fail("gate_sigma", gate_sigma, "in [1, 10]");
  if (!(min_gain > 0.0 && min_gain <= 1.0)) fail("min_gain", min_gain, "> 0 and <= 1");
  if (!(max_gain >= 1.0 && max_gain <= 10.0)) fail("max_gain", max_gain, "in [1, 10]");
  if (!(converged_sigma > 0.0 && converged_sigma < initial_sigma)) {
    fail("converged_sigma", converged_sigma, "> 0 and < initial_sigma");
  }
  if (!(min_updates >= 1 && min_updates <= 100'000)) {
    fail("min_updates", min_updates, "in [1, 100000]");
  }
  if (!(min_thrust_ratio >= 0.0 && min_thrust_ratio < 1.0)) {
    fail("min_thrust_ratio", min_thrust_ratio, ">= 0 and < 1");
  }
}

void read_config(config::StrictMap& section, HoverThrustConfig& out) {
  section.read("enabled", out.enabled);
  section.read_positive("filter_time_constant_s", out.filter_time_constant_s, 2.0);
  section.read_positive("update_period_s", out.update_period_s, 1.0);
  section.read_positive("initial_sigma", out.initial_sigma, 1.0);
  section.read("random_walk_per_sqrt_s", out.random_walk_per_sqrt_s, 0.0, 1.0);
  section.read_positive("specific_force_sigma_mps2", out.specific_force_sigma_mps2, 20.0);
  section.read("gate_sigma", out.gate_sigma, 1.0, 10.0);
  section.read_positive("min_gain", out.min_gain, 1.0);
  section.read("max_gain", out.max_gain, 1.0, 10.0);
  section.read_positive("converged_sigma", out.converged_sigma, 1.0);
  section.read("min_updates", out.min_updates, 1, 100'000);
  section.read("min_thrust_ratio", out.min_thrust_ratio, 0.0, 0.99);
  section.finish();
  // The key path without a key, e.g. "config/onboard.yaml: hover_thrust.", for cross-key checks.
  const std::string path = section.describe("enabled");
  out.validate(path.substr(0, path.size() - std::string("enabled").size()));
}

HoverThrustEstimator::HoverThrustEstimator(const HoverThrustConfig& config, double mass_kg)
    : config_(config), mass_kg_(mass_kg), variance_(config.initial_sigma * config.initial_sigma) {
  config_.validate();
  if (!(mass_kg > 0.0 && std::isfinite(mass_kg))) {
    throw InputError("HoverThrustEstimator: mass_kg = " + std::to_string(mass_kg) +
                     ", expected > 0");
  }
  estimate_.sigma = config_.initial_sigma;
}

void HoverThrustEstimator::on_command(std::int64_t /*t_ns*/, double sent_thrust_n) {
  if (!std::isfinite(sent_thrust_n)) return;
  sent_thrust_n_ = sent_thrust_n;
  have_command_ = true;
}

void HoverThrustEstimator::restart_filters() {
  filter_t_ns_ = -1;
  airborne_s_ = 0.0;
}

void HoverThrustEstimator::on_specific_force(std::int64_t t_ns, double f_z_mps2, bool airborne) {
  if (!config_.enabled || !have_command_ || !airborne || !std::isfinite(f_z_mps2)) {
    restart_filters();
    return;
  }
  const double y_n = -f_z_mps2 * mass_kg_;
  const double dt_s = filter_t_ns_ < 0 ? 0.0 : static_cast<double>(t_ns - filter_t_ns_) * 1e-9;
  if (filter_t_ns_ < 0 || dt_s <= 0.0 || dt_s > kMaxSampleGapS) {
    // Start the low-pass on the current values (a gap, or the first airborne sample).
    y_filtered_n_ = y_n;
    u_filtered_n_ = sent_thrust_n_;
    filter_t_ns_ = t_ns;
    airborne_s_ = 0.0;
    return;
  }
  const double alpha = 1.0 - std::exp(-dt_s / config_.filter_time_constant_s);
  y_filtered_n_ += alpha * (y_n - y_filtered_n_);
  u_filtered_n_ += alpha * (sent_thrust_n_ - u_filtered_n_);
  filter_t_ns_ = t_ns;
  airborne_s_ += dt_s;

  if (airborne_s_ < kSettleTimeConstants * config_.filter_time_constant_s) return;
  if (u_filtered_n_ < config_.min_thrust_ratio * mass_kg_ * kGravityMps2) return;
  const auto period_ns = static_cast<std::int64_t>(config_.update_period_s * 1e9);
  if (last_update_ns_ >= 0 && t_ns - last_update_ns_ < period_ns) return;
  const double since_s =
      last_update_ns_ < 0 ? 0.0 : static_cast<double>(t_ns - last_update_ns_) * 1e-9;
  last_update_ns_ = t_ns;
  update(y_filtered_n_, u_filtered_n_, since_s);
}

void HoverThrustEstimator::update(double y_n, double u_n, double dt_s) {
  // Predict: the gain wanders slowly. A long pause (landed) counts in full: the battery sagged.
  variance_ += config_.random_walk_per_sqrt_s * config_.random_walk_per_sqrt_s * dt_s;
  variance_ = std::min(variance_, config_.initial_sigma * config_.initial_sigma);

  // Measure the gain as y / u: its noise is the specific force's, scaled by m / u.
  const double measured_gain = y_n / u_n;
  const double r = std::pow(config_.specific_force_sigma_mps2 * mass_kg_ / u_n, 2);
  const double innovation = measured_gain - estimate_.gain;
  const double s = variance_ + r;
  // Gated only once converged: while learning, the prior itself may be the thing that is
  // wrong (a gain of 1.9 is 3 initial sigmas away).
  if (estimate_.converged &&
      innovation * innovation > config_.gate_sigma * config_.gate_sigma * s) {
    ++estimate_.rejected;
    rejected_s_ += dt_s;
    if (rejected_s_ >= kRelearnAfterS) {
      variance_ = config_.initial_sigma * config_.initial_sigma;
      rejected_s_ = 0.0;
      estimate_.converged = false;
      ++estimate_.relearned;
    }
  } else {
    rejected_s_ = 0.0;
    const double k = variance_ / s;
    estimate_.gain += k * innovation;
    variance_ *= 1.0 - k;
    ++estimate_.updates;
    if (estimate_.gain < config_.min_gain || estimate_.gain > config_.max_gain) {
      estimate_.gain = std::clamp(estimate_.gain, config_.min_gain, config_.max_gain);
      ++estimate_.clamped;
    }
  }
  estimate_.sigma = std::sqrt(variance_);
  estimate_.converged = estimate_.sigma < config_.converged_sigma &&
                        estimate_.updates >= static_cast<std::uint64_t>(config_.min_updates);
}

double HoverThrustEstimator::corrected_thrust_n(double commanded_n) const {
  return config_.enabled ? commanded_n / estimate_.gain : commanded_n;
}

double HoverThrustEstimator::hover_thrust_n() const {
  return mass_kg_ * kGravityMps2 / estimate_.gain;
}

}  // namespace hq::control
