#include "hq/console/console_model.hpp"
#include "hq/link/messages.hpp"
#include "hq/testing/allocation_counter.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace hq::console {
namespace {

using ::testing::HasSubstr;

void add_state(ConsoleModel& m, std::int64_t t_ns, float vx, const StateExtras& extras) {
  m.on_state(t_ns, 1.0, {vx, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0}, "marker", "ok", "ok", nullptr, 0,
             extras);
}

TEST(StateExtras, VehiclePositionReplacesDeadReckoningWhichResumesFromIt) {
  ConsoleModel m;
  Snapshot s = m.make_snapshot();
  // Dead reckoning first: 1 s at 1 m/s.
  for (int i = 0; i <= 100; ++i) add_state(m, i * 10'000'000LL, 1.0F, StateExtras{});
  m.snapshot(s);
  EXPECT_FALSE(s.position_from_vehicle);
  EXPECT_NEAR(s.position_W.x_W_m, 1.0, 1e-3);
  // The vehicle's estimate takes over, position and yaw.
  StateExtras extras;
  extras.position_valid = true;
  extras.p_W_m = {3.0F, -2.0F, -1.0F};
  extras.yaw_W_rad = static_cast<float>(M_PI / 2);
  add_state(m, 1'010'000'000LL, 1.0F, extras);
  m.snapshot(s);
  EXPECT_TRUE(s.position_from_vehicle);
  EXPECT_EQ(s.position_states, 1U);
  EXPECT_FLOAT_EQ(s.position_W.x_W_m, 3.0F);
  EXPECT_FLOAT_EQ(s.position_W.y_W_m, -2.0F);
  EXPECT_EQ(s.track[s.track_count - 1].x_W_m, 3.0F);
  // Position lost: dead reckoning goes on from it, heading east (yaw pi/2): 0.5 s at 1 m/s.
  for (int i = 1; i <= 50; ++i) add_state(m, 1'010'000'000LL + i * 10'000'000LL, 1.0F, {});
  m.snapshot(s);
  EXPECT_FALSE(s.position_from_vehicle);
  EXPECT_NEAR(s.position_W.x_W_m, 3.0, 1e-3);
  EXPECT_NEAR(s.position_W.y_W_m, -1.5, 1e-3);
  // A non-finite position is not taken.
  extras.p_W_m[0] = std::numeric_limits<float>::quiet_NaN();
  add_state(m, 2'000'000'000LL, 0.0F, extras);
  m.snapshot(s);
  EXPECT_FALSE(s.position_from_vehicle);
  EXPECT_TRUE(std::isfinite(s.position_W.x_W_m));
}

TEST(StateExtras, MarkersAreBoundedAndTruthIsPlottedOnlyWhenPresent) {
  ConsoleModel m;
  Snapshot s = m.make_snapshot();
  add_state(m, 0, 0.5F, StateExtras{});
  m.snapshot(s);
  EXPECT_FALSE(s.have_truth);
  EXPECT_FALSE(s.latest.truth_valid);
  std::array<MarkerView, 20> markers{};
  for (std::size_t i = 0; i < markers.size(); ++i) {
    markers[i].id = static_cast<std::int32_t>(i);
    markers[i].p_camera_marker_m = {0.1F, 0.0F, 1.0F + static_cast<float>(i)};
  }
  StateExtras extras;
  extras.markers = markers.data();
  extras.marker_count = markers.size();
  extras.truth_valid = true;
  extras.v_truth_H_mps = {0.4F, 0.1F, -0.05F};
  const long before = hq::testing::allocation_count();
  add_state(m, 100'000'000LL, 0.5F, extras);
  m.snapshot(s);
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
  EXPECT_EQ(s.marker_count, kMaxMarkerViews);
  EXPECT_EQ(s.markers[15].id, 15);
  EXPECT_EQ(s.marker_detections, kMaxMarkerViews);
  EXPECT_TRUE(s.have_truth);
  ASSERT_EQ(s.plot_count, 2U);
  EXPECT_FALSE(s.plot[0].truth_valid);
  EXPECT_TRUE(s.plot[1].truth_valid);
  EXPECT_FLOAT_EQ(s.plot[1].v_truth_H_mps[0], 0.4F);
  add_state(m, 200'000'000LL, 0.5F, StateExtras{});
  m.snapshot(s);
  EXPECT_EQ(s.marker_count, 0U);  // markers are those of the latest state only
  EXPECT_TRUE(s.have_truth);
}

TEST(StateExtras, ValidateRejectsBadPositionMarkersAndTruth) {
  link::VehicleState state{};
  EXPECT_TRUE(link::validate(state).ok);
  state.p_W_m.y = std::numeric_limits<float>::infinity();
  EXPECT_THAT(link::validate(state).reason, HasSubstr("p_W_m"));
  state = link::VehicleState{};
  state.v_truth_H_mps.z = std::nanf("");
  EXPECT_THAT(link::validate(state).reason, HasSubstr("v_truth_H_mps"));

  hq_msgs_MarkerInCamera markers[17]{};
  for (auto& marker : markers) {
    marker.id = 3;
    marker.p_camera_marker_m = {0.0F, 0.0F, 1.5F};
    marker.q_camera_marker = {1.0F, 0.0F, 0.0F, 0.0F};
  }
  state = link::VehicleState{};
  state.markers._buffer = markers;
  state.markers._maximum = 17;
  state.markers._length = 2;
  EXPECT_TRUE(link::validate(state).ok);
  state.markers._length = 17;
  EXPECT_THAT(link::validate(state).reason, HasSubstr("kMaxMarkersInState"));
  state.markers._length = 2;
  markers[1].id = -1;
  EXPECT_THAT(link::validate(state).reason, HasSubstr("negative id"));
  markers[1].id = 3;
  markers[1].p_camera_marker_m.z = -0.5F;
  EXPECT_THAT(link::validate(state).reason, HasSubstr("behind the camera"));
  markers[1].p_camera_marker_m.z = 1.5F;
  markers[1].q_camera_marker.w = 0.5F;
  EXPECT_THAT(link::validate(state).reason, HasSubstr("non-unit quaternion"));
  markers[1].q_camera_marker.w = std::nanf("");
  EXPECT_THAT(link::validate(state).reason, HasSubstr("NaN or Inf pose"));
  state.markers._buffer = nullptr;  // not owned by the state
  state.markers._length = 0;
}

}  // namespace
}  // namespace hq::console
