#pragma once
/// Link impairment for tests and demos: a receive-side stage that delays, jitters (hence
/// reorders) and drops samples, seeded, so every run can fly over a chosen slow, lossy link
/// without kernel netem (which needs privileges CI may lack). It sits below the code under
/// test: Reader<T>::take hands samples out only once their impaired arrival time has come.
///
///   --link-impair delay_ms=150,jitter_ms=30,loss=0.05[,seed=7]
///
/// delay_ms is one way (the receiver's side of the link; impair both processes for a round
/// trip of twice it), jitter_ms the half-width of a uniform spread added to it per sample, loss
/// the probability that a sample is dropped.

#include <cstdint>
#include <random>
#include <string>

namespace hq::link {

struct ImpairmentConfig {
  double delay_ms = 0.0;   ///< One-way delay added to every sample, 0..10000.
  double jitter_ms = 0.0;  ///< Uniform in [-jitter, +jitter] added per sample, 0..delay_ms.
  double loss = 0.0;       ///< Drop probability, 0..1.
  std::uint32_t seed = 1;  ///< Seed of the stage's generator (per reader: seed + topic salt).
  [[nodiscard]] bool active() const { return delay_ms > 0.0 || jitter_ms > 0.0 || loss > 0.0; }
};

/// Parses "key=value,..." (keys delay_ms, jitter_ms, loss, seed). Throws hq::InputError naming
/// the option, key and value and the expectation, e.g.
/// "--link-impair loss=1.5: expected 0..1".
ImpairmentConfig parse_impairment(const std::string& spec);
/// Throws hq::InputError (same wording, `where` first) if a value is out of range.
void check_impairment(const ImpairmentConfig& config, const std::string& where);
/// "delay 150 ms, jitter +-30 ms, loss 5.0 %, seed 7" or "none".
std::string describe(const ImpairmentConfig& config);

/// The per-sample decision: dropped, or the time it may be handed out. Allocation-free.
class Impairment {
 public:
  Impairment() = default;
  Impairment(const ImpairmentConfig& config, std::uint32_t salt);
  /// For a sample received at t_ns: false if dropped, else its release time in release_ns.
  bool admit(std::int64_t t_ns, std::int64_t& release_ns);
  [[nodiscard]] const ImpairmentConfig& config() const { return config_; }
  [[nodiscard]] bool active() const { return config_.active(); }
  [[nodiscard]] std::uint64_t received() const { return received_; }
  [[nodiscard]] std::uint64_t dropped() const { return dropped_; }

 private:
  ImpairmentConfig config_;
  std::mt19937 rng_;
  std::uniform_real_distribution<double> unit_{0.0, 1.0};
  std::uint64_t received_ = 0;
  std::uint64_t dropped_ = 0;
};

}  // namespace hq::link
