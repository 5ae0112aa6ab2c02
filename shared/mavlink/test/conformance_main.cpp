// hq-mavlink-conformance: one side of the conformance check against node-mavlink (conformance.sh).
//   write FRAMES JSON   encodes every message with chosen values into FRAMES and writes the values
//                       as JSON under the specification's field names, for node to decode and check
//   check FRAMES TEXT   decodes FRAMES that node-mavlink encoded and checks every field against
//                       TEXT ("message ID SYSID COMPID v1|v2|signed" then "FIELD VALUE..." lines)
//   targets JSON        writes the router's table (message_targets.hpp) for node to check each
//                       CRC_EXTRA and target offset against its own definitions
// Exit status 0 when everything matched, 1 on a mismatch, 2 on bad usage or files.

#include "hq/mavlink/codec.hpp"
#include "hq/mavlink/message_targets.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

namespace {

using namespace hq::mavlink;

// Every field under its common.xml name; arrays the XML splits (param1..7, errors_count1..4) are
// split the same way.
template <typename F>
void fields(const Heartbeat& m, F&& f) {
  f("custom_mode", m.custom_mode), f("type", m.type), f("autopilot", m.autopilot),
      f("base_mode", m.base_mode), f("system_status", m.system_status),
      f("mavlink_version", m.mavlink_version);
}
template <typename F>
void fields(const SysStatus& m, F&& f) {
  f("onboard_control_sensors_present", m.onboard_control_sensors_present);
  f("onboard_control_sensors_enabled", m.onboard_control_sensors_enabled);
  f("onboard_control_sensors_health", m.onboard_control_sensors_health);
  f("load", m.load_permille), f("voltage_battery", m.voltage_battery_mv);
  f("current_battery", m.current_battery_ca), f("battery_remaining", m.battery_remaining_pct);
  f("drop_rate_comm", m.drop_rate_comm_cpct), f("errors_comm", m.errors_comm);
  f("errors_count1", m.errors_count[0]), f("errors_count2", m.errors_count[1]);
  f("errors_count3", m.errors_count[2]), f("errors_count4", m.errors_count[3]);
  f("onboard_control_sensors_present_extended", m.onboard_control_sensors_present_extended);
  f("onboard_control_sensors_enabled_extended", m.onboard_control_sensors_enabled_extended);
  f("onboard_control_sensors_health_extended", m.onboard_control_sensors_health_extended);
}
template <typename F>
void fields(const Attitude& m, F&& f) {
  f("time_boot_ms", m.time_boot_ms), f("roll", m.roll_rad), f("pitch", m.pitch_rad),
      f("yaw", m.yaw_rad), f("rollspeed", m.rollspeed_radps), f("pitchspeed", m.pitchspeed_radps),
      f("yawspeed", m.yawspeed_radps);
}
template <typename F>
void fields(const CommandLong& m, F&& f) {
  const char* names[7] = {"param1", "param2", "param3", "param4", "param5", "param6", "param7"};
  for (std::size_t i = 0; i < 7; ++i) f(names[i], m.param[i]);
  f("command", m.command), f("target_system", m.target_system),
      f("target_component", m.target_component), f("confirmation", m.confirmation);
}
template <typename F>
void fields(const CommandAck& m, F&& f) {
  f("command", m.command), f("result", m.result), f("progress", m.progress),
      f("result_param2", m.result_param2), f("target_system", m.target_system),
      f("target_component", m.target_component);
}
template <typename F>
void fields(const SetAttitudeTarget& m, F&& f) {
  f("time_boot_ms", m.time_boot_ms), f("q", m.q), f("body_roll_rate", m.body_roll_rate_radps),
      f("body_pitch_rate", m.body_pitch_rate_radps), f("body_yaw_rate", m.body_yaw_rate_radps),
      f("thrust", m.thrust), f("target_system", m.target_system),
      f("target_component", m.target_component), f("type_mask", m.type_mask),
      f("thrust_body", m.thrust_body);
}
template <typename F>
void fields(const VisionSpeedEstimate& m, F&& f) {
  f("usec", m.usec), f("x", m.x_mps), f("y", m.y_mps), f("z", m.z_mps),
      f("covariance", m.covariance), f("reset_counter", m.reset_counter);
}
template <typename F>
void fields(const HighresImu& m, F&& f) {
  f("time_usec", m.time_usec), f("xacc", m.xacc_mps2), f("yacc", m.yacc_mps2),
      f("zacc", m.zacc_mps2), f("xgyro", m.xgyro_radps), f("ygyro", m.ygyro_radps),
      f("zgyro", m.zgyro_radps), f("xmag", m.xmag_gauss), f("ymag", m.ymag_gauss),
      f("zmag", m.zmag_gauss), f("abs_pressure", m.abs_pressure_hpa),
      f("diff_pressure", m.diff_pressure_hpa), f("pressure_alt", m.pressure_alt_m),
      f("temperature", m.temperature_degc), f("fields_updated", m.fields_updated), f("id", m.id);
}
template <typename F>
void fields(const Statustext& m, F&& f) {
  f("severity", m.severity), f("text", m.text), f("id", m.id), f("chunk_seq", m.chunk_seq);
}

template <typename F>
void fields(const Timesync& m, F&& f) {
  f("tc1", m.tc1_ns), f("ts1", m.ts1_ns), f("target_system", m.target_system),
      f("target_component", m.target_component);
}
template <typename F>
void fields(const Odometry& m, F&& f) {
  f("time_usec", m.time_usec), f("x", m.x_m), f("y", m.y_m), f("z", m.z_m), f("q", m.q);
  f("vx", m.vx_mps), f("vy", m.vy_mps), f("vz", m.vz_mps), f("rollspeed", m.rollspeed_radps);
  f("pitchspeed", m.pitchspeed_radps), f("yawspeed", m.yawspeed_radps);
  f("pose_covariance", m.pose_covariance), f("velocity_covariance", m.velocity_covariance);
  f("frame_id", m.frame_id), f("child_frame_id", m.child_frame_id);
  f("reset_counter", m.reset_counter), f("estimator_type", m.estimator_type);
  f("quality", m.quality_pct);
}

template <typename F>
void fields(const ParamRequestRead& m, F&& f) {
  f("param_index", m.param_index), f("target_system", m.target_system),
      f("target_component", m.target_component), f("param_id", m.param_id);
}
template <typename F>
void fields(const ParamRequestList& m, F&& f) {
  f("target_system", m.target_system), f("target_component", m.target_component);
}
template <typename F>
void fields(const ParamValue& m, F&& f) {
  f("param_value", m.param_value), f("param_count", m.param_count), f("param_index", m.param_index),
      f("param_id", m.param_id), f("param_type", m.param_type);
}
template <typename F>
void fields(const ParamSet& m, F&& f) {
  f("param_value", m.param_value), f("target_system", m.target_system),
      f("target_component", m.target_component), f("param_id", m.param_id),
      f("param_type", m.param_type);
}

template <std::size_t N>
std::array<char, N> text_of(const char* text) {
  std::array<char, N> out{};
  std::memcpy(out.data(), text, std::min(N, std::strlen(text)));
  return out;
}

// The values this side chooses: every field non-zero (extensions included), plus short ones that
// exercise zero-trimming and a full 50-character text.
std::vector<Message> chosen_messages() {
  std::vector<Message> out;
  out.emplace_back(Heartbeat{(6u << 16) | 3u, kMavTypeQuadrotor, kMavAutopilotPx4, 0x81 | 0x1D,
                             kMavStateActive, 3});
  out.emplace_back(Heartbeat{0, kMavTypeOnboardController, kMavAutopilotInvalid, 0, 0, 0});
  SysStatus ss;
  ss.onboard_control_sensors_present = 0x3020100F;
  ss.onboard_control_sensors_enabled = 0x1234567;
  ss.onboard_control_sensors_health = 0x0ABCDEF;
  ss.load_permille = 731;
  ss.voltage_battery_mv = 16123;
  ss.current_battery_ca = -2345;
  ss.battery_remaining_pct = -1;
  ss.drop_rate_comm_cpct = 17;
  ss.errors_comm = 18;
  ss.errors_count = {19, 20, 21, 65535};
  ss.onboard_control_sensors_present_extended = 1;
  ss.onboard_control_sensors_enabled_extended = 2;
  ss.onboard_control_sensors_health_extended = 4;
  out.emplace_back(ss);
  out.emplace_back(Attitude{4000000000u, -3.1415926f, 1.25e-7f, 2.5f, -0.001f, 100.f, -1e10f});
  CommandLong cl;
  cl.param = {1.f, 6.f, 0.f, -1.5f, 3.40282347e38f, -1.17549435e-38f, 123.456f};
  cl.command = kMavCmdDoSetMode;
  cl.target_system = 1;
  cl.target_component = 1;
  cl.confirmation = 255;
  out.emplace_back(cl);
  out.emplace_back(CommandAck{kMavCmdComponentArmDisarm, 4, 0, 0, 0, 0});
  out.emplace_back(CommandAck{511, 5, 99, -2000000000, 250, 191});
  SetAttitudeTarget sat;
  sat.time_boot_ms = 123456789;
  sat.q = {0.9238795f, 0.f, 0.3826834f, -0.01f};
  sat.body_roll_rate_radps = 0.5f;
  sat.body_pitch_rate_radps = -0.5f;
  sat.body_yaw_rate_radps = 0.25f;
  sat.thrust = 0.625f;
  sat.target_system = 1;
  sat.target_component = 1;
  sat.type_mask = kAttitudeTargetIgnoreBodyRollRate | kAttitudeTargetIgnoreBodyPitchRate;
  out.emplace_back(sat);
  sat.thrust_body = {0.f, 0.f, -0.75f};
  out.emplace_back(sat);
  VisionSpeedEstimate vse;
  vse.usec = 18446744073709551000ull;
  vse.x_mps = 1.f;
  vse.y_mps = -2.f;
  vse.z_mps = 0.125f;
  for (std::size_t i = 0; i < 9; ++i) vse.covariance[i] = i % 4 == 0 ? 0.04f : 0.f;
  vse.reset_counter = 7;
  out.emplace_back(vse);
  out.emplace_back(HighresImu{1700000000123456ull, 0.125f, -0.25f, -9.80665f, 0.01f, -0.02f, 0.03f,
                              0.21f, -0.05f, 0.43f, 1013.25f, 0.5f, 120.5f, 25.25f, 0x1FFF, 0});
  out.emplace_back(HighresImu{42, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 3});
  Statustext st;
  st.severity = 6;
  const char* text = "hq: fifty characters of text, no terminating NUL!!";
  std::memcpy(st.text.data(), text, 50);
  st.id = 0;
  out.emplace_back(st);
  Statustext st2;
  st2.severity = 1;
  std::memcpy(st2.text.data(), "short", 5);
  st2.id = 4242;
  st2.chunk_seq = 2;
  out.emplace_back(st2);
  // TIMESYNC: a request (tc1 0), an answer with targets, and an answer of the old protocol.
  out.emplace_back(Timesync{0, 1700000000123456789LL, 1, 1});
  out.emplace_back(Timesync{-42, 9223372036854775807LL, 255, 191});
  out.emplace_back(Timesync{123456789012LL, 987654321098LL, 0, 0});
  Odometry od;
  od.time_usec = 1700000000654321ull;
  od.x_m = 1.25f, od.y_m = -3.5f, od.z_m = -0.75f;
  od.q = {0.7071068f, 0.f, 0.f, -0.7071068f};
  od.vx_mps = 0.3f, od.vy_mps = -0.45f, od.vz_mps = 0.05f;
  od.rollspeed_radps = 0.01f, od.pitchspeed_radps = -0.02f, od.yawspeed_radps = 0.5f;
  for (std::size_t i = 0; i < 21; ++i) {
    od.pose_covariance[i] = 1e-3f * static_cast<float>(i + 1);
    od.velocity_covariance[i] = -2.5e-4f * static_cast<float>(i + 1);
  }
  od.frame_id = kMavFrameLocalFrd;
  od.child_frame_id = kMavFrameBodyFrd;
  od.reset_counter = 255;
  od.estimator_type = kMavEstimatorTypeVio;
  od.quality_pct = -1;
  out.emplace_back(od);
  od.quality_pct = 87;
  od.reset_counter = 0;
  out.emplace_back(od);
  out.emplace_back(ParamRequestRead{-1, 1, 1, text_of<16>("COM_OF_LOSS_T")});
  out.emplace_back(ParamRequestRead{7, 1, 0, {}});
  out.emplace_back(ParamRequestList{1, 1});
  out.emplace_back(ParamValue{0.5f, 5, 4, text_of<16>("SIXTEEN_CHARS_ID"), kMavParamTypeReal32});
  out.emplace_back(ParamSet{-1.25f, 1, 1, text_of<16>("MPC_LAND_SPEED"), kMavParamTypeReal32});
  return out;
}

std::uint32_t message_id(const Message& m) {
  return std::visit([](const auto& v) { return v.kId; }, m);
}

// One message's fields as a JSON object, under their names in fields()' order. Floats go as
// their exact double value (node compares Math.fround of it); uint64 as a decimal string,
// beyond a JSON number's exact range (node compares as BigInt).
struct JsonFields {
  nlohmann::ordered_json& object;
  template <typename T>
  static nlohmann::ordered_json number(T v) {
    if constexpr (std::is_floating_point_v<T>) {
      return static_cast<double>(v);
    } else if constexpr (std::is_same_v<T, std::uint64_t> || std::is_same_v<T, std::int64_t>) {
      return std::to_string(v);
    } else {
      return static_cast<std::int64_t>(v);
    }
  }
  template <std::size_t N>
  void operator()(const char* name, const std::array<char, N>& text) {
    object[name] = std::string(text.data(), strnlen(text.data(), text.size()));
  }
  template <typename T, std::size_t N>
  void operator()(const char* name, const std::array<T, N>& values) {
    nlohmann::ordered_json& array = object[name] = nlohmann::ordered_json::array();
    for (const T v : values) array.push_back(number(v));
  }
  template <typename T>
  void operator()(const char* name, T v) {
    object[name] = number(v);
  }
};

int write(const std::string& frames_path, const std::string& json_path) {
  std::ofstream frames(frames_path, std::ios::binary);
  std::ofstream json(json_path);
  if (!frames || !json) {
    std::cerr << "cannot write " << frames_path << " or " << json_path << "\n";
    return 2;
  }
  Encoder encoder(17, 191);
  std::array<std::uint8_t, kMaxFrameSize> buffer{};
  nlohmann::ordered_json messages = nlohmann::ordered_json::array();
  for (const Message& m : chosen_messages()) {
    const std::size_t n = encoder.encode(m, buffer);
    frames.write(reinterpret_cast<const char*>(buffer.data()), static_cast<std::streamsize>(n));
    nlohmann::ordered_json& message = messages.emplace_back();
    message["msgid"] = message_id(m);
    message["sysid"] = 17;
    message["compid"] = 191;
    message["payload_length"] = buffer[1];
    nlohmann::ordered_json& values = message["fields"] = nlohmann::ordered_json::object();
    std::visit([&](const auto& v) { fields(v, JsonFields{values}); }, m);
  }
  json << messages.dump(1) << "\n";
  return frames && json ? 0 : 2;
}

// Compares a decoded field with the tokens node wrote for it, exactly: floats as float32,
// integers as integers, the text as the characters up to the first NUL.
struct CheckFields {
  const std::vector<std::pair<std::string, std::string>>& expected;  // name -> rest of line
  std::string context;
  int mismatches = 0;
  std::size_t seen = 0;

  const std::string* find(const char* name) {
    for (const auto& [k, v] : expected) {
      if (k == name) return &v;
    }
    return nullptr;
  }
  void report(const char* name, const std::string& want, const std::string& got) {
    std::cerr << context << ": " << name << " expected " << want << ", decoded " << got << "\n";
    ++mismatches;
  }
  template <typename T>
  static bool equal(const std::string& token, T v) {
    char* end = nullptr;
    if constexpr (std::is_floating_point_v<T>) {
      // Bit for bit, so NaN payloads and -0 count; the width is T's (float or double).
      using Bits = std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>;
      const T want = static_cast<T>(std::strtod(token.c_str(), &end));
      return *end == 0 && std::bit_cast<Bits>(want) == std::bit_cast<Bits>(v);
    } else if constexpr (std::is_unsigned_v<T>) {
      return std::strtoull(token.c_str(), &end, 10) == v && *end == 0;
    } else {
      return std::strtoll(token.c_str(), &end, 10) == v && *end == 0;
    }
  }
  template <typename T>
  static std::string text(T v) {
    std::ostringstream os;
    if constexpr (std::is_floating_point_v<T>) {
      os.precision(9);
      os << v;
    } else {
      os << +v;
    }
    return os.str();
  }
  template <std::size_t N>
  void operator()(const char* name, const std::array<char, N>& value) {
    const std::string* want = find(name);
    ++seen;
    const std::string got(value.data(), strnlen(value.data(), value.size()));
    if (want == nullptr || *want != got) report(name, want ? *want : "(missing)", got);
  }
  template <typename T, std::size_t N>
  void operator()(const char* name, const std::array<T, N>& values) {
    const std::string* want = find(name);
    ++seen;
    std::istringstream tokens(want ? *want : "");
    std::string got_text;
    bool ok = want != nullptr;
    for (std::size_t i = 0; i < N; ++i) {
      std::string token;
      ok = ok && static_cast<bool>(tokens >> token) && equal(token, values[i]);
      if (i > 0) got_text.push_back(' ');
      got_text.append(text(values[i]));
    }
    if (!ok) report(name, want ? *want : "(missing)", got_text);
  }
  template <typename T>
  void operator()(const char* name, T v) {
    const std::string* want = find(name);
    ++seen;
    if (want == nullptr || !equal(*want, v)) report(name, want ? *want : "(missing)", text(v));
  }
};

int check(const std::string& frames_path, const std::string& text_path) {
  std::ifstream frames(frames_path, std::ios::binary);
  std::ifstream text(text_path);
  if (!frames || !text) {
    std::cerr << "cannot read " << frames_path << " or " << text_path << "\n";
    return 2;
  }
  const std::vector<char> bytes((std::istreambuf_iterator<char>(frames)),
                                std::istreambuf_iterator<char>());
  struct Decoded {
    FrameHeader header;
    Message message;
  };
  std::vector<Decoded> decoded;
  Parser parser;
  // Fed in odd-sized chunks so frames straddle feed() calls, as from a serial port.
  for (std::size_t i = 0; i < bytes.size(); i += 7) {
    const std::size_t n = std::min<std::size_t>(7, bytes.size() - i);
    parser.feed(
        std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(bytes.data()) + i, n),
        [&](const FrameHeader& h, const Message& m) {
          decoded.push_back({h, m});
        });
  }
  const ParserCounters& c = parser.counters();
  int mismatches = 0;
  if (c.dropped() != 0 || c.garbage_bytes != 0) {
    std::cerr << "parser dropped frames: bad_crc " << c.bad_crc << ", unknown_id " << c.unknown_id
              << ", bad_length " << c.bad_length << ", garbage bytes " << c.garbage_bytes << "\n";
    ++mismatches;
  }

  // Expected: "message ID SYSID COMPID KIND" then "FIELD VALUES..." lines until the next message.
  struct Expected {
    std::uint32_t id = 0;
    int sysid = 0, compid = 0;
    std::string kind;
    std::vector<std::pair<std::string, std::string>> fields;
  };
  std::vector<Expected> expected;
  std::string line;
  while (std::getline(text, line)) {
    if (line.empty()) continue;
    const auto space = line.find(' ');
    const std::string head = line.substr(0, space);
    const std::string rest = space == std::string::npos ? "" : line.substr(space + 1);
    if (head == "message") {
      Expected e;
      std::istringstream(rest) >> e.id >> e.sysid >> e.compid >> e.kind;
      expected.push_back(e);
    } else if (!expected.empty()) {
      expected.back().fields.emplace_back(head, rest);
    }
  }
  if (decoded.size() != expected.size()) {
    std::cerr << "decoded " << decoded.size() << " messages, node wrote " << expected.size()
              << "\n";
    return 1;
  }
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const Expected& e = expected[i];
    const Decoded& d = decoded[i];
    const std::string context =
        "message " + std::to_string(i) + " (id " + std::to_string(e.id) + ", " + e.kind + ")";
    const std::string kind = d.header.v1 ? "v1" : d.header.is_signed ? "signed" : "v2";
    if (message_id(d.message) != e.id || d.header.system_id != e.sysid ||
        d.header.component_id != e.compid || kind != e.kind) {
      std::cerr << context << ": header mismatch: id " << message_id(d.message) << " sysid "
                << int(d.header.system_id) << " compid " << int(d.header.component_id) << " "
                << kind << "\n";
      ++mismatches;
      continue;
    }
    CheckFields checker{e.fields, context};
    std::visit([&](const auto& v) { fields(v, checker); }, d.message);
    if (checker.seen != e.fields.size()) {
      std::cerr << context << ": node wrote " << e.fields.size() << " fields, codec has "
                << checker.seen << "\n";
      ++mismatches;
    }
    mismatches += checker.mismatches;
  }
  std::cout << "hq-mavlink-conformance: " << decoded.size() << " node-mavlink frames decoded ("
            << c.v1_frames << " v1), " << mismatches << " mismatches\n";
  return mismatches == 0 ? 0 : 1;
}

int targets(const std::string& json_path) {
  std::ofstream json(json_path);
  if (!json) {
    std::cerr << "cannot write " << json_path << "\n";
    return 2;
  }
  nlohmann::ordered_json table = nlohmann::ordered_json::array();
  for (const MessageTargets& m : routed_messages()) {
    table.push_back({{"msgid", m.id},
                     {"name", m.name},
                     {"crc_extra", m.crc_extra},
                     {"target_system", m.target_system_offset},
                     {"target_component", m.target_component_offset}});
  }
  json << table.dump(1) << "\n";
  return json ? 0 : 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 3 && std::string(argv[1]) == "targets") return targets(argv[2]);
  if (argc == 4 && std::string(argv[1]) == "write") return write(argv[2], argv[3]);
  if (argc == 4 && std::string(argv[1]) == "check") return check(argv[2], argv[3]);
  std::cerr
      << "usage: hq-mavlink-conformance write FRAMES JSON | check FRAMES TEXT | targets JSON\n";
  return 2;
}
