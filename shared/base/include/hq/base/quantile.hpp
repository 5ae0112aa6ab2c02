#pragma once
/// Quantiles, one definition for the whole tree. quantile(): of a sample set, as every benchmark
/// and campaign reports it, the sample at index floor(q * (n - 1)) of the sorted set (no
/// interpolation, so the value is one that occurred; q = 0 the minimum, q = 1 the maximum); it
/// copies and reorders, so not for 1 kHz paths. histogram_quantile_bin(): of a fixed histogram
/// (the haptic loop's jitter, the link's latencies), allocation-free.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace hq {

/// The q-quantile of `values` (taken by value: reordered in the copy); q is clamped to [0, 1].
/// NaN for an empty set or a NaN q.
template <typename T>
double quantile(std::vector<T> values, double q) {
  if (values.empty() || std::isnan(q)) return std::numeric_limits<double>::quiet_NaN();
  const double clamped = std::clamp(q, 0.0, 1.0);
  const auto k = static_cast<std::size_t>(clamped * static_cast<double>(values.size() - 1));
  const auto kth = values.begin() + static_cast<std::ptrdiff_t>(k);
  std::nth_element(values.begin(), kth, values.end());
  return static_cast<double>(*kth);
}

/// The bin holding the q-quantile of a histogram of `count` samples (nearest rank): the first
/// bin at which the running count reaches ceil(q * count), at least 1; q is clamped to [0, 1].
/// bins.size() when `count` is 0 or the bins hold fewer samples.
template <typename Count>
std::size_t histogram_quantile_bin(const std::vector<Count>& bins, std::int64_t count, double q) {
  if (count <= 0) return bins.size();
  const double clamped = std::clamp(q, 0.0, 1.0);
  const auto rank = std::max<std::int64_t>(
      static_cast<std::int64_t>(std::ceil(clamped * static_cast<double>(count))), 1);
  std::int64_t seen = 0;
  for (std::size_t b = 0; b < bins.size(); ++b) {
    seen += static_cast<std::int64_t>(bins[b]);
    if (seen >= rank) return b;
  }
  return bins.size();
}

}  // namespace hq
