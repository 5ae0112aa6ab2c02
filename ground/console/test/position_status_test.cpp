// The top view and a vehicle position that goes invalid: it is neither followed nor
// dead-reckoned from, and the reason reads in plain words.
#include "hq/console/position_status.hpp"

#include "hq/console/console_model.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>

namespace hq::console {
namespace {

void add_state(ConsoleModel& m, std::int64_t t_ns, float vx, const StateExtras& extras) {
  m.on_state(t_ns, 1.0, {vx, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0}, "marker", "ok", "ok", nullptr, 0,
             extras);
}

TEST(PositionStatus, ReasonsReadInPlainWords) {
  char text[96];
  EXPECT_STREQ(position_invalid_text(2, 3.44F, 0.1F, text, sizeof text), "no marker for 3.4 s");
  EXPECT_STREQ(position_invalid_text(3, 1.0F, 0.62F, text, sizeof text),
               "position uncertainty 0.62 m, over its bound");
  EXPECT_STREQ(position_invalid_text(4, 1.0F, 0.1F, text, sizeof text),
               "markers or velocity disagree with the estimate");
  EXPECT_STREQ(position_invalid_text(1, 0.0F, 0.0F, text, sizeof text), "no marker seen yet");
  EXPECT_STREQ(position_invalid_text(0, 0.0F, 0.0F, text, sizeof text), "");
  EXPECT_STREQ(position_invalid_text(9, 0.0F, 0.0F, text, sizeof text), "unknown reason 9");
  EXPECT_FALSE(position_lost(0));
  EXPECT_FALSE(position_lost(1));
  EXPECT_TRUE(position_lost(2));
  EXPECT_TRUE(position_lost(4));
  EXPECT_FALSE(position_lost(5));
}

// GIVEN the vehicle's position at (2, 3) WHEN it says the position is lost (no marker) while
// flying on at 1 m/s THEN the view keeps (2, 3) greyed, adds no track, and shows why, even
// though the state carries a far-off position; WHEN valid again THEN it follows the vehicle.
TEST(PositionStatus, ALostPositionIsNeitherFollowedNorDeadReckoned) {
  ConsoleModel m;
  StateExtras valid;
  valid.position_valid = true;
  valid.p_W_m = {2.0F, 3.0F, -1.0F};
  for (int i = 0; i < 10; ++i) add_state(m, i * 10'000'000LL, 1.0F, valid);
  Snapshot s = m.make_snapshot();
  m.snapshot(s);
  const std::size_t track_before = s.track_count;
  EXPECT_TRUE(s.position_from_vehicle);
  EXPECT_FALSE(s.position_lost);

  StateExtras lost;
  lost.position_valid = false;
  lost.p_W_m = {-34.0F, -122.0F, -1.0F};  // what a drifting filter would say: never shown
  lost.position_invalid_reason = 2;
  lost.position_age_s = 3.4F;
  for (int i = 10; i < 110; ++i) add_state(m, i * 10'000'000LL, 1.0F, lost);
  m.snapshot(s);
  EXPECT_TRUE(s.position_lost);
  EXPECT_FALSE(s.position_from_vehicle);
  EXPECT_FLOAT_EQ(s.position_W.x_W_m, 2.0F) << "dead-reckoned from a lost position";
  EXPECT_FLOAT_EQ(s.position_W.y_W_m, 3.0F);
  EXPECT_EQ(s.track_count, track_before) << "a lost position must not extend the track";
  EXPECT_EQ(s.position_invalid_reason, 2);
  EXPECT_FLOAT_EQ(s.position_age_s, 3.4F);

  valid.p_W_m = {2.5F, 3.1F, -1.0F};
  add_state(m, 110 * 10'000'000LL, 1.0F, valid);
  m.snapshot(s);
  EXPECT_FALSE(s.position_lost);
  EXPECT_TRUE(s.position_from_vehicle);
  EXPECT_EQ(s.position_invalid_reason, 0);
  EXPECT_FLOAT_EQ(s.position_W.x_W_m, 2.5F);
}

// A vehicle with no marker stage (or from before the reason) says none: the view dead-reckons
// as it always did, and says so.
TEST(PositionStatus, NoReasonGivenKeepsTheDeadReckoning) {
  ConsoleModel m;
  StateExtras none;
  for (int i = 0; i <= 100; ++i) add_state(m, i * 10'000'000LL, 1.0F, none);
  Snapshot s = m.make_snapshot();
  m.snapshot(s);
  EXPECT_FALSE(s.position_lost);
  EXPECT_NEAR(s.position_W.x_W_m, 1.0F, 0.02F);
}

}  // namespace
}  // namespace hq::console
