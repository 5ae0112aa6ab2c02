// The vehicle as on a real vehicle, in real processes on loopback: hq-sim --sitl (the flight
// controller and the camera), hq-onboard --source sitl --fc mavlink:udp (the companion computer)
// and hq-ground --device sim with the scripted hand (the operator), in a private DDS domain, a
// private UDP port and frame channel per test. Also a recorded sequence replayed with --link.
// Assertions come from the three programs' own summaries and status lines.
#include "hq/testing/vehicle_processes.hpp"

#include "hq/testing/loopback_dds.hpp"
#include "hq/testing/process.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <optional>
#include <regex>
#include <signal.h>
#include <sstream>
#include <string>
#include <sys/mman.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

using hq::testing::number_after;
using hq::testing::Process;
using hq::testing::slurp;
using hq::testing::wait_for_text;
using ::testing::HasSubstr;

/// The altitude of hq-sim's latest status line ("..., altitude 1.23 m").
std::optional<double> sim_altitude(const std::filesystem::path& sim_output) {
  return number_after(slurp(sim_output), R"(altitude (-?[0-9.]+) m)");
}

class VehicleProcesses : public ::testing::Test {
 protected:
  void SetUp() override {
    hq::testing::use_loopback_dds();
    const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    const int salt = static_cast<int>(std::hash<std::string>{}(test) % 97);
    domain_ = std::to_string(hq::testing::private_domain_id(0, test, 97));
    port_ = std::to_string(20000 + (getpid() * 7 + salt * 13) % 20000);
    channel_ = "hq-it-" + std::to_string(getpid()) + "-" + std::to_string(salt);
    dir_ = std::filesystem::temp_directory_path() /
           ("hq_vehicle_it_" + std::to_string(getpid()) + "_" + test);
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override {
    // A SIGKILLed hq-sim cannot unlink its frame channel.
    shm_unlink(("/hq-" + channel_).c_str());
    if (!HasFailure()) std::filesystem::remove_all(dir_);
  }
  std::vector<std::string> sim_args(double duration_s) const {
    return {HQ_SIM_EXE,     "--sitl",
            "--world",      "onboard/sim/worlds/arena.yaml",
            "--duration-s", std::to_string(duration_s),
            "--mavlink",    "udp-listen:" + port_,
            "--channel",    channel_};
  }
  std::vector<std::string> onboard_args(double duration_s) const {
    return {HQ_ONBOARD_EXE,
            "--source",
            "sitl",
            "--fc",
            "mavlink:udp:127.0.0.1:" + port_,
            "--channel",
            channel_,
            "--link",
            "--domain-id",
            domain_,
            "--insecure",
            "--duration-s",
            std::to_string(duration_s)};
  }
  std::vector<std::string> ground_args(double duration_s) const {
    return hq::testing::scripted_ground_args(HQ_GROUND_EXE, domain_, duration_s);
  }
  std::filesystem::path file(const char* name) const { return dir_ / name; }

  std::string domain_, port_, channel_;
  std::filesystem::path dir_;
};

// GIVEN the three processes WHEN the scripted hand takes off, flies forward and back and lands
// THEN the vehicle flew it without a collision, landed, and no MAVLink frame was dropped.
TEST_F(VehicleProcesses, ThreeProcessFlightLandsWithoutCollision) {
  Process sim(sim_args(24.0), file("sim.out"));
  ASSERT_TRUE(sim.started());
  Process onboard(onboard_args(30.0), file("onboard.out"));
  ASSERT_TRUE(onboard.started());
  Process ground(ground_args(18.0), file("ground.out"));
  ASSERT_TRUE(ground.started());
  EXPECT_EQ(ground.wait_exit(40.0), 0) << slurp(file("ground.out"));
  EXPECT_EQ(sim.wait_exit(20.0), 0) << slurp(file("sim.out"));
  // The simulator (its flight controller) ended: the companion says so and stops.
  EXPECT_EQ(onboard.wait_exit(15.0), 4) << slurp(file("onboard.out"));

  const std::string sim_out = slurp(file("sim.out"));
  const std::string onboard_out = slurp(file("onboard.out"));
  const std::string ground_out = slurp(file("ground.out"));
  EXPECT_EQ(number_after(sim_out, R"(collision ticks airborne ([0-9]+))"), 0.0) << sim_out;
  EXPECT_GT(number_after(sim_out, R"(max true speed ([0-9.]+) m/s)").value_or(0.0), 0.1)
      << "the vehicle never flew: " << sim_out;
  EXPECT_GT(number_after(sim_out, R"(setpoints received ([0-9]+))").value_or(0.0), 300.0);
  EXPECT_THAT(sim_out, HasSubstr("on the ground"));
  // The FC flies on its own estimate: HaptiQuad's ODOMETRY velocity fused with its IMU, as
  // EKF2 would. Both against the simulator's truth.
  const double received_rmse =
      number_after(sim_out, R"(RMSE against truth \(NED\): received ([0-9.]+) m/s)").value_or(1.0);
  const double fused_rmse =
      number_after(sim_out, R"(fused with the IMU ([0-9.]+) m/s)").value_or(1.0);
  fmt::print(
      "[ figures ] velocity RMSE against truth: HaptiQuad's {:.3f} m/s, the FC's fused {:.3f} "
      "m/s\n",
      received_rmse, fused_rmse);
  EXPECT_LT(received_rmse, 0.15) << sim_out;
  EXPECT_LT(fused_rmse, 0.15) << sim_out;
  EXPECT_THAT(onboard_out, HasSubstr("FC entered offboard mode"));
  EXPECT_EQ(number_after(onboard_out, R"(received, ([0-9]+) dropped)"), 0.0) << onboard_out;
  EXPECT_GT(number_after(ground_out, R"(received +([0-9]+) states)").value_or(0.0), 100.0)
      << ground_out;
}

// GIVEN a flight in progress WHEN hq-sim (the flight controller and the camera) is killed THEN
// hq-onboard says the flight controller is lost and stops.
TEST_F(VehicleProcesses, KillingTheSimulatorMakesTheVehicleSayFcLostAndStop) {
  Process sim(sim_args(60.0), file("sim.out"));
  Process onboard(onboard_args(60.0), file("onboard.out"));
  Process ground(ground_args(40.0), file("ground.out"));
  ASSERT_TRUE(sim.started() && onboard.started() && ground.started());
  ASSERT_TRUE(wait_for_text(file("onboard.out"), "FC entered offboard mode", 20.0))
      << slurp(file("onboard.out"));
  std::this_thread::sleep_for(std::chrono::seconds(2));
  sim.kill_now();
  EXPECT_EQ(onboard.wait_exit(10.0), 4) << slurp(file("onboard.out"));
  const std::string out = slurp(file("onboard.out"));
  EXPECT_THAT(out, HasSubstr("flight controller lost: nothing heard for"));
  EXPECT_THAT(out, HasSubstr("flight controller lost for 3.0 s: stopping"));
  EXPECT_THAT(out, HasSubstr("FC LOST"));
}

// GIVEN the vehicle airborne WHEN hq-ground is killed THEN the link fail-safes hold, then land,
// and the landing is flown through MAVLink: the simulator's vehicle comes down.
TEST_F(VehicleProcesses, KillingTheGroundHoldsThenLandsThroughMavlink) {
  Process sim(sim_args(60.0), file("sim.out"));
  Process onboard(onboard_args(60.0), file("onboard.out"));
  Process ground(ground_args(40.0), file("ground.out"));
  ASSERT_TRUE(sim.started() && onboard.started() && ground.started());
  // Airborne: hq-sim's status line reads an altitude well above the floor.
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(25);
  while (std::chrono::steady_clock::now() < end &&
         sim_altitude(file("sim.out")).value_or(0) < 0.6) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  ASSERT_GE(sim_altitude(file("sim.out")).value_or(0), 0.6) << slurp(file("sim.out"));
  ground.kill_now();
  ASSERT_TRUE(wait_for_text(file("onboard.out"), "fail-safe land", 6.0))
      << slurp(file("onboard.out"));
  EXPECT_THAT(slurp(file("onboard.out")), HasSubstr("fail-safe hold"));
  // Down within 15 s of the land request: at the simulated vehicle's rest height (0.08 m), as a
  // status line a second later confirms.
  constexpr double kOnTheFloorM = 0.09;
  const auto down_by = std::chrono::steady_clock::now() + std::chrono::seconds(15);
  while (std::chrono::steady_clock::now() < down_by &&
         sim_altitude(file("sim.out")).value_or(1) > kOnTheFloorM) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  EXPECT_LE(sim_altitude(file("sim.out")).value_or(1), kOnTheFloorM) << slurp(file("sim.out"));
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  sim.signal(SIGTERM);
  EXPECT_EQ(sim.wait_exit(10.0), 0);
  const std::string sim_out = slurp(file("sim.out"));
  EXPECT_EQ(number_after(sim_out, R"(collision ticks airborne ([0-9]+))"), 0.0) << sim_out;
  EXPECT_THAT(sim_out, HasSubstr("on the ground"));
}

// GIVEN the vehicle airborne, hq-onboard with no run length WHEN it is stopped by SIGTERM THEN
// it lands through MAVLink before it ends, says goodbye to the ground, which acknowledges it and
// raises no link loss for the silence that follows (its status line says ENDED).
TEST_F(VehicleProcesses, SigtermMidFlightLandsThenSaysGoodbyeNotALinkLoss) {
  Process sim(sim_args(90.0), file("sim.out"));
  Process onboard(onboard_args(0.0), file("onboard.out"));
  Process ground(ground_args(60.0), file("ground.out"));
  ASSERT_TRUE(sim.started() && onboard.started() && ground.started());
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(25);
  while (std::chrono::steady_clock::now() < end &&
         sim_altitude(file("sim.out")).value_or(0) < 0.6) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  ASSERT_GE(sim_altitude(file("sim.out")).value_or(0), 0.6) << slurp(file("sim.out"));
  onboard.signal(SIGTERM);
  EXPECT_EQ(onboard.wait_exit(40.0), 0) << slurp(file("onboard.out"));
  const std::string out = slurp(file("onboard.out"));
  EXPECT_THAT(out, HasSubstr("vehicle stopping: landing before the run ends"));
  EXPECT_THAT(out, HasSubstr("vehicle ended: stopped by SIGTERM; landed (goodbye acknowledged"));
  // Down at the simulated vehicle's rest height when hq-onboard ended.
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  EXPECT_LE(sim_altitude(file("sim.out")).value_or(1), 0.09) << slurp(file("sim.out"));
  std::this_thread::sleep_for(std::chrono::seconds(2));
  ground.signal(SIGTERM);
  EXPECT_EQ(ground.wait_exit(20.0), 0) << slurp(file("ground.out"));
  sim.signal(SIGTERM);
  EXPECT_EQ(sim.wait_exit(10.0), 0);
  const std::string ground_out = slurp(file("ground.out"));
  EXPECT_THAT(ground_out, ::testing::Not(HasSubstr("VEHICLE LINK LOST")));
  EXPECT_THAT(ground_out, HasSubstr("link ENDED"));
  EXPECT_EQ(number_after(slurp(file("sim.out")), R"(collision ticks airborne ([0-9]+))"), 0.0);
}

// GIVEN a recorded sequence WHEN hq-onboard replays it with --link THEN a ground station
// receives its states and camera frames, paced as recorded.
TEST_F(VehicleProcesses, ReplayWithLinkReachesTheGround) {
  const std::filesystem::path sequence = file("sequence");
  Process record({HQ_SIM_EXE, "--world", "onboard/sim/worlds/room.yaml", "--duration-s", "6",
                  "--record", sequence.string(), "--script", "circle"},
                 file("record.out"));
  ASSERT_EQ(record.wait_exit(120.0), 0) << slurp(file("record.out"));
  Process ground({HQ_GROUND_EXE, "--device", "sim", "--headless", "--domain-id", domain_,
                  "--insecure", "--duration-s", "12"},
                 file("ground.out"));
  std::this_thread::sleep_for(std::chrono::seconds(1));
  Process onboard(
      {HQ_ONBOARD_EXE, "--source", "replay", sequence.string(), "--camera",
       (sequence / "camera.yaml").string(), "--link", "--domain-id", domain_, "--insecure"},
      file("onboard.out"));
  EXPECT_EQ(onboard.wait_exit(60.0), 0) << slurp(file("onboard.out"));
  EXPECT_EQ(ground.wait_exit(30.0), 0) << slurp(file("ground.out"));
  const std::string onboard_out = slurp(file("onboard.out"));
  const std::string ground_out = slurp(file("ground.out"));
  EXPECT_GE(number_after(onboard_out, R"(hq-onboard: ([0-9]+) frames from)").value_or(0), 150)
      << onboard_out;
  EXPECT_GT(number_after(ground_out, R"(received +([0-9]+) states)").value_or(0.0), 100.0)
      << ground_out;
  EXPECT_GT(
      number_after(ground_out, R"(states, [0-9]+ events, ([0-9]+) camera frames)").value_or(0.0),
      20.0)
      << ground_out;
}

}  // namespace
