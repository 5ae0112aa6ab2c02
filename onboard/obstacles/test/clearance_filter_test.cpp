#include "hq/obstacles/clearance_filter.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace hq::obstacles {
namespace {

// GIVEN a steady 0.414 m with two consecutive bad frames at 0.159 m (flying pixels), THEN the
// filtered clearance never leaves 0.414 m: the bad frames are not the flight's closest.
TEST(ClearanceFilter, TwoConsecutiveOutlyingFramesChangeNothing) {
  ClearanceFilter f;
  double closest = 1e9;
  for (int i = 0; i < 30; ++i) {
    const double frame = (i == 12 || i == 13) ? 0.159 : 0.414;
    closest = std::min(closest, f.update(frame));
  }
  EXPECT_DOUBLE_EQ(closest, 0.414);
}

// GIVEN an obstacle that comes within 0.2 m and stays, THEN the filter reports it after three
// frames (the median of five), and reports it exactly.
TEST(ClearanceFilter, ARealObstacleShowsAfterThreeFrames) {
  ClearanceFilter f;
  for (int i = 0; i < 5; ++i) f.update(1.0);
  EXPECT_DOUBLE_EQ(f.update(0.2), 1.0);
  EXPECT_DOUBLE_EQ(f.update(0.2), 1.0);
  EXPECT_DOUBLE_EQ(f.update(0.2), 0.2);
  EXPECT_DOUBLE_EQ(f.clearance_m(), 0.2);
}

// Frames that saw no obstacle count as infinitely clear: a lone point in clear air is not a
// clearance, and a clear view reports none (-1), which the console shows as "none".
TEST(ClearanceFilter, FramesWithoutObstaclesAreClearAndMostlyClearIsNone) {
  ClearanceFilter f;
  EXPECT_EQ(f.clearance_m(), -1.0);
  for (int i = 0; i < 5; ++i) f.update(-1.0);
  EXPECT_EQ(f.update(0.3), -1.0);
  EXPECT_EQ(f.update(std::nan("")), -1.0);
  EXPECT_EQ(f.update(0.3), -1.0);
  EXPECT_DOUBLE_EQ(f.update(0.3), 0.3);  // three of the last five saw it
}

// The first frames are reported at once (lower middle of those seen), and reset forgets.
TEST(ClearanceFilter, FirstFramesReportAtOnceAndResetForgets) {
  ClearanceFilter f;
  EXPECT_DOUBLE_EQ(f.update(0.8), 0.8);
  EXPECT_DOUBLE_EQ(f.update(0.6), 0.6);  // lower of two: the nearer
  EXPECT_DOUBLE_EQ(f.update(0.9), 0.8);
  f.reset();
  EXPECT_EQ(f.clearance_m(), -1.0);
  EXPECT_DOUBLE_EQ(f.update(2.0), 2.0);
}

}  // namespace
}  // namespace hq::obstacles
