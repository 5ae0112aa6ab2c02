// GIVEN a fake flight controller on loopback (udp-listen + the codec) WHEN the MAVLink flight
// controller polls and sends THEN what it reports and what the FC receives are checked.
#include "hq/vehicle/mavlink_flight_controller.hpp"

#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"

#include <Eigen/Geometry>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace hq::vehicle {
namespace {

namespace ml = mavlink;
using ::testing::HasSubstr;

constexpr std::int64_t kSecond = 1'000'000'000;
constexpr std::int64_t kMs = 1'000'000;

int next_port() {
  static int offset = 0;
  return 30000 + static_cast<int>(::getpid() % 20000) + (offset++);
}

struct Event {
  FcSeverity severity;
  std::string text;
};

struct RecordingSink : FcSink {
  std::vector<FcImuSample> imu;
  std::vector<FcAttitude> attitude;
  std::vector<Event> events;
  void on_imu(const FcImuSample& sample) override { imu.push_back(sample); }
  void on_attitude(const FcAttitude& a) override { attitude.push_back(a); }
  void on_fc_event(FcSeverity severity, std::string_view text) override {
    events.push_back({severity, std::string(text)});
  }
  [[nodiscard]] bool said(const std::string& part) const {
    for (const auto& e : events) {
      if (e.text.find(part) != std::string::npos) return true;
    }
    return false;
  }
};

struct Received {
  ml::FrameHeader header;
  ml::Message message;
};

// The flight-controller side: system 1, component 1, as PX4 and ArduPilot are.
class FakeFc {
 public:
  explicit FakeFc(int port)
      : transport_(ml::open_transport("udp-listen:" + std::to_string(port))) {}

  void send(const ml::Message& message) {
    std::array<std::uint8_t, ml::kMaxFrameSize> frame{};
    const std::size_t n = encoder_.encode(message, frame);
    ASSERT_TRUE(transport_->send(std::span<const std::uint8_t>(frame.data(), n)))
        << transport_->error();
  }
  void send_raw(const std::vector<std::uint8_t>& bytes) { ASSERT_TRUE(transport_->send(bytes)); }

  // Everything the controller sent within `timeout_ns` (stops early once `until` holds).
  std::vector<Received> receive(
      std::int64_t timeout_ns,
      const std::function<bool(const std::vector<Received>&)>& until = nullptr) {
    std::vector<Received> out;
    const auto end = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
    std::array<std::uint8_t, 2048> buffer{};
    while (std::chrono::steady_clock::now() < end) {
      if (until && until(out)) break;
      if (!transport_->wait_readable(5 * kMs)) continue;
      const std::size_t n = transport_->receive(buffer);
      parser_.feed(std::span<const std::uint8_t>(buffer.data(), n),
                   [&](const ml::FrameHeader& h, const ml::Message& m) {
                     out.push_back({h, m});
                   });
      parser_.end_of_datagram();
    }
    return out;
  }

  template <typename M>
  std::vector<M> receive_all(std::int64_t timeout_ns, std::size_t count) {
    std::vector<M> out;
    receive(timeout_ns, [&](const std::vector<Received>& got) {
      out.clear();
      for (const auto& r : got) {
        if (const auto* m = std::get_if<M>(&r.message)) out.push_back(*m);
      }
      return out.size() >= count;
    });
    return out;
  }

 private:
  std::unique_ptr<ml::Transport> transport_;
  ml::Encoder encoder_{1, 1};
  ml::Parser parser_;
};

ml::Heartbeat px4_heartbeat(bool armed, std::uint32_t main_mode) {
  ml::Heartbeat hb;
  hb.type = ml::kMavTypeQuadrotor;
  hb.autopilot = ml::kMavAutopilotPx4;
  hb.base_mode = static_cast<std::uint8_t>(ml::kMavModeFlagCustomModeEnabled |
                                           (armed ? ml::kMavModeFlagSafetyArmed : 0));
  hb.custom_mode = main_mode << 16;
  hb.system_status = ml::kMavStateActive;
  return hb;
}

ml::Heartbeat ardupilot_heartbeat(bool armed, std::uint32_t mode) {
  ml::Heartbeat hb = px4_heartbeat(armed, 0);
  hb.autopilot = ml::kMavAutopilotArdupilotMega;
  hb.custom_mode = mode;
  return hb;
}

ml::HighresImu imu_at(std::uint64_t time_usec, float gyro_x = 0.1f) {
  ml::HighresImu imu;
  imu.time_usec = time_usec;
  imu.xgyro_radps = gyro_x;
  imu.ygyro_radps = -0.2f;
  imu.zgyro_radps = 0.3f;
  imu.xacc_mps2 = 0.5f;
  imu.yacc_mps2 = -0.25f;
  imu.zacc_mps2 = -9.75f;
  imu.fields_updated = 0x3F;
  return imu;
}

ml::Attitude attitude_with_yaw(double yaw_rad, std::uint32_t time_boot_ms = 0) {
  ml::Attitude a;
  a.time_boot_ms = time_boot_ms;
  a.yaw_rad = static_cast<float>(yaw_rad);
  return a;
}

// A controller wired to a fake FC that has heard its first heartbeat.
struct Link {
  explicit Link(MavlinkFcConfig config = {}) : port(next_port()), fc(port) {
    config.transport = "udp:127.0.0.1:" + std::to_string(port);
    controller = std::make_unique<MavlinkFlightController>(config);
    controller->poll(t_ns, sink);
    const auto hb = fc.receive_all<ml::Heartbeat>(kSecond, 1);
    EXPECT_EQ(hb.size(), 1u) << "the first poll sends our heartbeat";
  }
  // Polls at t_ns until `done` holds (the datagram may need a moment on loopback).
  bool poll_until(const std::function<bool()>& done) {
    for (int i = 0; i < 500; ++i) {
      controller->poll(t_ns, sink);
      if (done()) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return false;
  }
  bool deliver_imu(std::uint64_t time_usec, std::int64_t receipt_ns) {
    t_ns = receipt_ns;
    const std::uint64_t before = controller->counters().messages_received;
    fc.send(imu_at(time_usec));
    return poll_until([&] { return controller->counters().messages_received > before; });
  }
  bool deliver(const ml::Message& message) {
    const std::uint64_t before = controller->counters().messages_received;
    fc.send(message);
    return poll_until([&] { return controller->counters().messages_received > before; });
  }

  int port;
  FakeFc fc;
  std::unique_ptr<MavlinkFlightController> controller;
  RecordingSink sink;
  std::int64_t t_ns = 100 * kSecond;
};

TEST(MavlinkFc, ImuArrivesOnTheRuntimeClockWithItsValues) {
  Link link;
  // FC boot clock 2 s while the runtime reads 10 s: offset 8 s from the first sample; later ones
  // arriving later keep it, one arriving earlier lowers it (less delay, a tighter bound).
  ASSERT_TRUE(link.deliver_imu(2'000'000, 10'000 * kMs));
  ASSERT_TRUE(link.deliver_imu(2'004'000, 10'006 * kMs));
  ASSERT_TRUE(link.deliver_imu(2'008'000, 10'008 * kMs + kMs / 2));
  ASSERT_TRUE(link.deliver_imu(2'012'000, 10'011 * kMs + kMs / 2));
  ASSERT_EQ(link.sink.imu.size(), 4u);
  EXPECT_EQ(link.sink.imu[0].t_ns, 10'000 * kMs);
  EXPECT_EQ(link.sink.imu[1].t_ns, 10'004 * kMs);
  EXPECT_EQ(link.sink.imu[2].t_ns, 10'008 * kMs);
  EXPECT_EQ(link.sink.imu[3].t_ns, 10'011 * kMs + kMs / 2);
  const FcImuSample& s = link.sink.imu[0];
  EXPECT_NEAR(s.omega_B_radps.x(), 0.1, 1e-7);
  EXPECT_NEAR(s.omega_B_radps.y(), -0.2, 1e-7);
  EXPECT_NEAR(s.omega_B_radps.z(), 0.3, 1e-7);
  EXPECT_NEAR(s.f_B_mps2.x(), 0.5, 1e-7);
  EXPECT_NEAR(s.f_B_mps2.y(), -0.25, 1e-7);
  EXPECT_NEAR(s.f_B_mps2.z(), -9.75, 1e-6);
  EXPECT_EQ(link.controller->counters().imu_samples, 4u);

  // A repeated (older) stamp maps before the last sample: not emitted.
  ASSERT_TRUE(link.deliver_imu(2'008'000, 10'012 * kMs));
  EXPECT_EQ(link.sink.imu.size(), 4u);

  // The FC reboots: its clock restarts, the offset jumps by seconds and is re-learnt.
  ASSERT_TRUE(link.deliver_imu(50'000, 10'100 * kMs));
  ASSERT_TRUE(link.deliver_imu(54'000, 10'104 * kMs + kMs / 4));
  ASSERT_EQ(link.sink.imu.size(), 6u);
  EXPECT_EQ(link.sink.imu[4].t_ns, 10'100 * kMs);
  EXPECT_EQ(link.sink.imu[5].t_ns, 10'104 * kMs);
}

TEST(MavlinkFc, Px4HeartbeatGivesArmedAndOffboard) {
  Link link;
  EXPECT_FALSE(link.controller->status(link.t_ns).connected);
  EXPECT_EQ(link.controller->status(link.t_ns).heartbeat_age_ns, -1);
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));  // POSCTL, disarmed
  FcStatus s = link.controller->status(link.t_ns);
  EXPECT_TRUE(s.connected);
  EXPECT_FALSE(s.armed);
  EXPECT_FALSE(s.offboard);
  EXPECT_TRUE(link.sink.said("FC connected: PX4, system 1, component 1"));
  EXPECT_EQ(link.controller->describe(),
            "MAVLink udp:127.0.0.1:" + std::to_string(link.port) + " (PX4, system 1)");

  ASSERT_TRUE(link.deliver(px4_heartbeat(true, ml::kPx4MainModeOffboard)));
  s = link.controller->status(link.t_ns);
  EXPECT_TRUE(s.armed);
  EXPECT_TRUE(s.offboard);
  EXPECT_TRUE(link.sink.said("FC armed"));
  EXPECT_TRUE(link.sink.said("FC entered offboard mode"));

  // Said once per change: the same heartbeat again says nothing new.
  const std::size_t events = link.sink.events.size();
  ASSERT_TRUE(link.deliver(px4_heartbeat(true, ml::kPx4MainModeOffboard)));
  EXPECT_EQ(link.sink.events.size(), events);

  // A GCS heartbeat is not the FC.
  ml::Heartbeat gcs;
  gcs.type = 6;
  gcs.autopilot = ml::kMavAutopilotInvalid;
  ASSERT_TRUE(link.deliver(gcs));
  EXPECT_TRUE(link.controller->status(link.t_ns).armed);
}

TEST(MavlinkFc, ArduPilotGuidedNoGpsIsOffboard) {
  Link link;
  ASSERT_TRUE(link.deliver(ardupilot_heartbeat(true, ml::kArduCopterModeGuidedNoGps)));
  FcStatus s = link.controller->status(link.t_ns);
  EXPECT_TRUE(s.armed);
  EXPECT_TRUE(s.offboard);
  EXPECT_THAT(link.controller->describe(), HasSubstr("(ArduPilot, system 1)"));
  ASSERT_TRUE(link.deliver(ardupilot_heartbeat(true, 5)));  // LOITER
  EXPECT_FALSE(link.controller->status(link.t_ns).offboard);
  EXPECT_TRUE(link.sink.said("FC left offboard mode"));
  ASSERT_TRUE(link.deliver(ardupilot_heartbeat(false, 5)));
  EXPECT_TRUE(link.sink.said("FC disarmed"));
}

TEST(MavlinkFc, HeartbeatSilenceBeyondTheTimeoutIsLostOnce) {
  Link link;
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  const std::int64_t heard = link.t_ns;
  link.controller->poll(heard + 900 * kMs, link.sink);
  EXPECT_TRUE(link.controller->status(heard + 900 * kMs).connected);
  EXPECT_EQ(link.controller->status(heard + 900 * kMs).heartbeat_age_ns, 900 * kMs);
  link.controller->poll(heard + 1500 * kMs, link.sink);
  EXPECT_FALSE(link.controller->status(heard + 1500 * kMs).connected);
  ASSERT_FALSE(link.sink.events.empty());
  EXPECT_EQ(link.sink.events.back().severity, FcSeverity::kError);
  EXPECT_THAT(link.sink.events.back().text, HasSubstr("FC silent: nothing heard for 1.5 s"));
  const std::size_t events = link.sink.events.size();
  link.controller->poll(heard + 2000 * kMs, link.sink);
  EXPECT_EQ(link.sink.events.size(), events);
  // Heard again: connected, said once.
  link.t_ns = heard + 2100 * kMs;
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  EXPECT_TRUE(link.controller->status(link.t_ns).connected);
  EXPECT_TRUE(link.sink.events.back().text.starts_with("FC connected"));
}

// A 1 Hz heartbeat a little late is no loss while the FC's IMU still streams: any message from
// the FC keeps it connected; its silence, not a late heartbeat, is the loss.
TEST(MavlinkFc, AnyMessageFromTheFcKeepsItConnected) {
  Link link;
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  const std::int64_t heard = link.t_ns;
  ASSERT_TRUE(link.deliver_imu(1'000'000, heard + 800 * kMs));
  link.controller->poll(heard + 1500 * kMs, link.sink);
  EXPECT_TRUE(link.controller->status(heard + 1500 * kMs).connected);
  EXPECT_EQ(link.controller->status(heard + 1500 * kMs).heartbeat_age_ns, 700 * kMs);
  link.controller->poll(heard + 1900 * kMs, link.sink);
  EXPECT_FALSE(link.controller->status(heard + 1900 * kMs).connected);
}

struct Euler {
  double roll, pitch, yaw;
};
Euler euler_zyx(const std::array<float, 4>& q) {
  const Eigen::Matrix3d R =
      Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
  return {std::atan2(R(2, 1), R(2, 2)), -std::asin(R(2, 0)), std::atan2(R(1, 0), R(0, 0))};
}

TEST(MavlinkFc, SetpointCarriesAttitudeYawAnchorMaskAndThrust) {
  MavlinkFcConfig config;
  config.max_thrust_n = 32.9;
  Link link(config);
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  ASSERT_TRUE(link.deliver_imu(5'000'000, link.t_ns));  // FC clock 5 s at runtime t
  ASSERT_TRUE(link.deliver(attitude_with_yaw(1.0)));

  control::AttitudeSetpoint sp{16.45, 0.1, -0.2, 0.5};
  link.controller->send_setpoint(link.t_ns + 20 * kMs, sp);
  auto got = link.fc.receive_all<ml::SetAttitudeTarget>(kSecond, 1);
  ASSERT_EQ(got.size(), 1u);
  const Euler e = euler_zyx(got[0].q);
  EXPECT_NEAR(e.roll, 0.1, 1e-6);
  EXPECT_NEAR(e.pitch, -0.2, 1e-6);
  EXPECT_NEAR(e.yaw, 1.0, 1e-6) << "anchored to the FC's yaw while not armed and offboard";
  EXPECT_FLOAT_EQ(got[0].thrust, 0.5f);
  EXPECT_EQ(got[0].type_mask,
            ml::kAttitudeTargetIgnoreBodyRollRate | ml::kAttitudeTargetIgnoreBodyPitchRate);
  EXPECT_FLOAT_EQ(got[0].body_yaw_rate_radps, 0.5f);
  EXPECT_EQ(got[0].target_system, 1);
  EXPECT_EQ(got[0].target_component, 1);
  EXPECT_EQ(got[0].time_boot_ms, 5'020u) << "the runtime time in the FC's boot clock";
  EXPECT_EQ(link.controller->counters().setpoints_sent, 1u);

  // Thrust is clamped to 0..1.
  link.controller->send_setpoint(link.t_ns + 30 * kMs, {100.0, 0, 0, 0});
  link.controller->send_setpoint(link.t_ns + 40 * kMs, {-5.0, 0, 0, 0});
  got = link.fc.receive_all<ml::SetAttitudeTarget>(kSecond, 2);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_FLOAT_EQ(got[0].thrust, 1.0f);
  EXPECT_FLOAT_EQ(got[1].thrust, 0.0f);

  // Armed and offboard: yaw integrates the commanded rate from the anchor ...
  ASSERT_TRUE(link.deliver(px4_heartbeat(true, ml::kPx4MainModeOffboard)));
  std::int64_t t = link.t_ns + 100 * kMs;
  for (int i = 0; i <= 10; ++i, t += 10 * kMs) link.controller->send_setpoint(t, sp);
  got = link.fc.receive_all<ml::SetAttitudeTarget>(kSecond, 11);
  ASSERT_EQ(got.size(), 11u);
  EXPECT_NEAR(euler_zyx(got[0].q).yaw, 1.0, 1e-6);
  EXPECT_NEAR(euler_zyx(got[10].q).yaw, 1.0 + 0.5 * 0.1, 1e-5);
  // ... and never leads the FC's yaw (still 1.0) by more than max_yaw_lead_rad.
  for (int i = 0; i < 100; ++i, t += 10 * kMs) link.controller->send_setpoint(t, sp);
  got = link.fc.receive_all<ml::SetAttitudeTarget>(kSecond, 100);
  ASSERT_EQ(got.size(), 100u);
  EXPECT_NEAR(euler_zyx(got.back().q).yaw, 1.0 + config.max_yaw_lead_rad, 1e-5);
}

TEST(MavlinkFc, NonFiniteSetpointIsNeverSent) {
  Link link;
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  const double nan = std::nan("");
  link.controller->send_setpoint(link.t_ns, {nan, 0, 0, 0});
  link.controller->send_setpoint(link.t_ns, {10, nan, 0, 0});
  link.controller->send_setpoint(link.t_ns, {10, 0, 0, std::numeric_limits<double>::infinity()});
  EXPECT_EQ(link.controller->counters().send_failures, 3u);
  EXPECT_EQ(link.controller->counters().setpoints_sent, 0u);
  EXPECT_TRUE(link.fc.receive_all<ml::SetAttitudeTarget>(100 * kMs, 1).empty());
}

VelocityReport velocity_report(std::int64_t t_ns, const Eigen::Vector3d& v_H_mps,
                               double variance_m2ps2, double roll_rad = 0.0,
                               double pitch_rad = 0.0) {
  VelocityReport report;
  report.t_ns = t_ns;
  report.v_H_mps = v_H_mps;
  report.covariance_H_m2ps2 = variance_m2ps2 * Eigen::Matrix3d::Identity();
  report.roll_rad = roll_rad;
  report.pitch_rad = pitch_rad;
  return report;
}

Eigen::Matrix3d velocity_block(const ml::Odometry& odometry) {
  Eigen::Matrix3d m;
  for (std::size_t r = 0; r < 3; ++r) {
    for (std::size_t c = 0; c < 3; ++c) {
      m(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) =
          odometry.velocity_covariance[ml::upper_triangle_index(std::min(r, c), std::max(r, c))];
    }
  }
  return m;
}

TEST(MavlinkFc, OdometryCarriesTheBodyVelocityAndItsCovarianceWithoutAPose) {
  Link link;
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  ASSERT_TRUE(link.deliver_imu(7'000'000, link.t_ns));
  ASSERT_TRUE(link.deliver(attitude_with_yaw(std::numbers::pi / 2)));
  // GIVEN the body pitched 0.3 rad nose up and rolled 0.2 rad, flying 1 m/s forward in H and
  // climbing 0.5 m/s, with an anisotropic covariance in H.
  const double roll = 0.2, pitch = 0.3;
  VelocityReport report =
      velocity_report(link.t_ns + 3 * kMs, Eigen::Vector3d(1.0, 0.0, -0.5), 0.0, roll, pitch);
  report.covariance_H_m2ps2.diagonal() << 0.01, 0.04, 0.09;
  report.covariance_H_m2ps2(0, 1) = report.covariance_H_m2ps2(1, 0) = 0.005;
  report.reset_counter = 4;
  link.controller->send_velocity(report);
  const auto got = link.fc.receive_all<ml::Odometry>(kSecond, 1);
  ASSERT_EQ(got.size(), 1u);
  const ml::Odometry& o = got[0];
  // THEN v_B = R_H_B^T v_H with R_H_B = Ry(pitch) Rx(roll), and the covariance rotated alike.
  const Eigen::Matrix3d R_H_B = (Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                                 Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                    .toRotationMatrix();
  const Eigen::Vector3d v_B = R_H_B.transpose() * report.v_H_mps;
  EXPECT_NEAR(o.vx_mps, v_B.x(), 1e-6);
  EXPECT_NEAR(o.vy_mps, v_B.y(), 1e-6);
  EXPECT_NEAR(o.vz_mps, v_B.z(), 1e-6);
  EXPECT_GT(std::abs(static_cast<double>(o.vz_mps) + 0.5), 0.1)
      << "the pitch turns forward speed into body z";
  const Eigen::Matrix3d covariance_B = R_H_B.transpose() * report.covariance_H_m2ps2 * R_H_B;
  EXPECT_TRUE(velocity_block(o).isApprox(covariance_B, 1e-6)) << velocity_block(o);
  EXPECT_TRUE(std::isnan(o.velocity_covariance[ml::upper_triangle_index(3, 3)]))
      << "angular rates: unknown";
  EXPECT_EQ(o.time_usec, 7'003'000u);
  EXPECT_EQ(o.frame_id, ml::kMavFrameLocalFrd);
  EXPECT_EQ(o.child_frame_id, ml::kMavFrameBodyFrd);
  EXPECT_EQ(o.estimator_type, ml::kMavEstimatorTypeVio);
  EXPECT_EQ(o.reset_counter, 4);
  EXPECT_TRUE(std::isnan(o.x_m) && std::isnan(o.y_m) && std::isnan(o.z_m));
  EXPECT_TRUE(std::isnan(o.q[0]));
  EXPECT_TRUE(std::isnan(o.pose_covariance[0])) << "pose covariance unknown";
  EXPECT_TRUE(std::isnan(o.rollspeed_radps));
  // sigma 0.3 m/s on the worst axis: quality 100 * 0.1 / 0.3 -> 50 (the floor of tracked).
  EXPECT_EQ(o.quality_pct, 50);
  EXPECT_EQ(link.controller->counters().velocity_reports_sent, 1u);
}

TEST(MavlinkFc, OdometryQualityFallsWithTheCovarianceAndIsLowOnACoast) {
  Link link;
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  auto quality = [&](double variance, VelocitySource source) {
    VelocityReport report = velocity_report(link.t_ns, Eigen::Vector3d::Zero(), variance);
    report.source = source;
    link.controller->send_velocity(report);
    const auto got = link.fc.receive_all<ml::Odometry>(kSecond, 1);
    return got.empty() ? -100 : static_cast<int>(got[0].quality_pct);
  };
  EXPECT_EQ(quality(0.01, VelocitySource::kOdometry), 100);
  EXPECT_EQ(quality(0.0025, VelocitySource::kOdometry), 100);
  EXPECT_EQ(quality(0.0144, VelocitySource::kOdometry), 83);  // 0.12 m/s
  EXPECT_EQ(quality(1.0, VelocitySource::kOdometry), 50);
  EXPECT_EQ(quality(0.01, VelocitySource::kInertialCoast), 49);
  EXPECT_EQ(quality(1.0, VelocitySource::kInertialCoast), 1);
}

TEST(MavlinkFc, NonFiniteVelocityIsNotSent) {
  Link link;
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  link.controller->send_velocity(velocity_report(link.t_ns, Eigen::Vector3d(nan, 0, 0), 0.01));
  link.controller->send_velocity(velocity_report(link.t_ns, Eigen::Vector3d::Zero(), nan));
  link.controller->send_velocity(velocity_report(link.t_ns, Eigen::Vector3d::Zero(), 0.01, nan));
  EXPECT_EQ(link.controller->counters().send_failures, 3u);
  EXPECT_EQ(link.controller->counters().velocity_reports_sent, 0u);
  EXPECT_TRUE(link.fc.receive_all<ml::Odometry>(100 * kMs, 1).empty());
}

TEST(MavlinkFc, VisionSpeedEstimateOptionSendsNedVelocityWithRotatedCovariance) {
  MavlinkFcConfig config;
  config.velocity_message = MavlinkFcConfig::VelocityMessage::kVisionSpeedEstimate;
  Link link(config);
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  ASSERT_TRUE(link.deliver_imu(7'000'000, link.t_ns));
  ASSERT_TRUE(link.deliver(attitude_with_yaw(std::numbers::pi / 2)));
  VelocityReport report =
      velocity_report(link.t_ns + 3 * kMs, Eigen::Vector3d(1.0, 0.0, -0.5), 0.0, 0.2, 0.3);
  report.covariance_H_m2ps2.diagonal() << 0.01, 0.04, 0.09;
  report.reset_counter = 2;
  link.controller->send_velocity(report);
  const auto got = link.fc.receive_all<ml::VisionSpeedEstimate>(kSecond, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_NEAR(got[0].x_mps, 0.0, 1e-6);
  EXPECT_NEAR(got[0].y_mps, 1.0, 1e-6);
  EXPECT_NEAR(got[0].z_mps, -0.5, 1e-6);
  EXPECT_EQ(got[0].usec, 7'003'000u);
  // Yaw 90 deg: H's x variance becomes NED's y variance.
  EXPECT_NEAR(got[0].covariance[0], 0.04f, 1e-7);
  EXPECT_NEAR(got[0].covariance[4], 0.01f, 1e-7);
  EXPECT_NEAR(got[0].covariance[8], 0.09f, 1e-7);
  EXPECT_EQ(got[0].reset_counter, 2);
  EXPECT_TRUE(link.fc.receive_all<ml::Odometry>(100 * kMs, 1).empty()) << "no ODOMETRY";
}

TEST(MavlinkFc, ArduPilotWithOdometryIsToldToUseVisionSpeedEstimate) {
  Link link;
  ml::Heartbeat hb = px4_heartbeat(false, 0);
  hb.autopilot = ml::kMavAutopilotArdupilotMega;
  hb.custom_mode = 0;
  ASSERT_TRUE(link.deliver(hb));
  EXPECT_TRUE(link.sink.said("--fc-velocity-message vision_speed_estimate"));
}

// One TIMESYNC round trip: the controller's request at link.t_ns + 200 ms, answered by the FC
// with its clock (the runtime's minus fc_behind_ns, read at the middle of the round trip) and
// received rtt_ns after the request. False if no request came.
bool timesync_round(Link& link, std::int64_t fc_behind_ns, std::int64_t rtt_ns,
                    bool old_protocol = false) {
  link.t_ns += 200 * kMs;
  link.controller->poll(link.t_ns, link.sink);
  // All that came (an earlier request may still wait in the socket): the newest is answered.
  const auto requests = link.fc.receive_all<ml::Timesync>(50 * kMs, 100);
  if (requests.empty() || requests.back().tc1_ns != 0) return false;
  const std::int64_t ts1 = requests.back().ts1_ns;
  ml::Timesync answer;
  answer.tc1_ns = ts1 + rtt_ns / 2 - fc_behind_ns;
  answer.ts1_ns = ts1;
  answer.target_system = old_protocol ? 0 : 1;
  answer.target_component = old_protocol ? 0 : 191;
  link.t_ns = ts1 + rtt_ns;
  return link.deliver(answer);
}

TEST(MavlinkFc, TimesyncOffsetFromAnFcThatAnswersStampsTheImu) {
  Link link;
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  // GIVEN an FC whose clock is 8 s behind ours answering in 2 ms (the old protocol once).
  for (int i = 0; i < 6; ++i) ASSERT_TRUE(timesync_round(link, 8 * kSecond, 2 * kMs, i == 3));
  FcCounters c = link.controller->counters();
  EXPECT_TRUE(c.clock_from_timesync);
  EXPECT_EQ(c.timesync_samples, 6u);
  EXPECT_EQ(c.timesync_offset_ns, 8 * kSecond);
  EXPECT_EQ(c.timesync_rtt_ns, 2 * kMs);
  EXPECT_NEAR(c.timesync_jitter_ns, 0.0, 1.0);
  // WHEN an IMU sample arrives 3 ms after it was taken, THEN it sits at its FC stamp + 8 s, not
  // at its receipt (the least-delayed mapping's answer with one sample).
  const std::int64_t taken_ns = link.t_ns + kSecond;
  ASSERT_TRUE(link.deliver_imu(static_cast<std::uint64_t>((taken_ns - 8 * kSecond) / 1000),
                               taken_ns + 3 * kMs));
  ASSERT_FALSE(link.sink.imu.empty());
  EXPECT_EQ(link.sink.imu.back().t_ns, taken_ns);
  // A slow answer (50 ms round trip) says little of the offset: dropped and counted.
  ASSERT_TRUE(timesync_round(link, 9 * kSecond, 50 * kMs));
  c = link.controller->counters();
  EXPECT_EQ(c.timesync_rejected, 1u);
  EXPECT_EQ(c.timesync_offset_ns, 8 * kSecond);
  // Jittery answers: the filter follows their mean and reports their spread.
  for (int i = 0; i < 40; ++i) {
    ASSERT_TRUE(timesync_round(link, 8 * kSecond + (i % 2 == 0 ? 1 : -1) * kMs / 2, 2 * kMs));
  }
  c = link.controller->counters();
  EXPECT_NEAR(static_cast<double>(c.timesync_offset_ns), 8e9, 0.3e6);
  EXPECT_NEAR(c.timesync_jitter_ns, 0.5e6, 0.2e6);
}

TEST(MavlinkFc, WithoutTimesyncAnswersTheLeastDelayedPacketMapsTheClock) {
  Link link;
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  link.t_ns += 200 * kMs;
  link.controller->poll(link.t_ns, link.sink);
  EXPECT_FALSE(link.fc.receive_all<ml::Timesync>(kSecond, 1).empty()) << "requests go out";
  ASSERT_TRUE(link.deliver_imu(2'000'000, 10'003 * kMs));
  ASSERT_TRUE(link.deliver_imu(2'004'000, 10'005 * kMs));
  const FcCounters c = link.controller->counters();
  EXPECT_FALSE(c.clock_from_timesync);
  EXPECT_EQ(c.timesync_samples, 0u);
  EXPECT_EQ(link.sink.imu.back().t_ns, 10'005 * kMs) << "offset min(receipt - stamp) = 8.001 s";
}

TEST(MavlinkFc, TheFcsOwnTimesyncRequestIsAnsweredWithOurClock) {
  Link link;
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  link.t_ns = 42 * kSecond;
  ASSERT_TRUE(link.deliver(ml::Timesync{0, 777, 0, 0}));
  const auto answers = link.fc.receive_all<ml::Timesync>(100 * kMs, 100);
  bool answered = false;
  for (const auto& a : answers) {
    if (a.tc1_ns == 42 * kSecond && a.ts1_ns == 777) answered = a.target_system == 1;
  }
  EXPECT_TRUE(answered);
}

TEST(MavlinkFc, StatustextAndRefusalsBecomeEvents) {
  Link link;
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  auto text = [](std::uint8_t severity, const char* s) {
    ml::Statustext st;
    st.severity = severity;
    std::memcpy(st.text.data(), s, std::strlen(s));
    return st;
  };
  ASSERT_TRUE(link.deliver(text(2, "Preflight Fail: baro")));  // CRITICAL
  EXPECT_EQ(link.sink.events.back().severity, FcSeverity::kError);
  EXPECT_EQ(link.sink.events.back().text, "Preflight Fail: baro");
  ASSERT_TRUE(link.deliver(text(4, "Low battery")));
  EXPECT_EQ(link.sink.events.back().severity, FcSeverity::kWarning);
  ml::Statustext full = text(6, "");
  full.text.fill('x');  // 50 characters, no NUL
  ASSERT_TRUE(link.deliver(full));
  EXPECT_EQ(link.sink.events.back().severity, FcSeverity::kInfo);
  EXPECT_EQ(link.sink.events.back().text, std::string(50, 'x'));

  ASSERT_TRUE(link.deliver(ml::CommandAck{ml::kMavCmdComponentArmDisarm, 4, 0, 0, 1, 191}));
  EXPECT_EQ(link.sink.events.back().severity, FcSeverity::kError);
  EXPECT_EQ(link.sink.events.back().text,
            "FC refused MAV_CMD_COMPONENT_ARM_DISARM (400): result 4");
  const std::size_t events = link.sink.events.size();
  ASSERT_TRUE(
      link.deliver(ml::CommandAck{ml::kMavCmdDoSetMode, ml::kMavResultAccepted, 0, 0, 1, 191}));
  EXPECT_EQ(link.sink.events.size(), events) << "an accepted command says nothing";

  ml::SysStatus sys;
  sys.voltage_battery_mv = 15'600;
  sys.battery_remaining_pct = 64;
  ASSERT_TRUE(link.deliver(sys));
  EXPECT_DOUBLE_EQ(link.controller->status(link.t_ns).battery_v, 15.6);
  EXPECT_EQ(link.controller->status(link.t_ns).battery_pct, 64);
}

TEST(MavlinkFc, MalformedDatagramsAreCountedAndSurvived) {
  Link link;
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  std::array<std::uint8_t, ml::kMaxFrameSize> frame{};
  ml::Encoder other(1, 1);
  const std::size_t n = other.encode(imu_at(1000), frame);
  std::vector<std::uint8_t> bytes(frame.begin(), frame.begin() + static_cast<std::ptrdiff_t>(n));
  link.fc.send_raw({bytes.begin(), bytes.begin() + 20});  // truncated
  auto bad_crc = bytes;
  bad_crc[15] ^= 0xFF;
  link.fc.send_raw(bad_crc);
  link.fc.send_raw({0x01, 0x02, 0x03});  // garbage
  ASSERT_TRUE(link.poll_until([&] { return link.controller->counters().frames_dropped >= 2; }));
  EXPECT_EQ(link.controller->counters().frames_dropped, 2u);
  EXPECT_TRUE(link.sink.imu.empty());
  ASSERT_TRUE(link.deliver(imu_at(2000)));
  EXPECT_EQ(link.sink.imu.size(), 1u) << "a good frame after the bad ones still arrives";
}

TEST(MavlinkFc, ArmOffboardAndDisarmCommandsCarryTheRightParams) {
  {
    Link link;
    link.controller->request_arm_offboard(link.t_ns);  // nobody heard yet
    EXPECT_EQ(link.controller->counters().send_failures, 1u);
    link.controller->poll(link.t_ns, link.sink);
    EXPECT_TRUE(link.sink.said("autopilot unknown"));

    ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
    // The first heartbeat heard asks for the IMU at 200 Hz and the attitude at 50 Hz.
    const auto intervals = link.fc.receive_all<ml::CommandLong>(kSecond, 2);
    ASSERT_EQ(intervals.size(), 2u);
    EXPECT_EQ(intervals[0].command, ml::kMavCmdSetMessageInterval);
    EXPECT_EQ(intervals[0].param[0], static_cast<float>(ml::HighresImu::kId));
    EXPECT_EQ(intervals[0].param[1], 5000.0f);
    EXPECT_EQ(intervals[1].param[0], static_cast<float>(ml::Attitude::kId));
    EXPECT_EQ(intervals[1].param[1], 20000.0f);
    link.controller->request_arm_offboard(link.t_ns);
    const auto got = link.fc.receive_all<ml::CommandLong>(kSecond, 2);
    ASSERT_EQ(got.size(), 2u);
    EXPECT_EQ(got[0].command, ml::kMavCmdDoSetMode);
    EXPECT_EQ(got[0].param[0], 1.0f);
    EXPECT_EQ(got[0].param[1], 6.0f);
    EXPECT_EQ(got[0].target_system, 1);
    EXPECT_EQ(got[0].target_component, 1);
    EXPECT_EQ(got[1].command, ml::kMavCmdComponentArmDisarm);
    EXPECT_EQ(got[1].param[0], 1.0f);
    link.controller->request_disarm(link.t_ns);
    const auto disarm = link.fc.receive_all<ml::CommandLong>(kSecond, 1);
    ASSERT_EQ(disarm.size(), 1u);
    EXPECT_EQ(disarm[0].command, ml::kMavCmdComponentArmDisarm);
    EXPECT_EQ(disarm[0].param[0], 0.0f);
  }
  {
    Link link;
    ASSERT_TRUE(link.deliver(ardupilot_heartbeat(false, 0)));
    ASSERT_EQ(link.fc.receive_all<ml::CommandLong>(kSecond, 2).size(), 2u);  // stream rates
    link.controller->request_arm_offboard(link.t_ns);
    const auto got = link.fc.receive_all<ml::CommandLong>(kSecond, 2);
    ASSERT_EQ(got.size(), 2u);
    EXPECT_EQ(got[0].command, ml::kMavCmdDoSetMode);
    EXPECT_EQ(got[0].param[0], 1.0f);
    EXPECT_EQ(got[0].param[1], 20.0f);
    EXPECT_EQ(got[1].param[0], 1.0f);
  }
}

TEST(MavlinkFc, HeartbeatIsSentAtTheConfiguredRate) {
  MavlinkFcConfig config;
  config.heartbeat_rate_hz = 2.0;
  Link link(config);  // sent one at t
  const std::int64_t t0 = link.t_ns;
  link.controller->poll(t0 + 100 * kMs, link.sink);
  link.controller->poll(t0 + 499 * kMs, link.sink);
  link.controller->poll(t0 + 500 * kMs, link.sink);
  link.controller->poll(t0 + 700 * kMs, link.sink);
  link.controller->poll(t0 + 1000 * kMs, link.sink);
  const auto got = link.fc.receive_all<ml::Heartbeat>(200 * kMs, 3);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].type, ml::kMavTypeOnboardController);
  EXPECT_EQ(got[0].autopilot, ml::kMavAutopilotInvalid);
  EXPECT_EQ(got[0].system_status, ml::kMavStateActive);
}

struct CountingSink : FcSink {
  int imu = 0, attitude = 0, events = 0;
  void on_imu(const FcImuSample&) override { ++imu; }
  void on_attitude(const FcAttitude&) override { ++attitude; }
  void on_fc_event(FcSeverity, std::string_view) override { ++events; }
};

TEST(MavlinkFc, PollAndSendAllocateNothingAfterTheFirstCall) {
  Link link;
  CountingSink sink;
  ASSERT_TRUE(link.deliver(px4_heartbeat(true, ml::kPx4MainModeOffboard)));
  std::uint64_t stamp_usec = 1'000'000;
  std::int64_t t = link.t_ns;
  // The fake FC's side (encoder, sendto on loopback, which queues at once) allocates nothing
  // either, so its sends may sit inside the counted section.
  const long before = hq::testing::allocation_count();
  for (int i = 0; i < 50; ++i, t += 4 * kMs) {
    link.fc.send(imu_at(stamp_usec += 4000));
    link.fc.send(attitude_with_yaw(0.1));
    link.fc.send(ml::Statustext{6, {'h', 'i'}, 0, 0});
    if (i == 25) link.fc.send(px4_heartbeat(false, 3));  // disarmed, left offboard: events
    link.controller->poll(t, sink);
    link.controller->send_setpoint(t, {15.0, 0.05, -0.05, 0.2});
    link.controller->send_velocity(velocity_report(t, Eigen::Vector3d(0.1, 0.2, 0.3), 0.01));
    link.controller->send_setpoint(t, {std::nan(""), 0, 0, 0});
  }
  link.controller->request_arm_offboard(t);
  link.controller->request_disarm(t);
  link.controller->poll(t + 5 * kSecond, sink);  // heartbeat lost: an event
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
  EXPECT_EQ(sink.imu, 50);
  EXPECT_EQ(sink.attitude, 50);
  EXPECT_GE(sink.events, 50 + 3);
}

TEST(MavlinkFc, ConfigIsReadStrictlyAndValidated) {
  using hq::testing::input_error_message;
  const YAML::Node root = YAML::Load(
      "mavlink: {transport: 'udp:10.0.0.2:14550', system_id: 2, component_id: 192,\n"
      "          heartbeat_timeout_s: 1.5, heartbeat_rate_hz: 2, max_thrust_n: 40,\n"
      "          autopilot: ardupilot, max_yaw_lead_rad: 0.2,\n"
      "          velocity_message: vision_speed_estimate}");
  config::StrictMap map(root, "onboard.yaml");
  config::StrictMap section = map.child("mavlink");
  MavlinkFcConfig c;
  read_config(section, c);
  EXPECT_EQ(c.transport, "udp:10.0.0.2:14550");
  EXPECT_EQ(c.system_id, 2);
  EXPECT_EQ(c.component_id, 192);
  EXPECT_DOUBLE_EQ(c.heartbeat_timeout_s, 1.5);
  EXPECT_DOUBLE_EQ(c.heartbeat_rate_hz, 2.0);
  EXPECT_DOUBLE_EQ(c.max_thrust_n, 40.0);
  EXPECT_EQ(c.autopilot, MavlinkFcConfig::Autopilot::kArduPilot);
  EXPECT_DOUBLE_EQ(c.max_yaw_lead_rad, 0.2);
  EXPECT_EQ(c.velocity_message, MavlinkFcConfig::VelocityMessage::kVisionSpeedEstimate);

  auto read = [](const std::string& yaml) {
    const YAML::Node node = YAML::Load(yaml);
    config::StrictMap root_map(node, "onboard.yaml");
    config::StrictMap s = root_map.child("mavlink");
    MavlinkFcConfig out;
    read_config(s, out);
  };
  EXPECT_THAT(input_error_message([&] { read("mavlink: {max_thrust: 40}"); }),
              HasSubstr("max_thrust"));
  EXPECT_THAT(input_error_message([&] { read("mavlink: {max_thrust_n: -1}"); }),
              HasSubstr("onboard.yaml: mavlink.max_thrust_n = -1"));
  EXPECT_THAT(input_error_message([&] { read("mavlink: {autopilot: inav}"); }),
              HasSubstr("expected one of auto | px4 | ardupilot"));
  EXPECT_THAT(input_error_message([&] { read("mavlink: {velocity_message: vision_speed}"); }),
              HasSubstr("expected one of odometry | vision_speed_estimate"));
  EXPECT_THAT(input_error_message([&] { read("mavlink: {system_id: 300}"); }),
              HasSubstr("mavlink.system_id"));
  EXPECT_THAT(input_error_message([&] { read("mavlink: {transport: ''}"); }),
              HasSubstr("onboard.yaml: mavlink.transport = \"\""));
  EXPECT_THAT(input_error_message([&] { read("mavlink: {gcs: 'serial:/dev/ttyUSB0:57600'}"); }),
              HasSubstr("mavlink.gcs = \"serial:/dev/ttyUSB0:57600\", expected"));
  EXPECT_NO_THROW(read("mavlink: {gcs: 'udp-listen:14550'}"));
  EXPECT_EQ(gcs_transport_spec("udp-listen:14550"), "udp-listen:0.0.0.0:14550");
  EXPECT_EQ(gcs_transport_spec("udp-listen:127.0.0.1:14550"), "udp-listen:127.0.0.1:14550");
  EXPECT_EQ(gcs_transport_spec("udp:10.0.0.5:14550"), "udp:10.0.0.5:14550");

  MavlinkFcConfig bad;
  bad.max_thrust_n = 0.0;
  EXPECT_EQ(input_error_message([&] { MavlinkFlightController fc(bad); }),
            "mavlink.max_thrust_n = 0, expected > 0 and <= 10000");
  MavlinkFcConfig bad_transport;
  bad_transport.transport = "udp:127.0.0.1:99999";
  EXPECT_THAT(input_error_message([&] { MavlinkFlightController fc(bad_transport); }),
              HasSubstr("port 99999 out of range 1..65535"));
}

// A GCS listening on loopback, as QGroundControl does on 14550: every frame it gets, raw, so
// messages the codec does not decode are seen too.
class FakeGcs {
 public:
  explicit FakeGcs(int port)
      : transport_(ml::open_transport("udp-listen:" + std::to_string(port))) {}
  void send(const ml::Message& message) {
    std::array<std::uint8_t, ml::kMaxFrameSize> frame{};
    const std::size_t n = encoder_.encode(message, frame);
    ASSERT_TRUE(transport_->send(std::span<const std::uint8_t>(frame.data(), n)))
        << transport_->error();
  }
  /// Takes what arrived within timeout_ns, until `done` holds.
  bool receive_until(std::int64_t timeout_ns, const std::function<bool()>& done) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
    std::array<std::uint8_t, 2048> buffer{};
    while (!done()) {
      if (std::chrono::steady_clock::now() >= end) return false;
      if (!transport_->wait_readable(5 * kMs)) continue;
      const std::size_t n = transport_->receive(buffer);
      parser_.feed(
          std::span<const std::uint8_t>(buffer.data(), n),
          [&](const ml::FrameHeader& h, const ml::Message& m) {
            messages.push_back({h, m});
          },
          [&](const ml::RawFrame& f) { ids.push_back(f.header.message_id); });
      parser_.end_of_datagram();
    }
    return true;
  }
  [[nodiscard]] int count(std::uint32_t id) const {
    return static_cast<int>(std::count(ids.begin(), ids.end(), id));
  }
  std::vector<Received> messages;
  std::vector<std::uint32_t> ids;

 private:
  std::unique_ptr<ml::Transport> transport_;
  ml::Encoder encoder_{255, 190};
  ml::Parser parser_;
};

ml::Heartbeat gcs_heartbeat() {
  ml::Heartbeat hb;
  hb.type = 6;  // MAV_TYPE_GCS
  hb.autopilot = ml::kMavAutopilotInvalid;
  return hb;
}

TEST(MavlinkFcGcs, FcAndGcsTrafficIsRoutedBothWaysByTarget) {
  const int gcs_port = next_port();
  FakeGcs gcs(gcs_port);
  MavlinkFcConfig config;
  config.gcs = "udp:127.0.0.1:" + std::to_string(gcs_port);
  Link link(config);
  // GIVEN the FC heard WHEN it sends its heartbeat, IMU and a message the codec does not decode
  // THEN the GCS gets all of them, and our own heartbeat too.
  ASSERT_TRUE(link.deliver(px4_heartbeat(true, ml::kPx4MainModeOffboard)));
  ASSERT_TRUE(link.deliver_imu(1000, link.t_ns));
  const std::vector<std::uint8_t> battery_status = {
      0xFD, 2, 0, 0, 0, 1, 1, 147, 0, 0, 9, 9, 0x12, 0x34};  // id 147, CRC not checkable
  link.fc.send_raw(battery_status);
  EXPECT_TRUE(gcs.receive_until(kSecond, [&] {
    link.controller->poll(link.t_ns, link.sink);
    return gcs.count(ml::HighresImu::kId) >= 1 && gcs.count(147) == 1 &&
           gcs.count(ml::Heartbeat::kId) >= 2;
  }));
  int fc_heartbeats = 0;
  int companion_heartbeats = 0;
  for (const Received& r : gcs.messages) {
    if (!std::holds_alternative<ml::Heartbeat>(r.message)) continue;
    (r.header.component_id == 1 ? fc_heartbeats : companion_heartbeats) += 1;
  }
  EXPECT_GE(fc_heartbeats, 1);
  EXPECT_GE(companion_heartbeats, 1) << "the companion shows as a component of the vehicle";

  // WHEN the companion sends a setpoint (addressed to the FC) THEN the GCS does not get it.
  link.controller->send_setpoint(link.t_ns, {15.0, 0.0, 0.0, 0.0});
  const auto setpoints = link.fc.receive_all<ml::SetAttitudeTarget>(kSecond, 1);
  EXPECT_EQ(setpoints.size(), 1u);

  // WHEN the GCS says hello and commands the FC THEN the FC gets both, and the operator is told.
  gcs.send(gcs_heartbeat());
  ml::CommandLong land;
  land.command = ml::kMavCmdDoSetMode;
  land.param = {1, 4, 6, 0, 0, 0, 0};
  land.target_system = 1;
  land.target_component = 1;
  gcs.send(land);
  std::vector<Received> at_fc;
  ASSERT_TRUE(link.poll_until([&] {
    const auto got = link.fc.receive(2 * kMs);
    at_fc.insert(at_fc.end(), got.begin(), got.end());
    return std::any_of(at_fc.begin(), at_fc.end(), [](const Received& r) {
      return std::holds_alternative<ml::CommandLong>(r.message) && r.header.system_id == 255;
    });
  }));
  EXPECT_TRUE(std::any_of(at_fc.begin(), at_fc.end(), [](const Received& r) {
    return std::holds_alternative<ml::Heartbeat>(r.message) && r.header.system_id == 255;
  }));
  EXPECT_TRUE(link.sink.said("GCS heard: system 255, component 190"));
  EXPECT_TRUE(link.sink.said("GCS (system 255) sent MAV_CMD_DO_SET_MODE"));

  // WHEN the FC acks to the GCS THEN the ack goes to the GCS.
  ml::CommandAck ack;
  ack.command = ml::kMavCmdDoSetMode;
  ack.target_system = 255;
  ack.target_component = 190;
  link.fc.send(ack);
  EXPECT_TRUE(gcs.receive_until(kSecond, [&] {
    link.controller->poll(link.t_ns, link.sink);
    return gcs.count(ml::CommandAck::kId) == 1;
  }));

  const std::optional<GcsRouting> routing = link.controller->gcs_routing();
  ASSERT_TRUE(routing.has_value());
  EXPECT_EQ(routing->gcs_system, 255);
  EXPECT_EQ(routing->peer, "127.0.0.1:" + std::to_string(gcs_port));
  EXPECT_GE(routing->fc_to_gcs, 4u);
  EXPECT_EQ(routing->gcs_to_fc, 2u);
  EXPECT_GE(routing->companion_to_gcs, 1u);
  EXPECT_EQ(gcs.count(ml::SetAttitudeTarget::kId), 0) << "setpoints are the FC's alone";
  EXPECT_EQ(routing->router.unchecked_broadcast, 1u);
  EXPECT_EQ(routing->router.dropped(), 0u);
  EXPECT_THAT(link.controller->describe(), HasSubstr("routed to a GCS udp:127.0.0.1:"));
}

TEST(MavlinkFcGcs, ListeningForAGcsLearnsItsAddressFromWhatItSends) {
  const int gcs_port = next_port();
  MavlinkFcConfig config;
  config.gcs = "udp-listen:127.0.0.1:" + std::to_string(gcs_port);
  Link link(config);
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  // Nobody heard yet: the FC's frames have nowhere to go, counted, not an error per frame.
  EXPECT_GE(link.controller->gcs_routing()->gcs_send_failures, 1u);
  EXPECT_EQ(link.controller->gcs_routing()->peer, "");

  auto gcs = ml::open_transport("udp:127.0.0.1:" + std::to_string(gcs_port));
  std::array<std::uint8_t, ml::kMaxFrameSize> frame{};
  ml::Encoder encoder(255, 190);
  const std::size_t n = encoder.encode(gcs_heartbeat(), frame);
  ASSERT_TRUE(gcs->send(std::span<const std::uint8_t>(frame.data(), n)));
  ASSERT_TRUE(link.poll_until([&] { return link.sink.said("GCS heard"); }));
  link.fc.send(px4_heartbeat(false, 3));
  ml::Parser parser;
  int heartbeats_from_fc = 0;
  std::array<std::uint8_t, 2048> rx{};
  for (int i = 0; i < 500 && heartbeats_from_fc == 0; ++i) {
    link.controller->poll(link.t_ns, link.sink);
    for (std::size_t got = gcs->receive(rx); got > 0; got = gcs->receive(rx)) {
      parser.feed(std::span<const std::uint8_t>(rx.data(), got),
                  [&](const ml::FrameHeader& h, const ml::Message& m) {
                    if (std::holds_alternative<ml::Heartbeat>(m) && h.component_id == 1) {
                      ++heartbeats_from_fc;
                    }
                  });
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  EXPECT_EQ(heartbeats_from_fc, 1);
  EXPECT_THAT(link.controller->gcs_routing()->peer, HasSubstr("127.0.0.1:"));
}

TEST(MavlinkFcGcs, OurOdometryReachesTheGcsButOurTimesyncWithTheFcDoesNot) {
  const int gcs_port = next_port();
  FakeGcs gcs(gcs_port);
  MavlinkFcConfig config;
  config.gcs = "udp:127.0.0.1:" + std::to_string(gcs_port);
  Link link(config);
  ASSERT_TRUE(link.deliver(px4_heartbeat(false, 3)));
  // GIVEN the FC heard and answering our TIMESYNC requests (now addressed to it), and sending a
  // request of its own (a broadcast) WHEN we send the velocity
  for (int i = 0; i < 6; ++i) ASSERT_TRUE(timesync_round(link, 8 * kSecond, 2 * kMs));
  ASSERT_TRUE(link.controller->counters().clock_from_timesync);
  ASSERT_TRUE(link.deliver(ml::Timesync{0, 777, 0, 0}));
  link.controller->send_velocity(velocity_report(link.t_ns, Eigen::Vector3d(0.5, 0, 0), 0.01));
  // THEN the GCS gets our ODOMETRY (a broadcast, as our heartbeat) and the FC's request
  auto fc_request_seen = [&] {
    return std::any_of(gcs.messages.begin(), gcs.messages.end(), [](const Received& r) {
      const auto* ts = std::get_if<ml::Timesync>(&r.message);
      return ts != nullptr && r.header.component_id == 1 && ts->tc1_ns == 0 && ts->ts1_ns == 777;
    });
  };
  EXPECT_TRUE(gcs.receive_until(kSecond, [&] {
    link.controller->poll(link.t_ns, link.sink);
    return gcs.count(ml::Odometry::kId) >= 1 && fc_request_seen();
  }));
  // ... but none of our requests addressed to the FC, our answer to it, or its answers to us.
  for (const Received& r : gcs.messages) {
    const auto* ts = std::get_if<ml::Timesync>(&r.message);
    if (ts == nullptr) continue;
    if (r.header.component_id == ml::kMavCompIdOnboardComputer) {
      EXPECT_EQ(ts->target_system, 0) << "only the requests sent before the FC was heard";
    } else {
      EXPECT_EQ(ts->tc1_ns, 0) << "an FC's answer to the companion reached the GCS";
    }
  }
  // WHEN a GCS answers our request itself (as it may answer the early broadcast ones) THEN the
  // answer stays away from the FC and never sets our clock: only the FC's answers do.
  const FcCounters before = link.controller->counters();
  link.t_ns += 200 * kMs;
  link.controller->poll(link.t_ns, link.sink);  // a new request, stamped link.t_ns
  gcs.send(ml::Timesync{link.t_ns - 3 * kSecond, link.t_ns, 1, ml::kMavCompIdOnboardComputer});
  const std::uint64_t routed_before = link.controller->gcs_routing()->router.received[2];
  ASSERT_TRUE(link.poll_until(
      [&] { return link.controller->gcs_routing()->router.received[2] > routed_before; }));
  const FcCounters after = link.controller->counters();
  EXPECT_EQ(after.timesync_samples, before.timesync_samples);
  EXPECT_EQ(after.timesync_rejected, before.timesync_rejected);
  EXPECT_EQ(after.timesync_offset_ns, 8 * kSecond);
  EXPECT_EQ(link.controller->gcs_routing()->gcs_to_fc, 0u);
  EXPECT_EQ(link.controller->gcs_routing()->router.dropped(), 0u);
}

TEST(MavlinkFcGcs, RoutingAllocatesNothingAfterTheFirstCall) {
  const int gcs_port = next_port();
  FakeGcs gcs(gcs_port);
  MavlinkFcConfig config;
  config.gcs = "udp:127.0.0.1:" + std::to_string(gcs_port);
  Link link(config);
  CountingSink sink;
  ASSERT_TRUE(link.deliver(px4_heartbeat(true, ml::kPx4MainModeOffboard)));
  std::int64_t t = link.t_ns;
  std::uint64_t stamp_usec = 1'000'000;
  const long before = hq::testing::allocation_count();
  for (int i = 0; i < 50; ++i, t += 4 * kMs) {
    link.fc.send(imu_at(stamp_usec += 4000));
    link.controller->poll(t, sink);
    link.controller->send_setpoint(t, {15.0, 0.05, -0.05, 0.2});
    link.controller->send_velocity(velocity_report(t, Eigen::Vector3d(0.1, 0.2, 0.3), 0.01));
  }
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
  EXPECT_GE(link.controller->gcs_routing()->fc_to_gcs, 40u);
}

}  // namespace
}  // namespace hq::vehicle
