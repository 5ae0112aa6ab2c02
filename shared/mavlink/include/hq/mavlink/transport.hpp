#pragma once
/// Byte transports for MAVLink: UDP (as PX4 SITL and companion computers use it) and a serial
/// port in raw mode (a flight controller's TELEM/USB port). Non-blocking after open; no
/// allocation per packet.
///
/// Specs, as on the command line after `mavlink:`:
///   udp:HOST:PORT          send to HOST:PORT, receive on the socket we send from (a companion
///                          computer talking to an FC or SITL)
///   udp-listen:PORT        bind PORT (on 127.0.0.1 unless udp-listen:HOST:PORT), send to whoever
///                          sent the latest datagram (the flight-controller side, as SITL)
///   serial:DEVICE:BAUD     e.g. serial:/dev/ttyACM0:921600 (termios raw, 8N1, no flow control)

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

namespace hq::mavlink {

class Transport {
 public:
  virtual ~Transport() = default;
  /// Sends bytes (one or more whole frames). Returns false if they could not be sent now (no
  /// peer yet, a full buffer, a lost device); the caller counts that, it never throws.
  virtual bool send(std::span<const std::uint8_t> bytes) = 0;
  /// Reads what is available without blocking: one datagram for UDP, whatever is buffered for
  /// serial. Returns the byte count, 0 when nothing is pending.
  virtual std::size_t receive(std::span<std::uint8_t> buffer) = 0;
  /// True when receive() yields one datagram at a time (the parser then drops partial frames).
  [[nodiscard]] virtual bool datagrams() const = 0;
  /// Waits up to timeout_ns for input; true if some is pending.
  virtual bool wait_readable(std::int64_t timeout_ns) = 0;
  /// The spec it was opened with, for messages.
  [[nodiscard]] virtual const std::string& describe() const = 0;
  /// The latest error (errno text), "" if none.
  [[nodiscard]] virtual const std::string& error() const = 0;
  /// False while a listening transport has heard nobody to answer (a send would fail).
  [[nodiscard]] virtual bool has_peer() const { return true; }
  /// Where sends go as "HOST:PORT" (UDP), "" before a listening transport heard anyone or for
  /// serial. Allocates: for summaries, not per frame.
  [[nodiscard]] virtual std::string peer() const { return {}; }
};

/// Opens a transport from a spec (see the file comment). Throws hq::InputError naming the spec
/// and what is wrong: unknown kind, bad host or port, a baud rate termios does not have, a device
/// that cannot be opened (with strerror).
std::unique_ptr<Transport> open_transport(const std::string& spec);

}  // namespace hq::mavlink
