#include "hq/obstacles/clearance_filter.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hq::obstacles {

double ClearanceFilter::update(double frame_clearance_m) {
  const bool seen = std::isfinite(frame_clearance_m) && frame_clearance_m >= 0.0;
  ring_[next_] = seen ? frame_clearance_m : std::numeric_limits<double>::infinity();
  next_ = (next_ + 1) % kWindow;
  count_ = std::min(count_ + 1, kWindow);
  std::array<double, kWindow> sorted = ring_;
  const auto n = static_cast<std::ptrdiff_t>(count_);
  // The ring fills from index 0, so while count_ < kWindow its first count_ entries are the
  // frames seen; once full, all are.
  const auto middle = sorted.begin() + (n - 1) / 2;
  std::nth_element(sorted.begin(), middle, sorted.begin() + n);
  clearance_m_ = std::isfinite(*middle) ? *middle : -1.0;
  return clearance_m_;
}

void ClearanceFilter::reset() {
  count_ = 0;
  next_ = 0;
  clearance_m_ = -1.0;
}

}  // namespace hq::obstacles
