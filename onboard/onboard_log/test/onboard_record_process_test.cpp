// hq-onboard --record as a process: a simulated sequence replayed with --link to a ground
// station (hq-ground --device sim), as in tests/integration's ReplayWithLinkReachesTheGround.
// The onboard.mcap is read back with hq::mcap::McapReader (every channel present, counts as the
// exit summary reports them, stamps monotonic per channel) and by the npm readers; an
// unwritable folder stops the start naming it; a write failure mid-flight (a file-size limit
// standing in for a full disk) is an event to the ground and the flight goes on.
#include "hq/mcap/mcap.hpp"
#include "hq/testing/loopback_dds.hpp"
#include "hq/testing/process.hpp"
#include "hq/testing/vehicle_processes.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace {

using hq::testing::number_after;
using hq::testing::Process;
using hq::testing::slurp;
namespace fs = std::filesystem;

/// "  record /topic   N messages" lines of hq-onboard's exit summary.
std::map<std::string, std::uint64_t> reported_counts(const std::string& text) {
  std::map<std::string, std::uint64_t> counts;
  const std::regex re(R"(\n  record (\S+) +([0-9]+) messages)");
  for (auto it = std::sregex_iterator(text.begin(), text.end(), re); it != std::sregex_iterator();
       ++it) {
    counts[(*it)[1].str()] = std::stoull((*it)[2].str());
  }
  return counts;
}

class OnboardRecordProcess : public ::testing::Test {
 protected:
  void SetUp() override {
    hq::testing::use_loopback_dds();
    const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    domain_ = std::to_string(hq::testing::private_domain_id(101, test, 89));
    dir_ =
        fs::temp_directory_path() / ("hq_onboard_record_" + std::to_string(getpid()) + "_" + test);
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  fs::path file(const char* name) const { return dir_ / name; }

  /// A 3 s simulated sequence (with its IMU), replayed at its own pace with --link while a
  /// ground station flies; `prefix` wraps hq-onboard (e.g. a shell setting a file-size limit).
  /// Returns hq-onboard's exit code.
  int fly(const std::vector<std::string>& prefix, const std::string& record_dir,
          const std::string& ground_record_dir = "") {
    const fs::path sequence = file("sequence");
    Process record({HQ_SIM_EXE, "--world", "onboard/sim/worlds/room.yaml", "--duration-s", "3",
                    "--record", sequence.string(), "--script", "circle"},
                   file("sim.out"));
    EXPECT_EQ(record.wait_exit(60.0), 0) << slurp(file("sim.out"));
    std::vector<std::string> ground_args =
        hq::testing::scripted_ground_args(HQ_GROUND_EXE, domain_, 7.0);
    if (!ground_record_dir.empty()) {
      ground_args.push_back("--record");
      ground_args.push_back(ground_record_dir);
    }
    Process ground(ground_args, file("ground.out"));
    std::this_thread::sleep_for(std::chrono::seconds(1));
    std::vector<std::string> args = prefix;
    for (const std::string& a :
         {std::string(HQ_ONBOARD_EXE), std::string("--source"), std::string("replay"),
          sequence.string(), std::string("--camera"), (sequence / "camera.yaml").string(),
          std::string("--link"), std::string("--domain-id"), domain_, std::string("--insecure"),
          std::string("--record"), record_dir}) {
      args.push_back(a);
    }
    Process onboard(args, file("onboard.out"));
    const int code = onboard.wait_exit(40.0);
    EXPECT_EQ(ground.wait_exit(20.0), 0) << slurp(file("ground.out"));
    return code;
  }

  std::string domain_;
  fs::path dir_;
};

// GIVEN a replayed flight with a ground station WHEN hq-onboard records it THEN every channel
// is in onboard.mcap with the counts the exit summary reports, stamps monotonic per channel,
// the vehicle's own channels as many as the chain's frames and steps, the files attached.
TEST_F(OnboardRecordProcess, RecordedFlightReadsBackAsTheExitSummaryReports) {
  const fs::path record = file("record");
  ASSERT_EQ(fly({}, record.string()), 0) << slurp(file("onboard.out"));
  const std::string out = slurp(file("onboard.out"));
  const double frames = number_after(out, R"(hq-onboard: ([0-9]+) frames from)").value_or(0);
  const double ticks = number_after(out, R"(, ([0-9]+) camera-timeout steps)").value_or(-1);
  EXPECT_GE(frames, 60) << out;
  EXPECT_EQ(number_after(out, R"(on-board record samples +([0-9]+) dropped)"), 0.0) << out;
  const std::map<std::string, std::uint64_t> reported = reported_counts(out);

  const hq::mcap::McapReader r((record / "onboard.mcap").string());
  EXPECT_TRUE(r.report().has_summary);
  std::map<std::string, std::vector<const hq::mcap::Message*>> by_topic;
  for (const hq::mcap::Channel& c : r.channels()) by_topic[c.topic];
  for (const hq::mcap::Message& m : r.messages()) {
    by_topic[r.channel(m.channel_id)->topic].push_back(&m);
  }
  EXPECT_EQ(by_topic.size(), reported.size()) << out;
  for (const char* topic :
       {"/hq/vehicle_state", "/hq/camera_frame", "/hq/event", "/hq/heartbeat",
        "/hq/velocity_command", "/hq/mode_request", "/camera/image/compressed",
        "/camera/depth_preview/compressed", "/obstacles", "/onboard/imu", "/onboard/odometry",
        "/onboard/estimator", "/onboard/control", "/onboard/timing"}) {
    ASSERT_TRUE(by_topic.count(topic)) << topic;
    ASSERT_TRUE(reported.count(topic)) << topic << "\n" << out;
    EXPECT_EQ(by_topic[topic].size(), reported.at(topic)) << topic;
  }
  for (const auto& [topic, messages] : by_topic) {
    for (std::size_t i = 1; i < messages.size(); ++i) {
      ASSERT_LE(messages[i - 1]->log_time_ns, messages[i]->log_time_ns) << topic << " at " << i;
      if (topic.rfind("/onboard/", 0) == 0) {
        ASSERT_LT(messages[i - 1]->log_time_ns, messages[i]->log_time_ns) << topic << " at " << i;
      }
    }
  }
  // What the vehicle published and received went through the log's own reader.
  EXPECT_GT(by_topic["/hq/vehicle_state"].size(), 20u);
  EXPECT_GT(by_topic["/hq/velocity_command"].size(), 20u);
  EXPECT_GT(by_topic["/hq/heartbeat"].size(), 2u);
  // The chain's steps, one message each; the IMU at its recorded rate.
  EXPECT_EQ(by_topic["/onboard/timing"].size(), static_cast<std::size_t>(frames));
  EXPECT_EQ(by_topic["/onboard/odometry"].size(), static_cast<std::size_t>(frames));
  EXPECT_EQ(by_topic["/onboard/estimator"].size(), static_cast<std::size_t>(frames + ticks));
  EXPECT_GT(by_topic["/onboard/imu"].size(), 2 * static_cast<std::size_t>(frames));

  EXPECT_EQ(r.attachments().size(), 3u);  // on-board config, vehicle file, camera file
  bool summary_found = false;
  for (const hq::mcap::Metadata& m : r.metadata()) {
    if (m.name != "flight_summary") continue;
    summary_found = true;
    EXPECT_EQ(std::stod(m.values.at("frames")), frames);
    EXPECT_EQ(m.values.at("session_id").size(), 16u);
    EXPECT_GT(std::stod(m.values.at("duration_s")), 1.0);
  }
  EXPECT_TRUE(summary_found);
}

// GIVEN npm's MCAP and OMG IDL readers WHEN they read a recorded flight THEN every message
// decodes (cdr with the IDL in the file, json parsed) and the counts match the exit summary.
TEST_F(OnboardRecordProcess, RecordedFlightReadsBackWithNpmReaders) {
  const std::string script = std::string(HQ_ONBOARD_LOG_TEST_DIR) + "/onboard_mcap.sh";
  // Installing first, so a machine without npm skips before flying.
  const std::string probe = "bash " + script + " " + HQ_NPM_CHECKERS_DIR + " --probe x > " +
                            file("npm.out").string() + " 2>&1";
  const int probe_code = WEXITSTATUS(std::system(probe.c_str()));
  if (probe_code == 77) GTEST_SKIP() << slurp(file("npm.out"));
  ASSERT_EQ(probe_code, 0) << slurp(file("npm.out"));
  const fs::path record = file("record");
  ASSERT_EQ(fly({}, record.string()), 0) << slurp(file("onboard.out"));
  const std::string check =
      "bash " + script + " " + HQ_NPM_CHECKERS_DIR + " " + (record / "onboard.mcap").string() +
      " " + file("onboard.out").string() + " > " + file("npm.out").string() + " 2>&1";
  EXPECT_EQ(WEXITSTATUS(std::system(check.c_str())), 0) << slurp(file("npm.out"));
}

// GIVEN --record into a folder that cannot be made WHEN hq-onboard starts THEN it stops at
// once with exit code 2 and a message naming the folder.
TEST_F(OnboardRecordProcess, UnwritableFolderStopsTheStartNamingIt) {
  std::ofstream(file("a_file")) << "not a folder";
  const std::string dir = (file("a_file") / "flight").string();
  Process onboard({HQ_SIM_FLIGHT_EXE, "--world", "onboard/sim/worlds/arena.yaml", "--link",
                   "--duration-s", "5", "--domain-id", domain_, "--insecure", "--record", dir},
                  file("onboard.out"));
  EXPECT_EQ(onboard.wait_exit(20.0), 2) << slurp(file("onboard.out"));
  EXPECT_NE(slurp(file("onboard.out")).find(dir), std::string::npos) << slurp(file("onboard.out"));
}

// GIVEN a short simulated flight over the link whose record hits a file-size limit (a full
// disk) WHEN it ends THEN the flight ran its full length, and the exit status (5) and stderr
// say the record is incomplete. (96 KiB: past the record's opening, its attachments and
// schemas, which alone passed 64 KiB once the state grew.)
TEST_F(OnboardRecordProcess, SimRunWhoseRecordFailsExitsNonZeroAndSaysWhy) {
  Process onboard({"/bin/bash", "-c", "ulimit -f 96 && exec \"$0\" \"$@\"", HQ_SIM_FLIGHT_EXE,
                   "--world", "onboard/sim/worlds/arena.yaml", "--link", "--duration-s", "3",
                   "--domain-id", domain_, "--insecure", "--record", file("record").string()},
                  file("onboard.out"));
  const std::string out = [&] {
    EXPECT_EQ(onboard.wait_exit(30.0), 5) << slurp(file("onboard.out"));
    return slurp(file("onboard.out"));
  }();
  EXPECT_NE(out.find("on-board record FAILED"), std::string::npos) << out;
  EXPECT_NE(out.find("hq-sim-flight: the flight record is incomplete ("), std::string::npos) << out;
  EXPECT_NE(out.find("File too large"), std::string::npos) << out;
  EXPECT_NE(out.find("flight summary over the link"), std::string::npos) << out;
}

// GIVEN a replay without --link (and without keys) WHEN it is recorded THEN the vehicle's own
// channels are filled, the link channels are there and empty (nobody else's traffic is taken).
TEST_F(OnboardRecordProcess, WithoutTheLinkOnlyTheVehiclesOwnChannelsAreFilled) {
  const fs::path sequence = file("sequence");
  Process record({HQ_SIM_EXE, "--world", "onboard/sim/worlds/room.yaml", "--duration-s", "2",
                  "--record", sequence.string(), "--script", "circle"},
                 file("sim.out"));
  ASSERT_EQ(record.wait_exit(60.0), 0) << slurp(file("sim.out"));
  Process onboard({HQ_ONBOARD_EXE, "--source", "replay", sequence.string(), "--camera",
                   (sequence / "camera.yaml").string(), "--record", file("record").string()},
                  file("onboard.out"));
  ASSERT_EQ(onboard.wait_exit(40.0), 0) << slurp(file("onboard.out"));
  const std::string out = slurp(file("onboard.out"));
  const double frames = number_after(out, R"(hq-onboard: ([0-9]+) frames from)").value_or(0);
  EXPECT_GE(frames, 40) << out;
  const std::map<std::string, std::uint64_t> reported = reported_counts(out);
  ASSERT_TRUE(reported.count("/hq/vehicle_state")) << out;
  EXPECT_EQ(reported.at("/hq/vehicle_state"), 0u);
  EXPECT_EQ(reported.at("/hq/velocity_command"), 0u);
  EXPECT_EQ(reported.at("/onboard/timing"), static_cast<std::uint64_t>(frames));
  EXPECT_GT(reported.at("/onboard/imu"), static_cast<std::uint64_t>(frames));
  const hq::mcap::McapReader r((file("record") / "onboard.mcap").string());
  std::uint64_t onboard_messages = 0;
  for (const hq::mcap::Message& m : r.messages()) {
    const std::string& topic = r.channel(m.channel_id)->topic;
    // The camera mount's transforms and calibration are the vehicle's own too (Foxglove's
    // frames); everything else from the link would be somebody's traffic.
    if (topic == "/tf_static" || topic == "/camera/calibration") continue;
    ASSERT_EQ(topic.rfind("/onboard/", 0), 0u) << topic;
    ++onboard_messages;
  }
  EXPECT_GT(onboard_messages, 3 * static_cast<std::uint64_t>(frames));
}

// GIVEN a file-size limit far below the flight's log (a full disk's EFBIG) WHEN the write
// fails mid-flight THEN the vehicle tells the ground in an event, flies the replay to its end,
// and exits with status 5 saying on stderr that the record is incomplete.
TEST_F(OnboardRecordProcess, DiskFullMidFlightIsAnEventAndTheFlightGoesOn) {
  const fs::path record = file("record");
  // 96 KB: the header (IDL schemas, attachments) is about 52 KB, so the first or second chunk
  // (one a second) fails, well before the 3 s replay ends even when the log's niced thread
  // lags on a loaded machine (a failure found only at close is not told in flight).
  ASSERT_EQ(fly({"/bin/bash", "-c", "ulimit -f 96 && exec \"$0\" \"$@\""}, record.string(),
                file("ground_record").string()),
            5)
      << slurp(file("onboard.out"));
  const std::string out = slurp(file("onboard.out"));
  EXPECT_NE(out.find("hq-onboard: the flight record is incomplete ("), std::string::npos) << out;
  const std::string ground = slurp(file("ground.out"));
  // Sent through the link port (which prints what it publishes) to the ground.
  EXPECT_NE(out.find("s: on-board record stopped (flying on)"), std::string::npos) << out;
  EXPECT_NE(out.find("on-board record FAILED"), std::string::npos) << out;
  EXPECT_NE(out.find("File too large"), std::string::npos) << out;
  EXPECT_GE(number_after(out, R"(hq-onboard: ([0-9]+) frames from)").value_or(0), 60) << out;
  // The ground received it: its own flight record holds the event (its CDR carries the text).
  const hq::mcap::McapReader g((file("ground_record") / "flight.mcap").string());
  int told = 0;
  for (const hq::mcap::Message& m : g.messages()) {
    if (g.channel(m.channel_id)->topic != "/hq/event") continue;
    const std::string data(m.data.begin(), m.data.end());
    told += data.find("on-board record stopped (flying on)") != std::string::npos ? 1 : 0;
  }
  EXPECT_EQ(told, 1) << ground;
  // What reached the disk before the failure still opens (no summary: recovered, the cut
  // chunk dropped cleanly), with every channel the header declared.
  const hq::mcap::McapReader r((record / "onboard.mcap").string());
  EXPECT_FALSE(r.report().has_summary);
  // Six link topics, three Foxglove views, /tf, /tf_static, /camera/calibration, five on-board.
  EXPECT_EQ(r.channels().size(), 17u);
}

}  // namespace
