#pragma once
/// Per-stage duration statistics of OnboardChain runs (median and p99 per stage, ms), for the
/// apps' exit report and the benchmark.

#include "hq/pipeline/onboard_chain.hpp"

#include <array>
#include <cstddef>
#include <cstdio>
#include <vector>

namespace hq::pipeline {

struct StageStatistics {
  double median_ms = 0.0;
  double p99_ms = 0.0;
  double max_ms = 0.0;
};

class StageTimingLog {
 public:
  /// Preallocates room for `frames` entries; add() beyond it grows the buffers.
  explicit StageTimingLog(std::size_t frames = 4096);
  void add(const StageDurations& durations);
  [[nodiscard]] std::size_t size() const { return stages_[0].size(); }
  /// Statistics of stage i in kStageNames order (zeros when empty).
  [[nodiscard]] StageStatistics statistics(int stage) const;
  /// A table "stage  median  p99  max" in ms, one row per stage.
  void print(std::FILE* out) const;

 private:
  std::array<std::vector<double>, kStageCount> stages_;  // ms
};

}  // namespace hq::pipeline
