// Two (and three) real processes on loopback: hq-sim-flight --link flown by hq-ground
// --device sim with a scripted hand, in a private DDS domain per test process. Assertions come
// from hq-sim-flight's per-step link log (--link-log), written on simulated time that hq-sim-flight
// paces to wall time.
#include "hq/testing/loopback_dds.hpp"
#include "hq/testing/process.hpp"
#include "hq/testing/vehicle_processes.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <unistd.h>
#include <utility>
#include <vector>

namespace {

// One row of hq-sim-flight's --link-log.
struct Row {
  double t_s = 0;
  std::string mode;
  bool landed = false;
  bool airborne = false;
  double command_age_ms = 0;
  double heartbeat_age_ms = 0;
  bool hold = false;
  bool heartbeat_lost = false;
  double v_cmd[3] = {0, 0, 0};
  double v_true[3] = {0, 0, 0};
  double altitude_m = 0;
  bool collision = false;
  long commands_rejected = 0;
  long mode_requests_rejected = 0;
};

std::vector<Row> read_log(const std::string& path) {
  std::ifstream in(path);
  std::vector<Row> rows;
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) f.push_back(cell);
    if (f.size() != 21) continue;
    Row r;
    r.t_s = std::stod(f[0]);
    r.mode = f[1];
    r.landed = f[2] == "1";
    r.airborne = f[3] == "1";
    r.command_age_ms = std::stod(f[4]);
    r.heartbeat_age_ms = std::stod(f[5]);
    r.hold = f[6] == "1";
    r.heartbeat_lost = f[7] == "1";
    for (std::size_t i = 0; i < 3; ++i) r.v_cmd[i] = std::stod(f[8 + i]);
    for (std::size_t i = 0; i < 3; ++i) r.v_true[i] = std::stod(f[12 + i]);
    r.altitude_m = std::stod(f[15]);
    r.collision = f[16] == "1";
    r.commands_rejected = std::stol(f[19]);
    r.mode_requests_rejected = std::stol(f[20]);
    rows.push_back(r);
  }
  return rows;
}

/// The rows of the run itself, up to its --duration-s: after it the vehicle lands before the
/// process ends, as at every end of a run.
std::vector<Row> during_run(std::vector<Row> rows, double duration_s) {
  std::erase_if(rows, [&](const Row& r) { return r.t_s > duration_s; });
  return rows;
}

using hq::testing::slurp;

using hq::testing::Process;

// Follows the (line-buffered) log until a row satisfies `ready`; false after timeout_s.
template <typename Ready>
bool wait_for_row(const std::string& path, double timeout_s, Ready ready) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    for (const Row& r : read_log(path)) {
      if (ready(r)) return true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return false;
}

class LinkProcesses : public ::testing::Test {
 protected:
  void SetUp() override {
    // Loopback only, and a domain of our own: parallel ctest runs and other engineers'
    // processes on this machine never see these samples.
    hq::testing::use_loopback_dds();
    domain_ = std::to_string(hq::testing::private_domain_id(0));
    dir_ = std::filesystem::temp_directory_path() /
           ("hq_link_it_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) std::filesystem::remove_all(dir_);
  }
  std::vector<std::string> onboard_args(double duration_s) const {
    return {HQ_SIM_FLIGHT_EXE,
            "--link",
            "--world",
            "onboard/sim/worlds/arena.yaml",
            "--duration-s",
            std::to_string(duration_s),
            "--domain-id",
            domain_,
            "--insecure",
            "--link-log",
            (dir_ / "link.csv").string()};
  }
  std::vector<std::string> ground_args(double duration_s = 60.0) const {
    return hq::testing::scripted_ground_args(HQ_GROUND_EXE, domain_, duration_s);
  }
  std::vector<std::string> fuzz_args(const std::string& attacks, int station_id, int strength,
                                     double duration_s) const {
    return {HQ_LINK_FUZZ_EXE,
            "--domain-id",
            domain_,
            "--attacks",
            attacks,
            "--station-id",
            std::to_string(station_id),
            "--station-strength",
            std::to_string(strength),
            "--duration-s",
            std::to_string(duration_s),
            "--insecure"};
  }
  // Keys made by hq-keys in dir_/keys: vehicle 1, station 1 for vehicle 1, station 2 for
  // vehicle 2 only.
  std::string make_keys() const {
    std::string keys = (dir_ / "keys").string();
    const auto keys_tool = [&](std::vector<std::string> args) {
      args.insert(args.begin(), HQ_KEYS_EXE);
      Process p(args, (dir_ / "keys.out").string());
      return p.wait_exit(30.0);
    };
    const std::vector<std::vector<std::string>> steps = {
        {"init", keys},
        {"identity", keys, "--role", "vehicle", "--id", "1"},
        {"identity", keys, "--role", "station", "--id", "1", "--vehicles", "1"},
        {"identity", keys, "--role", "station", "--id", "2", "--vehicles", "2"}};
    for (const std::vector<std::string>& step : steps) {
      EXPECT_EQ(keys_tool(step), 0) << out("keys.out");
    }
    return keys;
  }
  // `args` of a process with --insecure, secured by `keys` instead.
  static std::vector<std::string> secured(std::vector<std::string> args, const std::string& keys) {
    const auto insecure = std::find(args.begin(), args.end(), "--insecure");
    *insecure = "--security-dir";
    args.insert(insecure + 1, keys);
    return args;
  }
  std::string log_path() const { return (dir_ / "link.csv").string(); }
  std::string out(const char* name) const { return slurp((dir_ / name).string()); }
  bool wait_airborne(double altitude_m = 0.5) const {
    return wait_for_row(log_path(), 12.0,
                        [&](const Row& r) { return r.airborne && r.altitude_m > altitude_m; });
  }
  std::string domain_;
  std::filesystem::path dir_;
};

TEST_F(LinkProcesses, GroundKilledMidFlightHoldsWithin200msThenLandsAfter2s) {
  Process onboard(onboard_args(16.0), (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  Process ground(ground_args(), (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  // The scripted hand flies forward from 5.5 s to 8 s of its clock: kill it mid-way, once the
  // vehicle is up and moving forward on the hand's command (the climb itself may drift by 0.1
  // m/s, which once killed the hand before it had commanded anything).
  const bool moving = wait_for_row((dir_ / "link.csv").string(), 12.0, [](const Row& r) {
    return r.airborne && r.altitude_m > 0.4 && std::abs(r.v_cmd[0]) + std::abs(r.v_cmd[1]) > 0.1 &&
           std::abs(r.v_true[0]) + std::abs(r.v_true[1]) > 0.1;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ground.kill_now();
  ASSERT_TRUE(moving) << slurp((dir_ / "onboard.out").string());
  ASSERT_EQ(onboard.wait_exit(30.0), 0) << slurp((dir_ / "onboard.out").string());

  const std::vector<Row> rows = read_log((dir_ / "link.csv").string());
  ASSERT_GT(rows.size(), 100U);
  // The last row flown on a fresh command while airborne, then the first hold after it.
  std::size_t last_fresh = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (!rows[i].hold && rows[i].airborne) last_fresh = i;
  }
  ASSERT_GT(last_fresh, 0U) << "never flew on a fresh command";
  ASSERT_LT(last_fresh + 1, rows.size());
  const Row& fresh = rows[last_fresh];
  const Row& held = rows[last_fresh + 1];
  EXPECT_GT(fresh.altitude_m, 0.3) << "killed before it was flying";
  EXPECT_GT(std::abs(fresh.v_cmd[0]) + std::abs(fresh.v_cmd[1]), 0.05)
      << "killed while the hand was not commanding a velocity";
  ASSERT_TRUE(held.hold);
  EXPECT_EQ(held.v_cmd[0], 0.0);
  EXPECT_EQ(held.v_cmd[1], 0.0);
  EXPECT_EQ(held.v_cmd[2], 0.0);
  // The log has a row per frame (30 Hz); hq-sim-flight prints the transitions at the 5 ms control
  // tick where they happen: the first tick past 200 ms, and past 2 s without a heartbeat.
  const std::string out = slurp((dir_ / "onboard.out").string());
  double hold_t_s = 0;
  double hold_age_ms = 0;
  double land_t_s = 0;
  double land_age_ms = 0;
  const std::size_t hold_at = out.find("fail-safe hold");
  const std::size_t land_at = out.find("fail-safe land");
  ASSERT_NE(hold_at, std::string::npos) << out;
  ASSERT_NE(land_at, std::string::npos) << out;
  ASSERT_EQ(std::sscanf(out.c_str() + out.rfind("t ", hold_at),
                        "t %lf s: fail-safe hold, command age %lf", &hold_t_s, &hold_age_ms),
            2);
  ASSERT_EQ(std::sscanf(out.c_str() + out.rfind("t ", land_at),
                        "t %lf s: fail-safe land, heartbeat age %lf", &land_t_s, &land_age_ms),
            2);
  EXPECT_GT(hold_age_ms, 200.0);
  EXPECT_LE(hold_age_ms, 205.0);
  EXPECT_GT(land_age_ms, 2000.0);
  EXPECT_LE(land_age_ms, 2005.0);
  EXPECT_LE(held.t_s - hold_t_s, 0.034) << "the first logged hold row is the next frame";

  // Land: switched at once, then on the ground before the end.
  std::size_t land = last_fresh + 1;
  while (land < rows.size() && rows[land].mode != "land") ++land;
  ASSERT_LT(land, rows.size()) << "never switched to land";
  EXPECT_TRUE(rows[land].heartbeat_lost);
  EXPECT_LE(rows[land].t_s - land_t_s, 0.034);
  for (std::size_t i = last_fresh + 1; i < land; ++i) {
    EXPECT_TRUE(rows[i].hold);
    EXPECT_EQ(rows[i].mode, "teleop");
  }
  std::size_t touchdown = land;
  while (touchdown < rows.size() && rows[touchdown].airborne) ++touchdown;
  ASSERT_LT(touchdown, rows.size()) << "still in the air at the end";
  EXPECT_FALSE(rows.back().airborne);
  for (const Row& r : rows) EXPECT_FALSE(r.collision) << r.t_s;
  fmt::print(
      "[ figures  ] hold at command age {:.1f} ms; land at heartbeat age {:.1f} ms, {:.2f} s after "
      "the hold; on the ground {:.2f} s after the land request (from {:.2f} m)\n",
      hold_age_ms, land_age_ms, land_t_s - hold_t_s, rows[touchdown].t_s - land_t_s,
      rows[land].altitude_m);
}

TEST_F(LinkProcesses, FuzzedVehicleKeepsFlyingAndCountsRejections) {
  Process onboard(onboard_args(11.0), (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  Process ground(ground_args(), (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  ASSERT_TRUE(wait_for_row((dir_ / "link.csv").string(), 10.0, [](const Row& r) {
    return r.airborne && r.altitude_m > 0.5;
  })) << slurp((dir_ / "onboard.out").string());
  Process fuzz({HQ_LINK_FUZZ_EXE, "--domain-id", domain_, "--duration-s", "4", "--insecure"},
               (dir_ / "fuzz.out").string());
  ASSERT_TRUE(fuzz.started());
  EXPECT_EQ(fuzz.wait_exit(20.0), 0) << slurp((dir_ / "fuzz.out").string());
  ASSERT_EQ(onboard.wait_exit(30.0), 0) << slurp((dir_ / "onboard.out").string());

  const std::vector<Row> rows = during_run(read_log((dir_ / "link.csv").string()), 11.0);
  ASSERT_GT(rows.size(), 100U);
  for (const Row& r : rows) {
    ASSERT_FALSE(r.collision) << r.t_s;
    for (int i = 0; i < 3; ++i) ASSERT_TRUE(std::isfinite(r.v_cmd[i])) << r.t_s;
    ASSERT_LE(std::abs(r.v_cmd[0]), 2.0) << r.t_s;
  }
  const Row& last = rows.back();
  EXPECT_TRUE(last.airborne) << "landed or fell under fuzzing";
  EXPECT_GT(last.altitude_m, 0.3);
  EXPECT_NE(last.mode, "land");
  EXPECT_GT(last.commands_rejected, 1000) << slurp((dir_ / "fuzz.out").string());
  EXPECT_GT(last.mode_requests_rejected, 0);
  fmt::print("[ figures  ] {} commands and {} mode requests rejected; final altitude {:.2f} m\n{}",
             last.commands_rejected, last.mode_requests_rejected, last.altitude_m,
             slurp((dir_ / "fuzz.out").string()).c_str());
}

// Every attack at once, both directions, on a plain link (issue 39 reported 936 collision ticks
// for this run; on this code it hits nothing). hq-sim-flight exits 3 on any collision tick.
TEST_F(LinkProcesses, AllAttacksAtOnceHitNothing) {
  Process onboard(onboard_args(14.0), (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  Process ground(ground_args(), (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  ASSERT_TRUE(wait_airborne()) << out("onboard.out");
  Process fuzz(fuzz_args("malformed,commands,requests,replay,heartbeats,states", 666, 200, 8.0),
               (dir_ / "fuzz.out").string());
  ASSERT_TRUE(fuzz.started());
  EXPECT_EQ(fuzz.wait_exit(30.0), 0) << out("fuzz.out");
  EXPECT_EQ(onboard.wait_exit(30.0), 0) << out("onboard.out");
  ground.kill_now();
  const std::vector<Row> rows = read_log(log_path());
  ASSERT_GT(rows.size(), 100U);
  for (const Row& r : rows) EXPECT_FALSE(r.collision) << r.t_s;
  const std::string onboard_out = out("onboard.out");
  EXPECT_NE(onboard_out.find("collision ticks                          0\n"), std::string::npos)
      << onboard_out;
  fmt::print("[ figures  ] {} commands rejected; fuzzer:\n{}", rows.back().commands_rejected,
             out("fuzz.out").c_str());
}

// Ownership, sessions, escalation, checked telemetry. Each < 20 s.

// (a) GIVEN station 1 (hq-ground, strength 100) flying in teleop, WHEN a weaker station 2 sends
// well-formed hover/land requests for the vehicle's current session, THEN they are rejected (it
// does not command the vehicle) and the vehicle keeps flying in teleop.
TEST_F(LinkProcesses, WeakerStationsModeRequestsAreIgnoredWhileTheStrongerCommands) {
  Process onboard(onboard_args(10.0), (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  Process ground(ground_args(), (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  ASSERT_TRUE(wait_airborne()) << out("onboard.out");
  const long rejected_before = read_log(log_path()).back().mode_requests_rejected;
  Process fuzz(fuzz_args("requests", 2, 50, 3.0), (dir_ / "fuzz.out").string());
  ASSERT_TRUE(fuzz.started());
  ASSERT_EQ(fuzz.wait_exit(15.0), 0) << out("fuzz.out");
  ASSERT_EQ(onboard.wait_exit(20.0), 0) << out("onboard.out");
  const std::vector<Row> rows = during_run(read_log(log_path()), 10.0);
  ASSERT_GT(rows.size(), 100U);
  bool after = false;
  for (const Row& r : rows) {
    after = after || r.mode_requests_rejected > rejected_before;
    if (after) {
      EXPECT_EQ(r.mode, "teleop") << r.t_s << ": a weaker station's request was obeyed";
    }
    EXPECT_FALSE(r.collision) << r.t_s;
  }
  EXPECT_TRUE(rows.back().airborne);
  EXPECT_GE(rows.back().mode_requests_rejected - rejected_before, 4) << out("fuzz.out");
  const std::string onboard_out = out("onboard.out");
  EXPECT_NE(onboard_out.find("commanded by station 1"), std::string::npos) << onboard_out;
  EXPECT_EQ(onboard_out.find("commanded by station 2"), std::string::npos) << onboard_out;
  fmt::print("[ figures  ] {} requests of the weaker station rejected; fuzzer:\n{}",
             rows.back().mode_requests_rejected - rejected_before, out("fuzz.out").c_str());
}

// (b) GIVEN a vehicle flown by station 1 and a station 666 that only sends heartbeats, WHEN
// station 1 is killed, THEN 666's heartbeats do not keep the link: it lands 2 s later for the
// lost heartbeat (not only after the hold's escalation) and is on the floor at the end.
TEST_F(LinkProcesses, ForeignHeartbeatsDoNotKeepAVehicleWhoseCommanderWasKilledInTheAir) {
  Process onboard(onboard_args(14.0), (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  Process ground(ground_args(), (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  ASSERT_TRUE(wait_airborne()) << out("onboard.out");
  Process fuzz(fuzz_args("heartbeats", 666, 50, 12.0), (dir_ / "fuzz.out").string());
  ASSERT_TRUE(fuzz.started());
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  ground.kill_now();
  ASSERT_EQ(onboard.wait_exit(30.0), 0) << out("onboard.out");
  fuzz.kill_now();
  const std::string onboard_out = out("onboard.out");
  double hold_t_s = 0;
  double land_t_s = 0;
  double age_ms = 0;
  const std::size_t hold_at = onboard_out.find("fail-safe hold");
  const std::size_t land_at = onboard_out.find("fail-safe land, heartbeat age");
  ASSERT_NE(hold_at, std::string::npos) << onboard_out;
  ASSERT_NE(land_at, std::string::npos) << "foreign heartbeats kept the link alive\n"
                                        << onboard_out;
  ASSERT_EQ(std::sscanf(onboard_out.c_str() + onboard_out.rfind("t ", hold_at), "t %lf", &hold_t_s),
            1);
  ASSERT_EQ(std::sscanf(onboard_out.c_str() + onboard_out.rfind("t ", land_at),
                        "t %lf s: fail-safe land, heartbeat age %lf", &land_t_s, &age_ms),
            2);
  EXPECT_LT(land_t_s - hold_t_s, 2.1);  // the heartbeat's 2 s, not the hold's 5 s
  EXPECT_NEAR(age_ms, 2000.0, 10.0);
  const std::vector<Row> rows = read_log(log_path());
  ASSERT_GT(rows.size(), 100U);
  EXPECT_FALSE(rows.back().airborne) << "still in the air at the end";
  for (const Row& r : rows) EXPECT_FALSE(r.collision) << r.t_s;
  fmt::print(
      "[ figures  ] hold at {:.2f} s, land at {:.2f} s (heartbeat age {:.1f} ms) with station 666 "
      "sending heartbeats\n",
      hold_t_s, land_t_s, age_ms);
}

// (c) GIVEN heartbeats that never time out (60 s), WHEN the commands stop, THEN the vehicle
// holds after 200 ms and lands hold_to_land (1.5 s) later, once.
TEST_F(LinkProcesses, CommandsStopHoldThenLandAfterHoldToLand) {
  std::vector<std::string> args = onboard_args(13.0);
  for (const char* a : {"--heartbeat-timeout-ms", "60000", "--hold-to-land-s", "1.5"}) {
    args.emplace_back(a);
  }
  Process onboard(args, (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  Process ground(ground_args(), (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  ASSERT_TRUE(wait_airborne()) << out("onboard.out");
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  ground.kill_now();
  ASSERT_EQ(onboard.wait_exit(30.0), 0) << out("onboard.out");
  const std::string onboard_out = out("onboard.out");
  const std::size_t land_at = onboard_out.find("fail-safe land after hold");
  ASSERT_NE(land_at, std::string::npos) << onboard_out;
  EXPECT_EQ(onboard_out.find("fail-safe land, heartbeat"), std::string::npos);
  EXPECT_EQ(onboard_out.find("fail-safe land", land_at + 1), std::string::npos) << "landed twice";
  double land_t_s = 0;
  double age_ms = 0;
  ASSERT_EQ(std::sscanf(onboard_out.c_str() + onboard_out.rfind("t ", land_at),
                        "t %lf s: fail-safe land after hold, command age %lf", &land_t_s, &age_ms),
            2);
  EXPECT_GT(age_ms, 1700.0);  // command_timeout 200 ms + hold_to_land 1.5 s
  EXPECT_LE(age_ms, 1706.0);
  const std::vector<Row> rows = read_log(log_path());
  ASSERT_GT(rows.size(), 100U);
  std::size_t land = 0;
  while (land < rows.size() && rows[land].t_s < land_t_s) ++land;
  for (std::size_t i = land; i < rows.size(); ++i) {
    if (rows[i].t_s > land_t_s + 0.05) {
      EXPECT_EQ(rows[i].mode, "land") << rows[i].t_s;
    }
  }
  EXPECT_FALSE(rows.back().airborne) << "still in the air at the end";
  fmt::print("[ figures  ] land after hold at command age {:.1f} ms (t {:.2f} s)\n", age_ms,
             land_t_s);
}

// (d) GIVEN a station that asked vehicle instance 1 for teleop (a TRANSIENT_LOCAL request),
// WHEN the vehicle process restarts, THEN instance 2 rejects the predecessor's request (another
// session) and stays on the floor; the station says the vehicle restarted and re-sends nothing.
TEST_F(LinkProcesses, RestartedVehicleIgnoresTheRequestMadeToItsPredecessor) {
  Process first(onboard_args(20.0), (dir_ / "onboard1.out").string());
  ASSERT_TRUE(first.started());
  Process ground(ground_args(), (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  ASSERT_TRUE(wait_airborne(0.3)) << out("onboard1.out");
  first.kill_now();
  std::vector<std::string> args = onboard_args(4.0);
  args.back() = (dir_ / "link2.csv").string();
  Process second(args, (dir_ / "onboard2.out").string());
  ASSERT_TRUE(second.started());
  ASSERT_EQ(second.wait_exit(20.0), 0) << out("onboard2.out");
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ground.kill_now();
  const std::vector<Row> rows = read_log((dir_ / "link2.csv").string());
  ASSERT_GT(rows.size(), 50U) << out("onboard2.out");
  for (const Row& r : rows) {
    EXPECT_NE(r.mode, "teleop") << r.t_s << ": obeyed the predecessor's request";
    EXPECT_FALSE(r.airborne) << r.t_s;
  }
  EXPECT_GE(rows.back().mode_requests_rejected, 1) << out("onboard2.out");
  const std::string ground_out = out("ground.out");
  EXPECT_NE(ground_out.find("restarted (new session"), std::string::npos) << ground_out;
  fmt::print("[ figures  ] instance 2 rejected {} stale request(s) and stayed on the floor\n",
             rows.back().mode_requests_rejected);
}

// (e) GIVEN hq-ground flying a vehicle, WHEN forged vehicle states (another session, NaN, 1e6
// m/s, sequence backwards or jumping ahead, roll 7 rad) and forged events flood its inbound
// topics, THEN they are rejected and counted, the hand's force stays what the real flight gives
// and the passivity observer stays near zero.
TEST_F(LinkProcesses, ForgedStatesAreRejectedAndTheHandsForceStaysBounded) {
  Process onboard(onboard_args(11.0), (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  std::vector<std::string> args = ground_args(9.0);
  args.emplace_back("--state-json");
  args.emplace_back((dir_ / "ground.json").string());
  Process ground(args, (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  ASSERT_TRUE(wait_airborne(0.3)) << out("onboard.out");
  Process fuzz(fuzz_args("states", 666, 50, 4.0), (dir_ / "fuzz.out").string());
  ASSERT_TRUE(fuzz.started());
  ASSERT_EQ(fuzz.wait_exit(15.0), 0) << out("fuzz.out");
  ASSERT_EQ(ground.wait_exit(20.0), 0) << out("ground.out");
  onboard.kill_now();
  const std::string json = out("ground.json");
  const auto number = [&](const char* key) {
    const std::size_t at = json.find(std::string("\"") + key + "\": ");
    EXPECT_NE(at, std::string::npos) << key << "\n" << json;
    return at == std::string::npos ? -1.0 : std::atof(json.c_str() + at + std::strlen(key) + 4);
  };
  EXPECT_GT(number("states_rejected"), 50.0) << json;
  // States are keep-last 1 per vehicle: forged and real ones overwrite each other in the
  // reader, so only part of each kind is taken; each kind must show up.
  EXPECT_GT(number("states_wrong_session"), 5.0) << json;
  EXPECT_GT(number("states_implausible"), 10.0) << json;
  EXPECT_GT(number("states_received"), 100.0) << json;
  // The sim hand's real flight peaks at 3.4 N (measured without forgeries); a believed
  // forgery (12-17 m/s) saturates the 8 N limit.
  EXPECT_LT(number("max_force_n"), 5.0) << json;
  EXPECT_GT(number("passivity_min_energy_j"), -0.05) << json;
  const std::string ground_out = out("ground.out");
  EXPECT_EQ(ground_out.find("FORGED"), std::string::npos) << "a forged event was shown";
  fmt::print(
      "[ figures  ] ground: {:.0f} states rejected ({:.0f} other session, {:.0f} implausible), max "
      "force {:.3f} N, passivity min {:.4f} J\n{}",
      number("states_rejected"), number("states_wrong_session"), number("states_implausible"),
      number("max_force_n"), number("passivity_min_energy_j"), out("fuzz.out").c_str());
}

// (f) GIVEN hq-ground station 1 flying, WHEN a second hq-ground (station 2) with the highest
// strength starts, THEN the vehicle follows station 2 and station 1 says it lost control
// (stdout once, --state-json), instead of showing "link ok".
TEST_F(LinkProcesses, StationThatLostControlShowsIt) {
  Process onboard(onboard_args(12.0), (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  std::vector<std::string> args = ground_args(8.0);
  args.emplace_back("--state-json");
  args.emplace_back((dir_ / "ground.json").string());
  Process ground(args, (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  ASSERT_TRUE(wait_airborne()) << out("onboard.out");
  std::vector<std::string> strong = ground_args(20.0);
  for (const char* a : {"--station-id", "2", "--station-strength", "2147483647"}) {
    strong.emplace_back(a);
  }
  Process thief(strong, (dir_ / "ground2.out").string());
  ASSERT_TRUE(thief.started());
  ASSERT_EQ(ground.wait_exit(20.0), 0) << out("ground.out");
  thief.kill_now();
  onboard.kill_now();
  const std::string json = out("ground.json");
  EXPECT_NE(json.find("\"control_lost\": true"), std::string::npos) << json;
  EXPECT_NE(json.find("\"commanding_station_id\": 2"), std::string::npos) << json;
  const std::string ground_out = out("ground.out");
  const std::string banner = "hq-ground: CONTROL LOST: station 2 commands vehicle 1";
  const std::size_t at = ground_out.find(banner);
  EXPECT_NE(at, std::string::npos) << ground_out;
  EXPECT_EQ(ground_out.find(banner, at + 1), std::string::npos) << "said more than once";
  EXPECT_NE(out("onboard.out").find("commanded by station 2"), std::string::npos);
}

// (g) GIVEN a vehicle that only station 1 may command (--stations 1), WHEN a station 7 with
// the highest strength sends in-envelope hostile commands (full speed ahead, then oscillating),
// THEN they are rejected (DDS hands it the command instance, so the vehicle holds), the vehicle
// never follows station 7 and hits nothing.
TEST_F(LinkProcesses, HostileCommandsFromAStationNotListedAreRejected) {
  std::vector<std::string> args = onboard_args(10.0);
  args.emplace_back("--stations");
  args.emplace_back("1");
  Process onboard(args, (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  Process ground(ground_args(), (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  ASSERT_TRUE(wait_airborne()) << out("onboard.out");
  Process fuzz(fuzz_args("commands", 7, 2147483647, 3.0), (dir_ / "fuzz.out").string());
  ASSERT_TRUE(fuzz.started());
  ASSERT_EQ(fuzz.wait_exit(15.0), 0) << out("fuzz.out");
  ASSERT_EQ(onboard.wait_exit(20.0), 0) << out("onboard.out");
  ground.kill_now();
  const std::string onboard_out = out("onboard.out");
  EXPECT_EQ(onboard_out.find("commanded by station 7"), std::string::npos) << onboard_out;
  const std::vector<Row> rows = read_log(log_path());
  ASSERT_GT(rows.size(), 100U);
  for (const Row& r : rows) EXPECT_FALSE(r.collision) << r.t_s;
  const long rejected = rows.back().commands_rejected;
  EXPECT_GT(rejected, 100) << onboard_out;
  fmt::print("[ figures  ] {} commands of station 7 rejected (not in link.stations)\n{}", rejected,
             out("fuzz.out").c_str());
}

// (h) A stronger station the vehicle is allowed to follow (no link.stations) flies it
// with in-envelope commands, full speed (1.8 m/s) ahead then 4 Hz side to side. Ownership
// passes to it (station 1 is told), and the seen-space limit keeps it off the walls: before the
// limit, the arena run hit a wall (66 collision ticks, clearance -0.35 m).
TEST_F(LinkProcesses, HostileInEnvelopeCommandsOfAnAllowedStationHitNothing) {
  Process onboard(onboard_args(12.0), (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  Process ground(ground_args(), (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  ASSERT_TRUE(wait_airborne()) << out("onboard.out");
  Process fuzz(fuzz_args("commands", 7, 2147483647, 8.0), (dir_ / "fuzz.out").string());
  ASSERT_TRUE(fuzz.started());
  onboard.wait_exit(30.0);
  fuzz.kill_now();
  ground.kill_now();
  EXPECT_NE(out("onboard.out").find("commanded by station 7"), std::string::npos);
  const std::vector<Row> rows = read_log(log_path());
  ASSERT_GT(rows.size(), 100U);
  for (const Row& r : rows) EXPECT_FALSE(r.collision) << r.t_s;
}

// DDS Security end to end, keys made by hq-keys: the vehicle flies on a secured station's
// commands; a station listed for another vehicle is refused, naming the writer; hq-sim-flight
// without keys and without --insecure says how to make them.
TEST_F(LinkProcesses, SecuredStationFliesItsVehicleOthersAreRefused) {
  const std::string keys = make_keys();
  const auto secured = [&](std::vector<std::string> args) {
    return LinkProcesses::secured(std::move(args), keys);
  };

  {
    std::vector<std::string> args = onboard_args(1.0);
    args.erase(std::find(args.begin(), args.end(), "--insecure"));
    Process no_keys(args, (dir_ / "no_keys.out").string());
    EXPECT_EQ(no_keys.wait_exit(30.0), 2);
    const std::string out = slurp((dir_ / "no_keys.out").string());
    EXPECT_NE(out.find("hq-keys identity KEYS --role vehicle --id 1"), std::string::npos) << out;
  }
  {
    std::vector<std::string> args = secured(ground_args());
    args.insert(args.end(), {"--station-id", "2"});
    Process other(args, (dir_ / "other.out").string());
    EXPECT_EQ(other.wait_exit(30.0), 2);
    const std::string out = slurp((dir_ / "other.out").string());
    EXPECT_NE(out.find("dds_create_writer(hq_velocity_command): Not Allowed By Security"),
              std::string::npos)
        << out;
  }

  Process onboard(secured(onboard_args(9.0)), (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  Process ground(secured(ground_args()), (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  EXPECT_TRUE(wait_for_row((dir_ / "link.csv").string(), 12.0,
                           [](const Row& r) { return r.airborne && r.altitude_m > 0.5; }))
      << slurp((dir_ / "onboard.out").string()) << slurp((dir_ / "ground.out").string());
  EXPECT_EQ(onboard.wait_exit(30.0), 0) << slurp((dir_ / "onboard.out").string());
}

// hq-link-fuzz on a secured vehicle attacks with the credentials it is given and reports what
// the secured link refused. Before, it ignored them and attacked on plain DDS: nothing arrived,
// yet it printed "0 refused" and exited 0, so a secured fuzz run read as a pass.
TEST_F(LinkProcesses, SecuredFuzzAttacksWithItsCredentialsAndReportsWhatWasRefused) {
  const std::string keys = make_keys();
  Process onboard(secured(onboard_args(14.0), keys), (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  ASSERT_TRUE(wait_for_row(log_path(), 12.0, [](const Row&) { return true; }))
      << out("onboard.out");
  const auto run_fuzz = [&](const std::vector<std::string>& args, const char* name) {
    Process fuzz(args, (dir_ / name).string());
    return fuzz.wait_exit(20.0);
  };

  // Station 2's credentials grant vehicle 2 only: every writer and reader is refused, nothing
  // reaches vehicle 1, and the run says it tested nothing.
  EXPECT_EQ(
      run_fuzz(secured(fuzz_args("malformed,commands,states", 2, 200, 3.0), keys), "other.out"), 3)
      << out("other.out");
  const std::string other = out("other.out");
  EXPECT_NE(other.find("refused by the secured link: dds_create_writer(hq_velocity_command): "
                       "Not Allowed By Security"),
            std::string::npos)
      << other;
  EXPECT_NE(other.find("NOT REACHED"), std::string::npos) << other;

  // No credentials at all: plain DDS never meets the secured vehicle.
  EXPECT_EQ(run_fuzz(fuzz_args("malformed", 666, 200, 3.0), "plain.out"), 3) << out("plain.out");
  EXPECT_NE(out("plain.out").find("NOT REACHED"), std::string::npos) << out("plain.out");

  // Station 1's credentials, its samples claiming station 666: the malformed commands reach the
  // vehicle (which rejects them) and its requests are rejected; the vehicle-state writer the
  // station's permissions deny is refused, and the forgeries it would have sent are counted.
  const long rejected_before = read_log(log_path()).back().commands_rejected;
  std::vector<std::string> own = secured(fuzz_args("malformed,requests,states", 1, 200, 3.0), keys);
  own.insert(own.end(), {"--identity", "station_1", "--claim-station", "666"});
  EXPECT_EQ(run_fuzz(own, "own.out"), 0) << out("own.out");
  const std::string report = out("own.out");
  EXPECT_NE(report.find("refused by the secured link: dds_create_writer(hq_vehicle_state): "
                        "Not Allowed By Security"),
            std::string::npos)
      << report;
  EXPECT_EQ(report.find("NOT REACHED"), std::string::npos) << report;
  EXPECT_EQ(report.find(" 0 of 0 states"), std::string::npos) << "saw no vehicle state\n" << report;
  ASSERT_EQ(onboard.wait_exit(30.0), 0) << out("onboard.out");
  EXPECT_GT(read_log(log_path()).back().commands_rejected - rejected_before, 100) << report;
  fmt::print("[ figures  ] station 2 (vehicle 2's):\n{}[ figures  ] station 1's credentials:\n{}",
             other, report);
}

// GIVEN a secured vehicle that allows stations 1 and 3 (both certified for it) and station 1
// flying it, WHEN station 3's certificate sends commands, mode requests (hover/land at 2 Hz) and
// heartbeats claiming station 1, THEN the vehicle flies none of them: station 1 keeps command
// and is never told it lost control, the vehicle reports the intrusion and station 1's console
// shows it; and the shipped hq-ground told --identity station_3 --station-id 1 cannot start.
// Before, the claim was taken at its word: the land request was obeyed mid-flight and the real
// station kept showing "control held, 0 losses".
TEST_F(LinkProcesses, AllowedStationSpeakingForAnotherIsRefusedAndReportedAsIntrusion) {
  const std::string keys = make_keys();
  {
    Process keys_tool(
        {HQ_KEYS_EXE, "identity", keys, "--role", "station", "--id", "3", "--vehicles", "1"},
        (dir_ / "keys3.out").string());
    ASSERT_EQ(keys_tool.wait_exit(30.0), 0) << out("keys3.out");
  }
  {
    std::vector<std::string> args = secured(ground_args(), keys);
    args.insert(args.end(), {"--identity", "station_3", "--station-id", "1"});
    Process impostor(args, (dir_ / "impostor.out").string());
    EXPECT_EQ(impostor.wait_exit(30.0), 2) << out("impostor.out");
    EXPECT_NE(out("impostor.out").find("is station_id 1 this certificate's station"),
              std::string::npos)
        << out("impostor.out");
  }
  std::vector<std::string> vehicle = secured(onboard_args(16.0), keys);
  vehicle.insert(vehicle.end(), {"--stations", "1,3"});
  Process onboard(vehicle, (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  std::vector<std::string> station = secured(ground_args(13.0), keys);
  station.insert(station.end(), {"--state-json", (dir_ / "ground.json").string()});
  Process ground(station, (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  ASSERT_TRUE(wait_airborne()) << out("onboard.out") << out("ground.out");
  std::vector<std::string> fuzz =
      secured(fuzz_args("commands,requests,heartbeats", 3, 200, 5.0), keys);
  fuzz.insert(fuzz.end(), {"--identity", "station_3", "--claim-station", "1"});
  Process impostor(fuzz, (dir_ / "fuzz.out").string());
  EXPECT_EQ(impostor.wait_exit(30.0), 0) << out("fuzz.out");
  EXPECT_EQ(onboard.wait_exit(30.0), 0) << out("onboard.out");
  EXPECT_EQ(ground.wait_exit(30.0), 0) << out("ground.out");

  const std::vector<Row> rows = read_log(log_path());
  ASSERT_FALSE(rows.empty());
  int landed_after_airborne = 0;
  bool airborne = false;
  for (const Row& r : rows) {
    airborne = airborne || r.airborne;
    // Up to the station's own scripted landing at the end of its 13 s.
    if (airborne && r.mode == "land" && r.t_s < 12.0) ++landed_after_airborne;
  }
  EXPECT_EQ(landed_after_airborne, 0) << "a forged land request was obeyed";
  const std::string report = out("fuzz.out");
  EXPECT_NE(report.find("the vehicle reported"), std::string::npos) << report;
  EXPECT_EQ(report.find("reported 0 intrusion events"), std::string::npos) << report;
  const std::string ground_said = out("ground.out");
  EXPECT_NE(ground_said.find("INTRUSION"), std::string::npos) << ground_said;
  EXPECT_NE(ground_said.find("written by station_3's certificate"), std::string::npos)
      << ground_said;
  EXPECT_NE(ground_said.find("held (commander: station 1, this station 1, 0 losses)"),
            std::string::npos)
      << ground_said;
  EXPECT_NE(out("onboard.out").find("written by station 3's certificate"), std::string::npos)
      << out("onboard.out");
  const std::string json = out("ground.json");
  EXPECT_NE(json.find("\"control_lost\": false"), std::string::npos) << json;
  EXPECT_EQ(json.find("\"intrusion_reports\": 0"), std::string::npos) << json;
  fmt::print("[ figures  ] station_3 speaking for station 1:\n{}", report);
}

// GIVEN a vehicle with keys of one CA and a station with a complete keyset of another (each
// passes `hq-keys check` alone), WHEN they run, THEN the handshake fails, the vehicle never
// hears a command and the station exits 3 naming both identities and the check to run, instead
// of waiting the whole run and exiting 0.
TEST_F(LinkProcesses, SecuredStationWithAnotherCasKeysExitsNamingBothEnds) {
  const auto keys_tool = [&](std::vector<std::string> args) {
    args.insert(args.begin(), HQ_KEYS_EXE);
    Process p(args, (dir_ / "keys.out").string());
    return p.wait_exit(30.0);
  };
  const std::string vehicle_keys = (dir_ / "vehicle_keys").string();
  const std::string station_keys = (dir_ / "station_keys").string();
  for (const std::string& keys : {vehicle_keys, station_keys}) {
    ASSERT_EQ(keys_tool({"init", keys}), 0) << slurp((dir_ / "keys.out").string());
  }
  ASSERT_EQ(keys_tool({"identity", vehicle_keys, "--role", "vehicle", "--id", "1"}), 0);
  ASSERT_EQ(
      keys_tool({"identity", station_keys, "--role", "station", "--id", "1", "--vehicles", "1"}),
      0);
  Process onboard(secured(onboard_args(8.0), vehicle_keys), (dir_ / "onboard.out").string());
  ASSERT_TRUE(onboard.started());
  Process ground(secured(ground_args(4.0), station_keys), (dir_ / "ground.out").string());
  ASSERT_TRUE(ground.started());
  EXPECT_EQ(ground.wait_exit(30.0), 3) << out("ground.out");
  const std::string said = out("ground.out");
  EXPECT_NE(said.find("station station_1 (certificate " + station_keys +
                      "/station_1/cert.pem) never reached vehicle 1 (vehicle_1)"),
            std::string::npos)
      << said;
  EXPECT_NE(said.find("hq-keys check " + station_keys + " --identity station_1 --peer"),
            std::string::npos)
      << said;
  onboard.wait_exit(30.0);
  for (const Row& r : read_log(log_path())) EXPECT_FALSE(r.airborne) << r.t_s;
}

}  // namespace
