#pragma once
/// MAVLink v2 framing (https://mavlink.io/en/guide/serialization.html), written from the
/// specification because Debian ships no MAVLink library: little-endian payloads in the spec's
/// wire order (fields sorted by size, extensions last), trailing zero bytes trimmed, CRC-16/MCRF4XX
/// over the header and payload with each message's CRC_EXTRA. Nothing here allocates.

#include "hq/mavlink/messages.hpp"

#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>

namespace hq::mavlink {

inline constexpr std::uint8_t kStxV2 = 0xFD;
inline constexpr std::uint8_t kStxV1 = 0xFE;
inline constexpr std::size_t kMaxPayload = 255;
inline constexpr std::size_t kSignatureSize = 13;
/// The largest frame: 10-byte header, payload, CRC, signature.
inline constexpr std::size_t kMaxFrameSize = 10 + kMaxPayload + 2 + kSignatureSize;

/// The header fields of a received frame.
struct FrameHeader {
  std::uint8_t sequence = 0;
  std::uint8_t system_id = 0;
  std::uint8_t component_id = 0;
  std::uint32_t message_id = 0;
  bool v1 = false;         ///< Arrived as a MAVLink 1 frame (0xFE).
  bool is_signed = false;  ///< Carried a signature (skipped, not verified).
};

/// A whole received frame as it arrived (start byte to CRC and signature), for a router that
/// forwards frames it may not decode. Valid only during the callback.
struct RawFrame {
  std::span<const std::uint8_t> bytes;
  FrameHeader header;
  /// The CRC was checked with the message's CRC_EXTRA (the codec's or message_targets.hpp's);
  /// false for an id neither knows, whose CRC cannot be checked.
  bool crc_checked = false;
};

/// CRC-16/MCRF4XX (X.25) as MAVLink accumulates it.
std::uint16_t crc16_mcrf4xx(std::span<const std::uint8_t> bytes, std::uint16_t crc = 0xFFFF);

/// Encodes v2 frames from one sender (system, component), numbering them 0..255 in turn.
class Encoder {
 public:
  Encoder(std::uint8_t system_id, std::uint8_t component_id);
  /// Writes one frame of `message` into `out` (at least kMaxFrameSize bytes); returns its length.
  std::size_t encode(const Message& message, std::span<std::uint8_t, kMaxFrameSize> out);
  [[nodiscard]] std::uint8_t system_id() const { return system_id_; }
  [[nodiscard]] std::uint8_t component_id() const { return component_id_; }

 private:
  std::uint8_t system_id_;
  std::uint8_t component_id_;
  std::uint8_t sequence_ = 0;
};

/// What the parser threw away, by reason.
struct ParserCounters {
  std::uint64_t frames = 0;         ///< Valid frames of a known message handed on.
  std::uint64_t v1_frames = 0;      ///< Of those, MAVLink 1 frames.
  std::uint64_t bad_crc = 0;        ///< Checksum mismatch (the parser resynchronises).
  std::uint64_t unknown_id = 0;     ///< Well-framed, of an id known nowhere: CRC unchecked.
  std::uint64_t undecoded = 0;      ///< Valid frames of a routed message the codec does not decode.
  std::uint64_t truncated = 0;      ///< A frame cut short by the end of a datagram.
  std::uint64_t bad_length = 0;     ///< Payload longer than the message allows, or bad flags.
  std::uint64_t garbage_bytes = 0;  ///< Bytes skipped while looking for a start byte.
  [[nodiscard]] std::uint64_t dropped() const {
    return bad_crc + unknown_id + truncated + bad_length;
  }
};

/// A byte-stream parser: feed() any chunk (a UDP datagram, whatever read() gave from a serial
/// port); each valid frame of a known message is decoded and handed to the callback. Broken input
/// is counted and skipped, never trusted: a bad CRC resynchronises on the next start byte.
class Parser {
 public:
  /// Calls on_message(const FrameHeader&, const Message&) for every valid frame in `bytes`
  /// (including one completed from bytes fed earlier).
  template <typename OnMessage>
  void feed(std::span<const std::uint8_t> bytes, OnMessage&& on_message);
  /// As above, and on_frame(const RawFrame&) first for every frame handed on whole: the decoded
  /// ones, the valid ones of routed messages the codec does not decode, and those of unknown ids
  /// (CRC unchecked, still counted unknown_id). Frames failing a check never reach it.
  template <typename OnMessage, typename OnFrame>
  void feed(std::span<const std::uint8_t> bytes, OnMessage&& on_message, OnFrame&& on_frame);
  /// A datagram ended: a partial frame left in the buffer is counted truncated and dropped
  /// (UDP carries whole frames; serial streams never call this).
  void end_of_datagram();
  [[nodiscard]] const ParserCounters& counters() const { return counters_; }

 private:
  /// Consumes bytes into the frame buffer; returns how many of `bytes` it used and sets
  /// `complete` when buf_ holds a whole candidate frame.
  std::size_t accumulate(std::span<const std::uint8_t> bytes, bool& complete);
  enum class Candidate { kDropped, kRawOnly, kDecoded };
  /// Checks and decodes the candidate frame in buf_; on failure counts it and shifts buf_ past
  /// its start byte so a frame starting inside it is found. Otherwise the frame stays at the
  /// start of buf_ (frame_size bytes) until consume_frame().
  Candidate check_candidate(RawFrame& frame, Message& message);
  void consume_frame(std::size_t frame_size);

  std::uint8_t buf_[kMaxFrameSize]{};
  std::size_t size_ = 0;
  ParserCounters counters_;
};

template <typename OnMessage, typename OnFrame>
void Parser::feed(std::span<const std::uint8_t> bytes, OnMessage&& on_message, OnFrame&& on_frame) {
  RawFrame frame;
  Message message;
  while (!bytes.empty()) {
    bool complete = false;
    bytes = bytes.subspan(accumulate(bytes, complete));
    while (complete) {
      const Candidate candidate = check_candidate(frame, message);
      if (candidate != Candidate::kDropped) {
        on_frame(std::as_const(frame));
        if (candidate == Candidate::kDecoded) {
          on_message(std::as_const(frame.header), std::as_const(message));
        }
        consume_frame(frame.bytes.size());
      }
      complete = false;
      accumulate({}, complete);  // the buffer may already hold the next frame
    }
  }
}

template <typename OnMessage>
void Parser::feed(std::span<const std::uint8_t> bytes, OnMessage&& on_message) {
  feed(bytes, std::forward<OnMessage>(on_message), [](const RawFrame&) {});
}

}  // namespace hq::mavlink
