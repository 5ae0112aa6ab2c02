#include "hq/pipeline/stage_timing.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>

namespace hq::pipeline {

StageTimingLog::StageTimingLog(std::size_t frames) {
  for (auto& stage : stages_) stage.reserve(frames);
}

void StageTimingLog::add(const StageDurations& durations) {
  for (int i = 0; i < kStageCount; ++i) {
    stages_[static_cast<std::size_t>(i)].push_back(1e-6 *
                                                   static_cast<double>(stage_ns(durations, i)));
  }
}

StageStatistics StageTimingLog::statistics(int stage) const {
  StageStatistics out;
  std::vector<double> sorted = stages_[static_cast<std::size_t>(stage)];
  if (sorted.empty()) return out;
  std::sort(sorted.begin(), sorted.end());
  // Nearest-rank percentiles: the value at or below which p of the samples lie.
  const auto rank = [&](double p) {
    const auto r = static_cast<std::size_t>(std::ceil(p * static_cast<double>(sorted.size())));
    return sorted[std::clamp<std::size_t>(r, 1, sorted.size()) - 1];
  };
  out.median_ms = rank(0.5);
  out.p99_ms = rank(0.99);
  out.max_ms = sorted.back();
  return out;
}

void StageTimingLog::print(std::FILE* out) const {
  fmt::print(out, "{:<10} {:>10} {:>10} {:>10}   ({} frames)\n", "stage", "median_ms", "p99_ms",
             "max_ms", size());
  for (int i = 0; i < kStageCount; ++i) {
    const StageStatistics s = statistics(i);
    fmt::print(out, "{:<10} {:10.3f} {:10.3f} {:10.3f}\n", kStageNames[i], s.median_ms, s.p99_ms,
               s.max_ms);
  }
}

}  // namespace hq::pipeline
