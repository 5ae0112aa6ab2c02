// A Recording from a flight record (flight.mcap): link samples encoded here by hand as CDR
// (independently of Cyclone, field by field from the IDL) in the recorder's channels, read back
// through load_recording: every field, the vehicle chosen, commands from /ground/haptics,
// camera frames from memory in the replay, damaged messages named, a folder's MCAP preferred
// over its CSV files and the CSV files read when the MCAP is unreadable.
#include "hq/console/flight_mcap.hpp"

#include "hq/base/format_into.hpp"
#include "hq/console/recording.hpp"
#include "hq/console/replay_player.hpp"
#include "hq/ground/ground_station.hpp"
#include "hq/mcap/mcap.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace hq::console {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("hq_flight_mcap_" + std::to_string(getpid()) + "_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// CDR as the OMG spec lays it out: little endian, each primitive aligned to its size (capped
// at 8 in XCDR1, 4 in XCDR2) from the end of the 4-byte encapsulation header.
class CdrOut {
 public:
  explicit CdrOut(bool xcdr2) : max_align_(xcdr2 ? 4 : 8) {
    bytes_ = {0x00, static_cast<std::uint8_t>(xcdr2 ? 0x07 : 0x01), 0x00, 0x00};
  }
  template <typename T>
  CdrOut& put(T v) {
    const std::size_t align = std::min(sizeof(T), max_align_);
    while ((bytes_.size() - 4) % align != 0) bytes_.push_back(0);
    const auto* p = reinterpret_cast<const std::uint8_t*>(&v);
    bytes_.insert(bytes_.end(), p, p + sizeof(T));
    return *this;
  }
  CdrOut& vec3(float x, float y, float z) { return put(x).put(y).put(z); }
  CdrOut& octets(const std::vector<std::uint8_t>& data) {
    put(static_cast<std::uint32_t>(data.size()));
    bytes_.insert(bytes_.end(), data.begin(), data.end());
    return *this;
  }
  CdrOut& text(const std::string& s) {  // length with the NUL, then the characters and NUL
    put(static_cast<std::uint32_t>(s.size() + 1));
    bytes_.insert(bytes_.end(), s.begin(), s.end());
    bytes_.push_back(0);
    return *this;
  }
  [[nodiscard]] const std::vector<std::uint8_t>& bytes() const { return bytes_; }

 private:
  std::size_t max_align_;
  std::vector<std::uint8_t> bytes_;
};

// hq_msgs::VehicleState in IDL order; i makes every value distinct.
std::vector<std::uint8_t> vehicle_state(std::uint32_t vehicle, int i, bool xcdr2 = false) {
  const auto f = static_cast<float>(i);
  CdrOut c(xcdr2);
  c.put<std::uint32_t>(vehicle)
      .put<std::uint64_t>(static_cast<std::uint64_t>(100 + i))
      .put<std::int64_t>(5'000'000LL * i);
  c.vec3(0.1F * f, -0.2F, 0.3F).vec3(0.01F, 0.02F, 0.03F * f).put(0.05F).put(-0.06F);
  c.vec3(0.4F, 0.0F, -0.1F);
  c.put<std::uint32_t>(i < 5 ? 1 : 0).put<std::uint32_t>(0).put<std::uint32_t>(1);  // hover|teleop
  // XCDR2 puts a DHEADER (the byte size) before a sequence of structs.
  if (xcdr2) c.put<std::uint32_t>(4 + 2 * 12);
  c.put<std::uint32_t>(2).vec3(3.0F, 4.0F, 0.0F).vec3(1.0F, 0.0F, 0.0F);  // cloud: nearest 1 m
  c.put<std::uint8_t>(1).vec3(1.5F, -2.5F, -1.0F).put(0.7F);              // position
  if (xcdr2) c.put<std::uint32_t>(4 + 32);
  c.put<std::uint32_t>(1).put<std::int32_t>(9).vec3(0, 0, 1).put(1.0F).vec3(0, 0, 0);  // 1 marker
  c.put<std::uint8_t>(1).vec3(0.11F * f, -0.19F, 0.29F);                               // truth
  c.put<std::uint64_t>(0xABCDEF).put<std::uint32_t>(7).put<std::uint32_t>(2);          // airborne
  c.put<std::uint8_t>(1).put<std::uint32_t>(1).put(1.25F).put<std::uint32_t>(6);  // depth, limited
  c.vec3(0.2F, 0.0F, 0.0F).put(0.85F);
  c.put(1.2F).put<std::uint8_t>(1);             // hover thrust: the rotors give 120 %, learnt
  c.put<std::uint8_t>(0).put(0.2F).put(0.05F);  // position valid, marker 0.2 s old, sigma 5 cm
  c.put<std::uint8_t>(1).put<std::int32_t>(12).put<std::uint8_t>(3);    // to marker 12, exploring
  c.put<std::uint8_t>(0x1F).put<std::uint8_t>(0).put<std::uint8_t>(0);  // every mode offered
  // The odom pose (valid, p, yaw, sigmas, yaw relative to the start) and the velocity's sigma.
  c.put<std::uint8_t>(1).vec3(0.5F * f, -1.5F, -1.0F).put(0.3F).put(0.25F).put(0.02F);
  c.put<std::uint8_t>(1).vec3(0.03F, 0.04F, 0.05F);
  return c.bytes();
}

std::vector<std::uint8_t> camera_frame(std::uint32_t vehicle, int i,
                                       const std::vector<std::uint8_t>& jpeg,
                                       const std::vector<std::uint8_t>& depth) {
  CdrOut c(false);
  c.put<std::uint32_t>(vehicle)
      .put<std::uint64_t>(static_cast<std::uint64_t>(i))
      .put<std::int64_t>(i);
  c.put<std::uint16_t>(640).put<std::uint16_t>(480).octets(jpeg).octets(depth);
  return c.bytes();
}

std::vector<std::uint8_t> event(std::uint32_t vehicle, const std::string& text) {
  CdrOut c(false);
  c.put<std::uint32_t>(vehicle).put<std::uint64_t>(1).put<std::int64_t>(2);
  c.put<std::uint32_t>(1).put<std::uint32_t>(7).text(text).put<std::uint64_t>(0xABCDEF);
  return c.bytes();
}

std::vector<std::uint8_t> mode_request(std::uint32_t mode) {
  CdrOut c(false);
  c.put<std::uint32_t>(1).put<std::uint32_t>(7).put<std::uint64_t>(3).put<std::int64_t>(4);
  c.put<std::uint32_t>(mode).put<std::uint32_t>(0).put<std::int32_t>(-1);
  c.put<std::uint64_t>(0xABCDEF).put<std::uint8_t>(0);
  return c.bytes();
}

mcap::Bytes as_bytes(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

constexpr std::int64_t kT0_ns = 1'700'000'000'000'000'000LL;

// The recorder's channels (ground/mcap_recorder): link topics as cdr with the IDL type names,
// the ground's commands as JSON.
struct FlightFile {
  explicit FlightFile(const std::string& path) {
    writer.open(path);
    const std::string idl = "module hq_msgs { };";  // the schema's text is not read back
    for (const char* type : {"VehicleState", "CameraFrame", "Event", "ModeRequest"}) {
      const std::uint16_t schema =
          writer.add_schema(std::string("hq_msgs::") + type, "omgidl", as_bytes(idl));
      channels.push_back(schema);
    }
    state = writer.add_channel(channels[0], "/hq/vehicle_state", "cdr");
    camera = writer.add_channel(channels[1], "/hq/camera_frame", "cdr");
    events = writer.add_channel(channels[2], "/hq/event", "cdr");
    modes = writer.add_channel(channels[3], "/hq/mode_request", "cdr");
    haptics = writer.add_channel(0, "/ground/haptics", "json");
  }
  void add(std::uint16_t channel, std::int64_t log_ns, std::int64_t publish_ns,
           const std::vector<std::uint8_t>& data) {
    writer.write(channel, sequence++, log_ns, publish_ns, data);
  }
  void command(std::int64_t t_ns, bool valid, float vx) {
    char json[256];
    hq::format_into(json,
                    "{{\"timestamp\":{{\"sec\":1,\"nsec\":2}},\"command_valid\":{},\"v_cmd_H_mps\":"
                    "{{\"x\":{:.3f},\"y\":0,\"z\":-0.25}},\"yaw_rate_cmd_radps\":0.125,\"p_D_m\":{{"
                    "\"x\":0,\"y\":0,\"z\":0}},\"F_D_n\":{{\"x\":0,\"y\":0,\"z\":1.5}}}}",
                    valid ? "true" : "false", static_cast<double>(vx));
    command_text(t_ns, json);
  }
  void command_text(std::int64_t t_ns, const std::string& text) {
    writer.write(haptics, sequence++, t_ns, t_ns, as_bytes(text));
  }
  mcap::McapWriter writer;
  std::vector<std::uint16_t> channels;
  std::uint16_t state = 0, camera = 0, events = 0, modes = 0, haptics = 0;
  std::uint32_t sequence = 0;
};

const std::vector<std::uint8_t> kJpeg = {0xFF, 0xD8, 0xFF, 0xE0, 0x42, 0xFF, 0xD9};
const std::vector<std::uint8_t> kPng = {0x89, 'P', 'N', 'G', 0x0D};

// 20 states of vehicle 1 at 30 ms (2 ms latency), 3 of vehicle 2, 4 frames, 2 events,
// a mode request, 10 commands.
void write_flight(const std::string& path) {
  FlightFile f(path);
  for (int i = 0; i < 20; ++i) {
    const std::int64_t t = kT0_ns + i * 30'000'000LL;
    f.add(f.state, t, t - 2'000'000, vehicle_state(1, i));
    if (i % 5 == 0) f.add(f.camera, t + 1, t, camera_frame(1, i, kJpeg, i == 5 ? kPng : kJpeg));
    if (i % 2 == 0) f.command(t + 2, i != 4, 0.1F * static_cast<float>(i));
    if (i < 3) f.add(f.state, t + 3, t, vehicle_state(2, i));
  }
  f.add(f.events, kT0_ns + 100'000'000, kT0_ns, event(1, "obstacle ahead"));
  f.add(f.events, kT0_ns + 110'000'000, kT0_ns, event(2, "another vehicle's"));
  f.add(f.modes, kT0_ns + 120'000'000, kT0_ns, mode_request(2));
  f.writer.close();
}

TEST(FlightMcap, EveryFieldOfTheRecordedStatesReturns) {
  const fs::path dir = fresh_dir("fields");
  write_flight((dir / "flight.mcap").string());
  const Recording r = load_recording((dir / "flight.mcap").string());
  EXPECT_TRUE(r.from_mcap);
  ASSERT_EQ(r.states.size(), 20U);  // vehicle 1 only: vehicle 2 named in problems
  ASSERT_EQ(r.problems.size(), 1U);
  EXPECT_THAT(r.problems[0], HasSubstr("vehicle 1 shown (most states); not shown: vehicle 2 (3"));
  const RecordedState& s = r.states[7];
  EXPECT_EQ(s.receipt_ns, kT0_ns + 7 * 30'000'000LL);
  EXPECT_DOUBLE_EQ(s.latency_ms, 2.0);
  EXPECT_EQ(s.sequence, 107U);
  EXPECT_EQ(s.vehicle_t_ns, 35'000'000LL);
  EXPECT_FLOAT_EQ(s.v_H_mps[0], 0.7F);
  EXPECT_FLOAT_EQ(s.v_H_mps[1], -0.2F);
  EXPECT_FLOAT_EQ(s.omega_B_radps[2], 0.21F);
  EXPECT_FLOAT_EQ(s.pitch_rad, -0.06F);
  EXPECT_FLOAT_EQ(s.v_obs_H_mps[2], -0.1F);
  EXPECT_STREQ(s.mode, "teleop");
  EXPECT_STREQ(r.states[2].mode, "hover");
  EXPECT_STREQ(s.estimator_health, "ok");
  EXPECT_STREQ(s.link_health, "degraded");
  EXPECT_DOUBLE_EQ(s.closest_obstacle_m, 1.0);
  EXPECT_TRUE(s.position_valid);
  EXPECT_FLOAT_EQ(s.p_W_m[1], -2.5F);
  EXPECT_FLOAT_EQ(s.yaw_W_rad, 0.7F);
  EXPECT_EQ(s.position_invalid_reason, 0);
  EXPECT_FLOAT_EQ(s.position_age_s, 0.2F);
  EXPECT_FLOAT_EQ(s.position_sigma_m, 0.05F);
  EXPECT_EQ(s.marker_target_id, 12);
  EXPECT_EQ(s.explore_phase, 3);
  EXPECT_EQ(s.modes_offered, 0x1F);
  EXPECT_EQ(s.marker_mode_off_reason, 0);
  EXPECT_EQ(s.markers_n, 1);
  EXPECT_TRUE(s.truth_valid);
  EXPECT_FLOAT_EQ(s.v_truth_H_mps[0], 0.77F);
  EXPECT_TRUE(s.flight_fields);
  EXPECT_EQ(s.session_id, 0xABCDEFU);
  EXPECT_EQ(s.commanding_station_id, 7U);
  EXPECT_STREQ(s.flight_state, "airborne");
  EXPECT_EQ(s.motors_armed, 1);
  EXPECT_STREQ(s.height_source, "depth");
  EXPECT_DOUBLE_EQ(s.height_m, 1.25);
  EXPECT_STREQ(s.operator_input, "limited_unseen");
  EXPECT_FLOAT_EQ(s.v_cmd_flown_H_mps[0], 0.2F);
  EXPECT_NEAR(s.clearance_m, 0.85, 1e-6);
  EXPECT_TRUE(s.odom_valid);
  EXPECT_FLOAT_EQ(s.p_odom_m[0], 3.5F);
  EXPECT_FLOAT_EQ(s.p_odom_m[1], -1.5F);
  EXPECT_FLOAT_EQ(s.yaw_odom_rad, 0.3F);
  EXPECT_FLOAT_EQ(s.odom_position_sigma_m, 0.25F);
  EXPECT_FLOAT_EQ(s.odom_yaw_sigma_rad, 0.02F);
  EXPECT_TRUE(s.odom_yaw_relative_to_start);
  EXPECT_FLOAT_EQ(s.v_H_sigma_mps[2], 0.05F);
  fs::remove_all(dir);
}

TEST(FlightMcap, CommandsEventsModeRequestsAndFramesReturn) {
  const fs::path dir = fresh_dir("streams");
  write_flight((dir / "flight.mcap").string());
  const Recording r = load_recording(dir.string());  // the folder: its flight.mcap
  EXPECT_TRUE(r.from_mcap);
  ASSERT_EQ(r.commands.size(), 10U);
  EXPECT_EQ(r.commands[3].t_ns, kT0_ns + 6 * 30'000'000LL + 2);
  EXPECT_TRUE(r.commands[3].valid);
  EXPECT_FALSE(r.commands[2].valid);
  EXPECT_FLOAT_EQ(r.commands[3].v_H_mps[0], 0.6F);
  EXPECT_FLOAT_EQ(r.commands[3].v_H_mps[2], -0.25F);
  EXPECT_FLOAT_EQ(r.commands[3].yaw_rate_radps, 0.125F);
  ASSERT_EQ(r.events.size(), 1U);  // vehicle 2's is not shown
  EXPECT_EQ(r.events[0].text, "obstacle ahead");
  EXPECT_EQ(r.events[0].severity, 1);
  EXPECT_EQ(r.events[0].code, 7);
  ASSERT_EQ(r.mode_requests.size(), 1U);
  EXPECT_STREQ(r.mode_requests[0].mode, "land");
  ASSERT_EQ(r.rgb.size(), 4U);
  EXPECT_EQ(r.rgb[1].data, kJpeg);
  EXPECT_TRUE(r.rgb[1].path.empty());
  ASSERT_EQ(r.depth_preview.size(), 4U);
  EXPECT_EQ(r.depth_preview[1].data, kPng);

  // The replay shows the frames from memory: none missing, the newest one on show.
  ReplayPlayer player(r);
  ConsoleModel model;
  std::uint64_t missing = 0;
  player.seek(player.duration_s());
  player.feed(model, missing);
  EXPECT_EQ(missing, 0U);
  EXPECT_EQ(player.counts().frames, 4U);
  Snapshot snap = model.make_snapshot();
  model.snapshot(snap);
  ASSERT_EQ(snap.jpeg_size, kJpeg.size());
  EXPECT_TRUE(std::equal(kJpeg.begin(), kJpeg.end(), snap.jpeg.begin()));
  fs::remove_all(dir);
}

TEST(FlightMcap, Xcdr1AndXcdr2DecodeToTheSameState) {
  link::Sample<link::VehicleState> one;
  link::Sample<link::VehicleState> two;
  std::vector<std::uint8_t> scratch;
  std::string error;
  ASSERT_TRUE(decode_cdr(vehicle_state(3, 11, false), one, scratch, error)) << error;
  ASSERT_TRUE(decode_cdr(vehicle_state(3, 11, true), two, scratch, error)) << error;
  EXPECT_EQ(one->vehicle_id, 3U);
  EXPECT_EQ(two->session_id, 0xABCDEFU);
  EXPECT_EQ(one->obstacle_points_B_m._length, 2U);
  EXPECT_EQ(two->obstacle_points_B_m._buffer[1].x, 1.0F);
  EXPECT_EQ(two->markers._buffer[0].id, 9);
  EXPECT_EQ(one->clearance_m, two->clearance_m);
  EXPECT_EQ(two->operator_input, hq_msgs_INPUT_LIMITED_UNSEEN);
}

TEST(FlightMcap, DamagedMessagesAreNamedAndTheRestIsRead) {
  const fs::path dir = fresh_dir("damaged");
  const std::string path = (dir / "flight.mcap").string();
  {
    FlightFile f(path);
    for (int i = 0; i < 6; ++i) {
      std::vector<std::uint8_t> state = vehicle_state(1, i);
      if (i == 2) state.resize(30);  // cut inside v_H_mps
      if (i == 3) state[1] = 0x0B;   // a parameter-list encapsulation the link never sends
      if (i == 4) std::memset(state.data() + 4 + 80, 0xFF, 4);  // a cloud of 4 G points
      f.add(f.state, kT0_ns + i * 1'000'000, kT0_ns, state);
    }
    f.writer.close();
  }
  const Recording r = load_recording(path);
  EXPECT_EQ(r.states.size(), 3U);
  ASSERT_EQ(r.problems.size(), 3U);
  EXPECT_THAT(r.problems[0], HasSubstr("flight.mcap: /hq/vehicle_state message 2: CDR of 26 "
                                       "bytes does not fit the IDL type"));
  EXPECT_THAT(r.problems[1], HasSubstr("message 3: CDR encapsulation 0x000b"));
  EXPECT_THAT(r.problems[2], HasSubstr("message 4: CDR of"));
  fs::remove_all(dir);
}

// /ground/haptics is read as JSON, not searched as text: any key order and spacing, exponents;
// what is not the recorder's message (cut, a null where the recorder wrote a NaN, a key
// missing) is named and skipped.
TEST(FlightMcap, HapticsMessagesAreReadAsJson) {
  const fs::path dir = fresh_dir("haptics_json");
  const std::string path = (dir / "flight.mcap").string();
  {
    FlightFile f(path);
    f.command_text(kT0_ns, R"({ "yaw_rate_cmd_radps" : -1.25e-1, "v_cmd_H_mps" : )"
                           R"({ "z" : 2E-3, "y" : -0.5, "x" : 1.5e+0 }, "command_valid" : true })");
    f.command_text(kT0_ns + 1, R"({"command_valid":true,"v_cmd_H_mps":{"x":0.1,"y":0)");
    f.command_text(kT0_ns + 2, R"({"command_valid":true,"v_cmd_H_mps":{"x":null,"y":0,"z":0},)"
                               R"("yaw_rate_cmd_radps":0})");
    f.command_text(kT0_ns + 3, R"({"command_valid":false,"v_cmd_H_mps":{"x":0,"y":0,"z":0}})");
    f.writer.close();
  }
  const Recording r = load_recording(path);
  ASSERT_EQ(r.commands.size(), 1U);
  EXPECT_TRUE(r.commands[0].valid);
  EXPECT_FLOAT_EQ(r.commands[0].v_H_mps[0], 1.5F);
  EXPECT_FLOAT_EQ(r.commands[0].v_H_mps[1], -0.5F);
  EXPECT_FLOAT_EQ(r.commands[0].v_H_mps[2], 0.002F);
  EXPECT_FLOAT_EQ(r.commands[0].yaw_rate_radps, -0.125F);
  ASSERT_EQ(r.problems.size(), 3U);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_THAT(r.problems[i],
                HasSubstr("flight.mcap: /ground/haptics message " + std::to_string(i + 1) +
                          ": not the recorder's haptics JSON"));
  }
  fs::remove_all(dir);
}

TEST(FlightMcap, FolderWithAnUnreadableMcapReadsItsCsvFiles) {
  const fs::path dir = fresh_dir("fallback");
  {
    ground::TelemetryRecorder recorder(dir.string());
    link::VehicleState s{};
    s.sequence_number = 1;
    recorder.state(1'000'000'000LL, 1'000'000, s);
  }
  std::ofstream(dir / "flight.mcap") << "not an mcap";
  const Recording r = load_recording(dir.string());
  EXPECT_FALSE(r.from_mcap);
  EXPECT_EQ(r.states.size(), 1U);
  ASSERT_FALSE(r.problems.empty());
  EXPECT_THAT(r.problems.back(), HasSubstr("flight.mcap unreadable ("));
  EXPECT_THAT(r.problems.back(), HasSubstr("the CSV files were read instead"));
  // A file given by name must be an MCAP.
  EXPECT_THROW(load_recording((dir / "telemetry.csv").string()), InputError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace hq::console
