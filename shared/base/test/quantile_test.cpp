// hq::quantile: the sorted sample at floor(q * (n - 1)), whatever the input order and type.
#include "hq/base/quantile.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

namespace hq {
namespace {

TEST(Quantile, IsTheSortedSampleAtTheFloorIndex) {
  std::vector<double> values(101);
  std::iota(values.begin(), values.end(), 0.0);  // 0 .. 100
  std::shuffle(values.begin(), values.end(), std::mt19937(7));
  EXPECT_EQ(quantile(values, 0.0), 0.0);
  EXPECT_EQ(quantile(values, 0.5), 50.0);
  EXPECT_EQ(quantile(values, 0.99), 99.0);
  EXPECT_EQ(quantile(values, 0.999), 99.0);  // floor(99.9): no interpolation
  EXPECT_EQ(quantile(values, 1.0), 100.0);
}

TEST(Quantile, SmallSetsAndIntegerSamples) {
  const std::vector<std::int64_t> ns = {40, 10, 30, 20};
  EXPECT_EQ(quantile(ns, 0.5), 20.0);  // floor(1.5) = 1
  EXPECT_EQ(quantile(ns, 0.9), 30.0);  // floor(2.7) = 2
  EXPECT_EQ(quantile(std::vector<int>{5}, 0.99), 5.0);
}

TEST(Quantile, ClampsQAndSaysNothingOfNothing) {
  const std::vector<double> values = {3.0, 1.0, 2.0};
  EXPECT_EQ(quantile(values, -1.0), 1.0);
  EXPECT_EQ(quantile(values, 2.0), 3.0);
  EXPECT_TRUE(std::isnan(quantile(std::vector<double>{}, 0.5)));
  EXPECT_TRUE(std::isnan(quantile(values, std::nan(""))));
}

TEST(HistogramQuantileBin, IsTheBinWhereTheRunningCountReachesTheRank) {
  // 10 samples: 2 in bin 0, 5 in bin 3, 3 in bin 7.
  std::vector<std::uint32_t> bins(10, 0);
  bins[0] = 2;
  bins[3] = 5;
  bins[7] = 3;
  EXPECT_EQ(histogram_quantile_bin(bins, 10, 0.0), 0U);   // rank 1
  EXPECT_EQ(histogram_quantile_bin(bins, 10, 0.2), 0U);   // rank 2
  EXPECT_EQ(histogram_quantile_bin(bins, 10, 0.21), 3U);  // rank 3
  EXPECT_EQ(histogram_quantile_bin(bins, 10, 0.7), 3U);   // rank 7
  EXPECT_EQ(histogram_quantile_bin(bins, 10, 0.71), 7U);  // rank 8
  EXPECT_EQ(histogram_quantile_bin(bins, 10, 1.0), 7U);
  EXPECT_EQ(histogram_quantile_bin(bins, 10, 5.0), 7U);  // clamped
  EXPECT_EQ(histogram_quantile_bin(bins, 0, 0.5), bins.size());
  EXPECT_EQ(histogram_quantile_bin(bins, 11, 1.0), bins.size());  // fewer in the bins than said
}

}  // namespace
}  // namespace hq
