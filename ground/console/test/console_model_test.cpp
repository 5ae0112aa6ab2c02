#include "hq/console/console_model.hpp"

#include "hq/base/format_into.hpp"
#include "hq/testing/allocation_counter.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

namespace hq::console {
namespace {

void add_state(ConsoleModel& m, std::int64_t t_ns, float vx, float yaw_rate) {
  m.on_state(t_ns, 1.0, {vx, 0, 0}, {0, 0, yaw_rate}, 0, 0, {0, 0, 0}, "teleop", "ok", "ok",
             nullptr, 0);
}

TEST(ConsoleModel, TopViewIntegratesVelocityInHRotatedByGyroYaw) {
  ConsoleModel m;
  // 1 s straight ahead at 1 m/s, then turning at pi/2 rad/s for 1 s at the same speed in H.
  for (int i = 0; i <= 100; ++i) add_state(m, i * 10'000'000LL, 1.0F, 0.0F);
  for (int i = 101; i <= 200; ++i)
    add_state(m, i * 10'000'000LL, 1.0F, static_cast<float>(M_PI / 2));
  Snapshot s = m.make_snapshot();
  m.snapshot(s);
  EXPECT_EQ(s.plot_count, 201U);
  EXPECT_NEAR(s.yaw_W_rad, M_PI / 2, 1e-3);
  // A quarter circle of radius 2/pi after the first metre: x = 1 + 2/pi, y = 2/pi.
  EXPECT_NEAR(s.position_W.x_W_m, 1.0 + 2.0 / M_PI, 0.03);
  EXPECT_NEAR(s.position_W.y_W_m, 2.0 / M_PI, 0.03);
  EXPECT_EQ(s.mode, "teleop");
}

TEST(ConsoleModel, RingsKeepTheNewestSamplesOldestFirst) {
  ConsoleModel::Capacity c;
  c.plot = 8;
  ConsoleModel m(c);
  for (int i = 0; i < 20; ++i) add_state(m, i * 1'000'000'000LL, static_cast<float>(i), 0);
  Snapshot s = m.make_snapshot();
  m.snapshot(s);
  ASSERT_EQ(s.plot_count, 8U);
  EXPECT_EQ(s.plot_total, 20U);
  for (std::size_t i = 0; i < 8; ++i)
    EXPECT_EQ(s.plot[i].v_est_H_mps[0], 12.0F + static_cast<float>(i));
}

TEST(ConsoleModel, SamplesAndSnapshotsAllocateNothingAfterConstruction) {
  ConsoleModel m;
  Snapshot s = m.make_snapshot();
  std::vector<std::uint8_t> jpeg(50'000, 7);
  std::vector<float> cloud(3 * 500, 1.0F);
  const long before = hq::testing::allocation_count();
  for (int i = 0; i < 5000; ++i) {
    m.on_command(i * 1'000'000LL, {0.1F, 0, 0}, 0.0F);
    m.on_state(i * 1'000'000LL, 1.0, {0.1F, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0}, "hover", "ok", "ok",
               cloud.data(), 500);
    if (i % 10 == 0) m.on_camera(i * 1'000'000LL, jpeg.data(), jpeg.size(), nullptr, 0);
    m.on_event(i * 1'000'000LL, 0, "event");
    if (i % 16 == 0) m.snapshot(s);
  }
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
  m.snapshot(s);
  EXPECT_EQ(s.cloud_count, 500U);
  EXPECT_EQ(s.jpeg_size, jpeg.size());
}

// The vehicle sends its remembered cloud on one state a second: the states between carry none
// and must not blank the top view; the next cloud replaces it.
TEST(ConsoleModel, ObstacleCloudStandsUntilTheNextCloud) {
  ConsoleModel m;
  Snapshot s = m.make_snapshot();
  std::vector<float> cloud(3 * 40, 1.0F);
  m.on_state(0, 1.0, {0, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0}, "hover", "ok", "ok", cloud.data(), 40);
  for (int i = 1; i < 30; ++i) {
    m.on_state(i * 33'000'000LL, 1.0, {0, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0}, "hover", "ok", "ok",
               nullptr, 0);
  }
  m.snapshot(s);
  EXPECT_EQ(s.cloud_count, 40U);
  m.on_state(1'000'000'000LL, 1.0, {0, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0}, "hover", "ok", "ok",
             cloud.data(), 7);
  m.snapshot(s);
  EXPECT_EQ(s.cloud_count, 7U);
}

TEST(ConsoleModel, CameraFrameCarriesItsExposureAndReceiptForTheVideoLatency) {
  ConsoleModel m;
  Snapshot s = m.make_snapshot();
  std::vector<std::uint8_t> jpeg(100, 7);
  m.on_camera(5, jpeg.data(), jpeg.size(), nullptr, 0);
  m.snapshot(s);
  EXPECT_EQ(s.camera_exposure_ns, -1);  // no clock offset yet: unknown
  m.on_camera(6, jpeg.data(), jpeg.size(), nullptr, 0, 1'000'000'000, 1'080'000'000);
  m.snapshot(s);
  EXPECT_EQ(s.camera_exposure_ns, 1'000'000'000);
  EXPECT_EQ(s.camera_receipt_ns, 1'080'000'000);
}

// A station that lost control says so, loudly, naming who commands; nothing otherwise.
TEST(ConsoleModel, ControlBannerNamesTheCommandingStation) {
  LinkHealth link;
  char text[192];
  EXPECT_FALSE(control_banner(link, text, sizeof text));
  EXPECT_STREQ(text, "");
  link.control_lost = true;
  link.commanding_station = 9;
  link.selected_vehicle = 1;
  link.own_station = 2;
  ASSERT_TRUE(control_banner(link, text, sizeof text));
  EXPECT_EQ(std::string(text).rfind("CONTROL LOST: station 9 commands vehicle 1", 0), 0U) << text;
  ConsoleModel m;
  m.on_link(link);
  Snapshot s = m.make_snapshot();
  m.snapshot(s);
  EXPECT_TRUE(s.link.control_lost);
  EXPECT_EQ(s.link.commanding_station, 9U);
}

// A vehicle's intrusion report (another certificate speaking for a station) is shown whole,
// with how many came, from the first one on; nothing before.
TEST(ConsoleModel, IntrusionBannerShowsTheVehiclesLatestReport) {
  LinkHealth link;
  link.selected_vehicle = 1;
  char text[256];
  EXPECT_FALSE(intrusion_banner(link, text, sizeof text));
  EXPECT_STREQ(text, "");
  link.intrusion_reports = 3;
  hq::format_into(link.last_intrusion.data(), link.last_intrusion.size(),
                  "INTRUSION: 12 samples (40 in total) claimed another station, refused; last: a "
                  "command claiming station 1, written by station_3's certificate");
  ASSERT_TRUE(intrusion_banner(link, text, sizeof text));
  EXPECT_EQ(std::string(text).rfind("vehicle 1, report 3: INTRUSION: 12 samples", 0), 0U) << text;
  EXPECT_NE(std::string(text).find("written by station_3's certificate"), std::string::npos);
  ConsoleModel m;
  m.on_link(link);
  Snapshot s = m.make_snapshot();
  m.snapshot(s);
  EXPECT_EQ(s.link.intrusion_reports, 3U);
  EXPECT_STREQ(s.link.last_intrusion.data(), link.last_intrusion.data());
}

// GIVEN a vehicle that turned to -98 deg, left a trail and a cloud, with 150 s of plots WHEN it
// restarts (a new session) THEN the new session's top view starts at W's origin with yaw 0 and
// no cloud, the old trail is kept as the previous (greyed) one, and the plots hold only the new
// session's states from t = 0: no axis spans both sessions. Events are kept.
TEST(ConsoleModel, ARestartResetsThePoseTrailCloudAndPlotsOfTheOldSession) {
  ConsoleModel m;
  const float yaw_rate = static_cast<float>(-98.0 * M_PI / 180.0);  // -98 deg in 1 s
  for (int i = 0; i <= 100; ++i) add_state(m, i * 10'000'000LL, 1.0F, yaw_rate);
  const float cloud[3] = {2.0F, 0.0F, 0.0F};
  m.on_state(1'010'000'000LL, 150'000.0, {1, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0}, "teleop", "ok",
             "ok", cloud, 1);
  for (int i = 102; i < 15000; i += 100) add_state(m, i * 10'000'000LL, 0.0F, 0.0F);
  m.on_event(150'000'000'000LL, 1, "vehicle 1 restarted (new session 2): request the mode again");
  Snapshot before = m.make_snapshot();
  m.snapshot(before);
  ASSERT_NEAR(before.yaw_W_rad, -98.0 * M_PI / 180.0, 1e-2);
  ASSERT_EQ(before.cloud_count, 1U);
  ASSERT_GT(before.latest.t_s, 140.0F);
  EXPECT_EQ(before.sessions, 1U);

  m.start_new_track();
  Snapshot s = m.make_snapshot();
  m.snapshot(s);
  EXPECT_EQ(s.sessions, 2U);
  EXPECT_EQ(s.plot_count, 0U);
  EXPECT_EQ(s.track_count, 0U);
  EXPECT_EQ(s.cloud_count, 0U);
  EXPECT_EQ(s.previous_track_count, before.track_count);
  EXPECT_FLOAT_EQ(s.previous_track[s.previous_track_count - 1].x_W_m,
                  before.track[before.track_count - 1].x_W_m);
  EXPECT_EQ(s.event_count, before.event_count);

  // The new vehicle's first states, on the same ground clock 200 s on, turning slightly left.
  for (int i = 0; i <= 10; ++i) add_state(m, 200'000'000'000LL + i * 10'000'000LL, 0.5F, 0.035F);
  m.snapshot(s);
  EXPECT_EQ(s.plot_count, 11U);
  EXPECT_FLOAT_EQ(s.plot[0].t_s, 0.0F);  // a fresh axis from the new session's first state
  EXPECT_NEAR(s.plot[10].t_s, 0.1F, 1e-4);
  for (std::size_t i = 0; i < s.plot_count; ++i) EXPECT_LT(s.plot[i].latency_ms, 2.0F);
  EXPECT_NEAR(s.yaw_W_rad, 0.0035, 1e-4);  // +0.2 deg, not -98 deg carried on
  EXPECT_NEAR(s.position_W.x_W_m, 0.05, 1e-3);
  EXPECT_EQ(s.track_count, 11U);
  EXPECT_EQ(s.previous_track_count, before.track_count);  // still shown, greyed
  EXPECT_EQ(s.cloud_count, 0U);                           // the old cloud is not this vehicle's

  m.reset();  // a replay seeking backwards forgets both sessions
  m.snapshot(s);
  EXPECT_EQ(s.previous_track_count, 0U);
  EXPECT_EQ(s.sessions, 0U);
}

TEST(ConsoleModel, VehicleEndedBannerSaysWhyOnlyOnceTheVehicleSaidGoodbye) {
  LinkHealth link;
  link.selected_vehicle = 1;
  char text[200];
  EXPECT_FALSE(vehicle_ended_banner(link, text, sizeof text));
  EXPECT_STREQ(text, "");
  link.vehicle_ended = true;
  hq::format_into(link.vehicle_ended_text.data(), link.vehicle_ended_text.size(), "{}",
                  "vehicle ended: stopped by SIGTERM; landed");
  ASSERT_TRUE(vehicle_ended_banner(link, text, sizeof text));
  EXPECT_STREQ(text, "vehicle 1: vehicle ended: stopped by SIGTERM; landed");
  EXPECT_FALSE(vehicle_ended_banner(link, text, 0));
}

TEST(ConsoleModel, FlightStateHeightAndOperatorInputReachTheSnapshot) {
  ConsoleModel m;
  StateExtras extras;
  extras.flight_state = "airborne";
  extras.motors_armed = true;
  extras.height_valid = true;
  extras.height_m = 1.02F;
  extras.height_source = "depth";
  extras.operator_input = "slowed: unseen space";
  extras.clearance_m = 0.7F;
  extras.hover_thrust_gain = 1.3F;
  extras.hover_thrust_converged = true;
  m.on_state(0, 1.0, {0, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0}, "teleop", "ok", "ok", nullptr, 0,
             extras);
  Snapshot s = m.make_snapshot();
  m.snapshot(s);
  EXPECT_STREQ(s.flight_state, "airborne");
  EXPECT_TRUE(s.motors_armed);
  EXPECT_TRUE(s.height_valid);
  EXPECT_FLOAT_EQ(s.height_m, 1.02F);
  EXPECT_STREQ(s.height_source, "depth");
  EXPECT_STREQ(s.operator_input, "slowed: unseen space");
  EXPECT_FLOAT_EQ(s.clearance_m, 0.7F);
  EXPECT_FLOAT_EQ(s.hover_thrust_gain, 1.3F);
  EXPECT_TRUE(s.hover_thrust_converged);
  // A non-finite height or gain from a broken sender is shown as unknown, never as NaN.
  extras.height_m = std::nanf("");
  extras.hover_thrust_gain = std::nanf("");
  m.on_state(1, 1.0, {0, 0, 0}, {0, 0, 0}, 0, 0, {0, 0, 0}, "teleop", "ok", "ok", nullptr, 0,
             extras);
  m.snapshot(s);
  EXPECT_FALSE(s.height_valid);
  EXPECT_EQ(s.height_m, 0.0F);
  EXPECT_EQ(s.hover_thrust_gain, 0.0F);
  EXPECT_FALSE(s.hover_thrust_converged);
}

TEST(LinkLossMonitor, LostAfterTheThresholdRegainedByAFreshStateCountsAndKeepsTheLongest) {
  LinkLossMonitor monitor(0.5);
  // No state yet: never lost, however long.
  EXPECT_EQ(monitor.update(-1.0), LinkLossMonitor::Change::kNone);
  EXPECT_EQ(monitor.update(0.1), LinkLossMonitor::Change::kNone);
  EXPECT_EQ(monitor.update(0.5), LinkLossMonitor::Change::kNone) << "at the threshold: not yet";
  EXPECT_EQ(monitor.update(0.6), LinkLossMonitor::Change::kLost);
  EXPECT_TRUE(monitor.lost());
  EXPECT_EQ(monitor.update(2.4), LinkLossMonitor::Change::kNone) << "told once per loss";
  EXPECT_EQ(monitor.update(0.02), LinkLossMonitor::Change::kRegained);
  EXPECT_FALSE(monitor.lost());
  EXPECT_DOUBLE_EQ(monitor.last_loss_s(), 2.4);
  EXPECT_EQ(monitor.update(0.9), LinkLossMonitor::Change::kLost);
  EXPECT_EQ(monitor.update(1.0), LinkLossMonitor::Change::kNone);
  EXPECT_EQ(monitor.update(0.01), LinkLossMonitor::Change::kRegained);
  EXPECT_EQ(monitor.losses(), 2U);
  EXPECT_DOUBLE_EQ(monitor.longest_s(), 2.4);
  EXPECT_DOUBLE_EQ(monitor.last_loss_s(), 1.0);
}

}  // namespace
}  // namespace hq::console
