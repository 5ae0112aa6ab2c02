#pragma once
/// Reading a flight record (hq-ground --record's flight.mcap, written by ground/mcap_recorder)
/// back as link samples: the cdr channels are decoded with the IDL's idlc-generated descriptors
/// (Cyclone's CDR stream reader, after its normalize step has checked every length and bound
/// against the type, so a damaged message is refused, never read out of bounds); the ground's
/// own channels (/ground/haptics, /ground/link) are read from their JSON. Replay, hq-report and the
/// CSV export (hq-report --csv) all take their data from here.

#include "hq/link/link.hpp"
#include "hq/mcap/mcap.hpp"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace hq::console {

/// Receives a flight's samples in log-time order. log_ns is the ground's receipt (dds_time(),
/// the CSV recording's receipt_ns clock), publish_ns the sample's DDS source timestamp.
class FlightSampleSink {
 public:
  virtual ~FlightSampleSink() = default;
  virtual void on_state(std::int64_t /*log_ns*/, std::int64_t /*publish_ns*/,
                        const link::VehicleState& /*state*/) {}
  virtual void on_camera(std::int64_t /*log_ns*/, const link::CameraFrame& /*frame*/) {}
  virtual void on_event(std::int64_t /*log_ns*/, const link::Event& /*event*/) {}
  virtual void on_mode_request(std::int64_t /*log_ns*/, const link::ModeRequest& /*request*/) {}
  /// The recording station's command at one tick (/ground/haptics): commands.csv's row. Zero
  /// velocity when !valid, as sent.
  virtual void on_command(std::int64_t /*t_ns*/, bool /*valid*/,
                          const std::array<float, 3>& /*v_H_mps*/, float /*yaw_rate_radps*/) {}
  /// The ground's link figures at one tick (/ground/link): the latest state's age through the
  /// clock offset and the heartbeat round trip (ms; < 0 or NaN: unknown then).
  virtual void on_ground_link(std::int64_t /*t_ns*/, float /*state_age_ms*/,
                              float /*round_trip_ms*/) {}
  /// A message that could not be decoded ("flight.mcap: /hq/vehicle_state message 17: ...").
  virtual void on_problem(const std::string& /*text*/) {}
};

/// What read_flight() found.
struct FlightCounts {
  std::size_t states = 0;
  std::size_t frames = 0;
  std::size_t events = 0;
  std::size_t mode_requests = 0;
  std::size_t commands = 0;
  std::size_t undecodable = 0;
};

/// Hands every message of the channels above to `sink`, in log-time order; `name` prefixes
/// problems. A channel whose schema is not the link's (another IDL type name) is not read.
FlightCounts read_flight(const mcap::McapReader& reader, const std::string& name,
                         FlightSampleSink& sink);

/// Decodes one "cdr" message (4-byte encapsulation header, then XCDR1 or XCDR2 plain data in
/// either byte order, as Cyclone sends final types) into `out`, reusing its buffers. False
/// with `error` set when the header is unknown or the data does not fit the type.
template <typename T>
bool decode_cdr(mcap::Bytes message, link::Sample<T>& out, std::vector<std::uint8_t>& scratch,
                std::string& error);

/// True if `path` is a file starting with the MCAP magic.
bool is_mcap_file(const std::string& path);

}  // namespace hq::console
