// The console window's pure parts: the camera image's fit, the alarm's cause and mute.
#include "alarm.hpp"
#include "camera_panel.hpp"
#include <gtest/gtest.h>

namespace hq::console {
namespace {

TEST(CameraFit, WholeImageKeepsItsAspectCentredInTheArea) {
  // A 4:3 image in a wide area: as tall as the area, centred across.
  const PixelRect wide = fit_image({10, 20, 800, 300}, 320, 240);
  EXPECT_FLOAT_EQ(wide.height, 300);
  EXPECT_FLOAT_EQ(wide.width, 400);
  EXPECT_FLOAT_EQ(wide.x, 10 + 200);
  EXPECT_FLOAT_EQ(wide.y, 20);
  // In a tall area: as wide as it, centred down.
  const PixelRect tall = fit_image({0, 0, 409, 700}, 640, 480);
  EXPECT_LE(tall.width, 409);
  EXPECT_NEAR(tall.width / tall.height, 640.0 / 480.0, 0.01);
  EXPECT_GE(tall.y, 0);
  EXPECT_LE(tall.y + tall.height, 700);
  // Nothing to fit: empty.
  EXPECT_FLOAT_EQ(fit_image({0, 0, 0, 100}, 640, 480).width, 0);
  EXPECT_FLOAT_EQ(fit_image({0, 0, 100, 100}, 0, 480).width, 0);
}

Snapshot live_state() {
  Snapshot s;
  s.have_state = true;
  return s;
}

TEST(Alarm, LinkLossWinsOverAFailsafeAndAReplayNeverAlarms) {
  Snapshot s = live_state();
  EXPECT_EQ(alarm_cause(s), AlarmCause::kNone);
  s.operator_input = "commands ignored: fail-safe";
  EXPECT_EQ(alarm_cause(s), AlarmCause::kFailsafe);
  s.link.link_lost = true;
  EXPECT_EQ(alarm_cause(s), AlarmCause::kLinkLost);
  s.replay.active = true;
  EXPECT_EQ(alarm_cause(s), AlarmCause::kNone);
  Snapshot none;  // no vehicle heard yet: nothing to lose
  none.link.link_lost = true;
  EXPECT_EQ(alarm_cause(none), AlarmCause::kNone);
}

TEST(Alarm, MuteHoldsWhileItsCauseLastsAndANewCauseSoundsAgain) {
  AlarmMute mute;
  EXPECT_FALSE(mute.update(AlarmCause::kNone, true)) << "nothing to mute";
  EXPECT_FALSE(mute.update(AlarmCause::kLinkLost, false));
  EXPECT_TRUE(mute.update(AlarmCause::kLinkLost, true));
  EXPECT_TRUE(mute.update(AlarmCause::kLinkLost, false));
  // Another cause sounds again.
  EXPECT_FALSE(mute.update(AlarmCause::kFailsafe, false));
  EXPECT_TRUE(mute.update(AlarmCause::kFailsafe, true));
  EXPECT_FALSE(mute.update(AlarmCause::kFailsafe, true)) << "B again unmutes";
  // The cause clears; its return sounds again.
  EXPECT_TRUE(mute.update(AlarmCause::kFailsafe, true));
  EXPECT_FALSE(mute.update(AlarmCause::kNone, false));
  EXPECT_FALSE(mute.update(AlarmCause::kFailsafe, false));
}

}  // namespace
}  // namespace hq::console
