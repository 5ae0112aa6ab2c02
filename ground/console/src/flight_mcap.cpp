#include "hq/console/flight_mcap.hpp"

#include "hq/base/format_into.hpp"

#include <dds/ddsi/ddsi_cdrstream.h>
#include <dds/ddsrt/endian.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string_view>

namespace hq::console {

namespace {

// The encapsulation identifiers (RTPS 2.5 10.5, XTypes 1.3 7.6.3.1.2) of the representations
// Cyclone uses for final types: XCDR1 and plain XCDR2, big or little endian.
struct Encapsulation {
  std::uint32_t xcdr_version = 0;  // 0: not one of them
  bool little_endian = false;
};

Encapsulation encapsulation(mcap::Bytes message) {
  switch ((unsigned{message[0]} << 8) | message[1]) {
    case 0x0000:
      return {1, false};  // CDR_BE
    case 0x0001:
      return {1, true};  // CDR_LE
    case 0x0006:
      return {2, false};  // PLAIN_CDR2_BE
    case 0x0007:
      return {2, true};  // PLAIN_CDR2_LE
    default:
      return {};
  }
}

// A finite number at `key` of a JSON object; false if absent, not a number, or null (the
// recorder's NaN).
bool finite_number(const nlohmann::json& object, const char* key, double& out) {
  const auto it = object.find(key);
  if (it == object.end() || !it->is_number()) return false;
  out = it->get<double>();
  return std::isfinite(out);
}

// One "/ground/haptics" message (hq_ground.Haptics): command_valid, v_cmd_H_mps {x,y,z},
// yaw_rate_cmd_radps. False if it is not JSON or lacks one of them.
bool parse_ground_command(std::string_view text, bool& valid, std::array<float, 3>& v_H_mps,
                          float& yaw_rate_radps) {
  const nlohmann::json json = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!json.is_object()) return false;  // also a discarded (unparsable) value
  const auto valid_it = json.find("command_valid");
  const auto v_it = json.find("v_cmd_H_mps");
  if (valid_it == json.end() || !valid_it->is_boolean() || v_it == json.end() ||
      !v_it->is_object()) {
    return false;
  }
  valid = valid_it->get<bool>();
  double v = 0;
  static constexpr std::array<const char*, 3> kAxes = {"x", "y", "z"};
  for (std::size_t i = 0; i < 3; ++i) {
    if (!finite_number(*v_it, kAxes[i], v)) return false;
    v_H_mps[i] = static_cast<float>(v);
  }
  if (!finite_number(json, "yaw_rate_cmd_radps", v)) return false;
  yaw_rate_radps = static_cast<float>(v);
  return true;
}

// One "/ground/link" message (hq_ground.Link): state_age_ms and round_trip_ms, each a number or
// null (unknown). False if it is not JSON or lacks one of them.
bool parse_ground_link(std::string_view text, float& state_age_ms, float& round_trip_ms) {
  const nlohmann::json json = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!json.is_object()) return false;
  const auto figure = [&](const char* key, float& out) {
    const auto it = json.find(key);
    if (it == json.end() || !(it->is_number() || it->is_null())) return false;
    out = it->is_number() ? it->get<float>() : -1.0F;
    if (!std::isfinite(out)) out = -1.0F;
    return true;
  };
  return figure("state_age_ms", state_age_ms) && figure("round_trip_ms", round_trip_ms);
}

enum class Kind { kNone, kState, kCamera, kEvent, kModeRequest, kGroundCommand, kGroundLink };

// The channels read, by topic and the schema the recorder gives them.
Kind kind_of(const mcap::McapReader& reader, const mcap::Channel& c) {
  const mcap::Schema* schema = reader.schema(c.schema_id);
  const std::string schema_name = schema != nullptr ? schema->name : "";
  if (c.message_encoding == "json" && c.topic == "/ground/haptics") return Kind::kGroundCommand;
  if (c.message_encoding == "json" && c.topic == "/ground/link") return Kind::kGroundLink;
  if (c.message_encoding != "cdr") return Kind::kNone;
  if (c.topic == "/hq/vehicle_state" && schema_name == "hq_msgs::VehicleState") {
    return Kind::kState;
  }
  if (c.topic == "/hq/camera_frame" && schema_name == "hq_msgs::CameraFrame") return Kind::kCamera;
  if (c.topic == "/hq/event" && schema_name == "hq_msgs::Event") return Kind::kEvent;
  if (c.topic == "/hq/mode_request" && schema_name == "hq_msgs::ModeRequest") {
    return Kind::kModeRequest;
  }
  return Kind::kNone;
}

// One decoder per type, its sample reused from message to message.
struct Decoders {
  link::Sample<link::VehicleState> state;
  link::Sample<link::CameraFrame> camera;
  link::Sample<link::Event> event;
  link::Sample<link::ModeRequest> mode;
  std::vector<std::uint8_t> scratch;
  std::string error;
};

// Decodes `m` as `kind` and hands it to the sink; false (error set) if it does not decode.
bool dispatch(Kind kind, const mcap::Message& m, Decoders& d, FlightSampleSink& sink,
              FlightCounts& counts) {
  switch (kind) {
    case Kind::kState:
      if (!decode_cdr(m.data, d.state, d.scratch, d.error)) return false;
      sink.on_state(m.log_time_ns, m.publish_time_ns, *d.state);
      ++counts.states;
      return true;
    case Kind::kCamera:
      if (!decode_cdr(m.data, d.camera, d.scratch, d.error)) return false;
      sink.on_camera(m.log_time_ns, *d.camera);
      ++counts.frames;
      return true;
    case Kind::kEvent:
      if (!decode_cdr(m.data, d.event, d.scratch, d.error)) return false;
      sink.on_event(m.log_time_ns, *d.event);
      ++counts.events;
      return true;
    case Kind::kModeRequest:
      if (!decode_cdr(m.data, d.mode, d.scratch, d.error)) return false;
      sink.on_mode_request(m.log_time_ns, *d.mode);
      ++counts.mode_requests;
      return true;
    case Kind::kGroundCommand: {
      bool valid = false;
      std::array<float, 3> v{};
      float yaw_rate = 0;
      const std::string_view json(reinterpret_cast<const char*>(m.data.data()), m.data.size());
      if (!parse_ground_command(json, valid, v, yaw_rate)) {
        d.error = "not the recorder's haptics JSON (command_valid, v_cmd_H_mps, yaw_rate)";
        return false;
      }
      sink.on_command(m.log_time_ns, valid, v, yaw_rate);
      ++counts.commands;
      return true;
    }
    case Kind::kGroundLink: {
      float state_age_ms = -1;
      float round_trip_ms = -1;
      const std::string_view json(reinterpret_cast<const char*>(m.data.data()), m.data.size());
      if (!parse_ground_link(json, state_age_ms, round_trip_ms)) {
        d.error = "not the recorder's link JSON (state_age_ms, round_trip_ms)";
        return false;
      }
      sink.on_ground_link(m.log_time_ns, state_age_ms, round_trip_ms);
      return true;
    }
    case Kind::kNone:
      return true;
  }
  return true;
}

}  // namespace

template <typename T>
bool decode_cdr(mcap::Bytes message, link::Sample<T>& out, std::vector<std::uint8_t>& scratch,
                std::string& error) {
  if (message.size() <= 4) {
    error = "CDR of " + std::to_string(message.size()) + " bytes, expected a header and data";
    return false;
  }
  const Encapsulation e = encapsulation(message);
  if (e.xcdr_version == 0) {
    char text[96];
    hq::format_into(
        text,
        "CDR encapsulation 0x{:02x}{:02x}, expected XCDR1 or plain XCDR2 (0000/0001/0006/0007)",
        message[0], message[1]);
    error = text;
    return false;
  }
  // Normalizing swaps to this host's byte order in place and checks every length, bound and
  // enum against the type's ops: only then may the stream reader copy from it.
  scratch.assign(message.begin() + 4, message.end());
  const auto size = static_cast<std::uint32_t>(scratch.size());
  const std::uint32_t* ops = link::TopicTraits<T>::descriptor().m_ops;
  const bool swap = e.little_endian != (DDSRT_ENDIAN == DDSRT_LITTLE_ENDIAN);
  std::uint32_t offset = 0;
  if (dds_stream_normalize_data(reinterpret_cast<char*>(scratch.data()), &offset, size, swap,
                                e.xcdr_version, ops) == nullptr) {
    error = "CDR of " + std::to_string(size) +
            " bytes does not fit the IDL type (a length, bound or enum out of range, or cut)";
    return false;
  }
  dds_istream_t in;
  dds_istream_init(&in, size, scratch.data(), e.xcdr_version);
  dds_stream_read(&in, reinterpret_cast<char*>(&*out), ops);
  return true;
}

template bool decode_cdr(mcap::Bytes, link::Sample<link::VehicleState>&, std::vector<std::uint8_t>&,
                         std::string&);
template bool decode_cdr(mcap::Bytes, link::Sample<link::CameraFrame>&, std::vector<std::uint8_t>&,
                         std::string&);
template bool decode_cdr(mcap::Bytes, link::Sample<link::Event>&, std::vector<std::uint8_t>&,
                         std::string&);
template bool decode_cdr(mcap::Bytes, link::Sample<link::ModeRequest>&, std::vector<std::uint8_t>&,
                         std::string&);
template bool decode_cdr(mcap::Bytes, link::Sample<link::VelocityCommand>&,
                         std::vector<std::uint8_t>&, std::string&);

FlightCounts read_flight(const mcap::McapReader& reader, const std::string& name,
                         FlightSampleSink& sink) {
  std::vector<Kind> kinds;
  for (const mcap::Channel& c : reader.channels()) {
    if (kinds.size() <= c.id) kinds.resize(c.id + 1u, Kind::kNone);
    kinds[c.id] = kind_of(reader, c);
  }
  Decoders decoders;
  FlightCounts counts;
  std::vector<std::size_t> index(kinds.size(), 0);
  for (const mcap::Message& m : reader.messages()) {
    if (m.channel_id >= kinds.size() || kinds[m.channel_id] == Kind::kNone) continue;
    const std::size_t n = index[m.channel_id]++;
    if (!dispatch(kinds[m.channel_id], m, decoders, sink, counts)) {
      ++counts.undecodable;
      sink.on_problem(name + ": " + reader.channel(m.channel_id)->topic + " message " +
                      std::to_string(n) + ": " + decoders.error);
    }
  }
  return counts;
}

bool is_mcap_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[8] = {};
  in.read(magic, sizeof magic);
  return in && std::memcmp(magic, "\x89MCAP0\r\n", 8) == 0;
}

}  // namespace hq::console
