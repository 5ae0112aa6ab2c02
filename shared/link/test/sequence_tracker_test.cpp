#include "hq/link/sequence_tracker.hpp"

#include <gtest/gtest.h>

#include <cstdint>

namespace hq::link {
namespace {

constexpr std::uint64_t kVehicle = 11;  // writer identities
constexpr std::uint64_t kForger = 22;
constexpr std::int64_t kPeriodNs = 33'000'000;  // states at 30 Hz

TEST(SequenceTracker, NextAndGapsAreAcceptedAndMissingCounted) {
  SequenceTracker tracker;
  EXPECT_EQ(tracker.check(7, kVehicle, 0).verdict, SequenceVerdict::kNext);  // the first
  EXPECT_EQ(tracker.check(8, kVehicle, kPeriodNs).verdict, SequenceVerdict::kNext);
  const SequenceCheck gap = tracker.check(12, kVehicle, 2 * kPeriodNs);
  EXPECT_EQ(gap.verdict, SequenceVerdict::kGap);
  EXPECT_EQ(gap.missing, 3U);
  EXPECT_EQ(tracker.last(), 12U);
}

TEST(SequenceTracker, OvertakenReplayedAndFarAheadSamplesAreDropped) {
  SequenceTracker tracker({.max_forward_jump = 1000});
  tracker.check(10, kVehicle, 0);
  tracker.check(12, kVehicle, kPeriodNs);
  EXPECT_EQ(tracker.check(11, kVehicle, kPeriodNs).verdict, SequenceVerdict::kBehind);
  EXPECT_EQ(tracker.check(12, kVehicle, kPeriodNs).verdict, SequenceVerdict::kBehind);
  EXPECT_EQ(tracker.check(5000, kForger, kPeriodNs).verdict, SequenceVerdict::kJump);
  EXPECT_EQ(tracker.last(), 12U);
}

// GIVEN a stream jittered so that single samples are overtaken, THEN no resync ever happens:
// an accepted sample in between ends every run of dropped ones.
TEST(SequenceTracker, JitterNeverResyncs) {
  SequenceTracker tracker;
  std::int64_t t_ns = 0;
  tracker.check(1, kVehicle, t_ns);
  for (std::uint64_t n = 3; n < 300; n += 2) {
    t_ns += kPeriodNs;
    EXPECT_TRUE(tracker.check(n, kVehicle, t_ns).accepted());
    EXPECT_EQ(tracker.check(n - 1, kVehicle, t_ns).verdict, SequenceVerdict::kBehind);
  }
}

// GIVEN one forged sample far ahead, WHEN the vehicle's own samples continue below it, THEN
// the third of them resyncs and every one after is followed.
TEST(SequenceTracker, RealStreamBehindAForgedNumberResyncsAfterThreeSamples) {
  SequenceTracker tracker;
  std::int64_t t_ns = 0;
  std::uint64_t n = 1;
  for (; n <= 10; ++n, t_ns += kPeriodNs) tracker.check(n, kVehicle, t_ns);
  ASSERT_TRUE(tracker.check(n + 50'000, kForger, t_ns).accepted());
  EXPECT_EQ(tracker.check(n++, kVehicle, t_ns += kPeriodNs).verdict, SequenceVerdict::kBehind);
  EXPECT_EQ(tracker.check(n - 1, kVehicle, t_ns).verdict, SequenceVerdict::kBehind);  // duplicate
  EXPECT_EQ(tracker.check(n++, kVehicle, t_ns += kPeriodNs).verdict, SequenceVerdict::kBehind);
  const SequenceCheck resync = tracker.check(n, kVehicle, t_ns += kPeriodNs);
  EXPECT_EQ(resync.verdict, SequenceVerdict::kResync);
  EXPECT_EQ(resync.abandoned, 11U + 50'000U);
  EXPECT_EQ(tracker.last(), n);
  EXPECT_EQ(tracker.check(n + 1, kVehicle, t_ns += kPeriodNs).verdict, SequenceVerdict::kNext);
}

// GIVEN the followed stream quiet for longer than resync_after_ns, THEN two consistent
// samples suffice; one (a replay) does not, nor do two from different writers.
TEST(SequenceTracker, AQuietStreamResyncsOnTwoConsistentSamples) {
  SequenceTracker tracker({.resync_after_samples = 10, .resync_after_ns = 500'000'000});
  tracker.check(100, kVehicle, 0);
  const std::int64_t late_ns = 600'000'000;
  EXPECT_EQ(tracker.check(40, kVehicle, late_ns).verdict, SequenceVerdict::kBehind);
  EXPECT_EQ(tracker.check(41, kForger, late_ns).verdict, SequenceVerdict::kBehind);
  EXPECT_EQ(tracker.check(42, kForger, late_ns).verdict, SequenceVerdict::kResync);
  EXPECT_EQ(tracker.last(), 42U);
}

// GIVEN a real stream whose number legitimately leapt beyond max_forward_jump (a reader that
// missed an hour), THEN it is followed again after the same run, not dropped forever.
TEST(SequenceTracker, AFarLeapOfTheLiveStreamResyncsToo) {
  SequenceTracker tracker({.max_forward_jump = 100});
  tracker.check(1, kVehicle, 0);
  EXPECT_EQ(tracker.check(1'000'000, kVehicle, kPeriodNs).verdict, SequenceVerdict::kJump);
  EXPECT_EQ(tracker.check(1'000'001, kVehicle, 2 * kPeriodNs).verdict, SequenceVerdict::kJump);
  EXPECT_EQ(tracker.check(1'000'002, kVehicle, 3 * kPeriodNs).verdict, SequenceVerdict::kResync);
}

TEST(SequenceTracker, ResetAcceptsTheNextSampleAsTheFirst) {
  SequenceTracker tracker;
  tracker.check(500, kVehicle, 0);
  tracker.reset();
  EXPECT_FALSE(tracker.started());
  EXPECT_EQ(tracker.check(1, kVehicle, kPeriodNs).verdict, SequenceVerdict::kNext);
}

}  // namespace
}  // namespace hq::link
