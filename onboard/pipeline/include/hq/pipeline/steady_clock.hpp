#pragma once
/// The pipeline's Clock on the host's steady clock (CLOCK_MONOTONIC on Linux), for programs that
/// time the chain's stages on real hardware; tests pass a clock of their own.

#include "hq/base/monotonic_clock.hpp"
#include "hq/pipeline/onboard_chain.hpp"

#include <chrono>
#include <cstdint>

namespace hq::pipeline {

/// std::chrono::steady_clock now, ns.
class SteadyClock final : public Clock {
 public:
  [[nodiscard]] std::int64_t now_ns() const override { return monotonic_now_ns(); }
};

}  // namespace hq::pipeline
