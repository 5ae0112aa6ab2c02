#include "hq/mavlink/codec.hpp"

#include "hq/mavlink/message_targets.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <type_traits>

namespace hq::mavlink {
namespace {

static_assert(std::endian::native == std::endian::little,
              "MAVLink payloads are little-endian; this codec copies fields as they are in memory");

constexpr std::size_t kHeaderV2 = 10;
constexpr std::size_t kHeaderV1 = 6;
constexpr std::size_t kCrcSize = 2;
constexpr std::uint8_t kIncompatSigned = 0x01;

// CRC-16/MCRF4XX: reflected polynomial 0x1021 (0x8408), init 0xFFFF, no final xor, accumulated
// byte-wise as the MAVLink specification writes it (serialization.html, "CRC").
constexpr std::uint16_t crc_accumulate(std::uint8_t byte, std::uint16_t crc) {
  std::uint8_t tmp = byte ^ static_cast<std::uint8_t>(crc & 0xFF);
  tmp ^= static_cast<std::uint8_t>(tmp << 4);
  return static_cast<std::uint16_t>((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4));
}

// Writes or reads each field at its wire offset. The payload buffer is always kMaxPayload long
// and zero-filled past the received length, so reads never leave it.
class Writer {
 public:
  explicit Writer(std::uint8_t* payload) : p_(payload) {}
  template <typename T>
  void operator()(const T& value) {
    if constexpr (std::is_arithmetic_v<T>) {
      std::memcpy(p_ + offset_, &value, sizeof(T));
      offset_ += sizeof(T);
    } else {
      for (const auto& element : value) (*this)(element);
    }
  }
  [[nodiscard]] std::size_t offset() const { return offset_; }

 private:
  std::uint8_t* p_;
  std::size_t offset_ = 0;
};

class Reader {
 public:
  explicit Reader(const std::uint8_t* payload) : p_(payload) {}
  template <typename T>
  void operator()(T& value) {
    if constexpr (std::is_arithmetic_v<T>) {
      std::memcpy(&value, p_ + offset_, sizeof(T));
      offset_ += sizeof(T);
    } else {
      for (auto& element : value) (*this)(element);
    }
  }

 private:
  const std::uint8_t* p_;
  std::size_t offset_ = 0;
};

// Per message: CRC_EXTRA, the v1 (base) and v2 (with extensions) payload lengths and the fields in
// wire order: base fields sorted by type size, largest first, stable (arrays by element size);
// then the extension fields in declaration order (common.xml, serialization.html "Field
// Reordering"). The lengths are checked against the field list by the static_asserts below.
template <typename M>
struct Spec;

template <>
struct Spec<Heartbeat> {
  static constexpr std::uint8_t kCrcExtra = 50;
  static constexpr std::size_t kBaseLen = 9, kMaxLen = 9;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.custom_mode), io(m.type), io(m.autopilot), io(m.base_mode), io(m.system_status),
        io(m.mavlink_version);
  }
};

template <>
struct Spec<SysStatus> {
  static constexpr std::uint8_t kCrcExtra = 124;
  static constexpr std::size_t kBaseLen = 31, kMaxLen = 43;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.onboard_control_sensors_present), io(m.onboard_control_sensors_enabled),
        io(m.onboard_control_sensors_health), io(m.load_permille), io(m.voltage_battery_mv),
        io(m.current_battery_ca), io(m.drop_rate_comm_cpct), io(m.errors_comm), io(m.errors_count),
        io(m.battery_remaining_pct);
    io(m.onboard_control_sensors_present_extended), io(m.onboard_control_sensors_enabled_extended),
        io(m.onboard_control_sensors_health_extended);
  }
};

template <>
struct Spec<Attitude> {
  static constexpr std::uint8_t kCrcExtra = 39;
  static constexpr std::size_t kBaseLen = 28, kMaxLen = 28;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.time_boot_ms), io(m.roll_rad), io(m.pitch_rad), io(m.yaw_rad), io(m.rollspeed_radps),
        io(m.pitchspeed_radps), io(m.yawspeed_radps);
  }
};

template <>
struct Spec<CommandLong> {
  static constexpr std::uint8_t kCrcExtra = 152;
  static constexpr std::size_t kBaseLen = 33, kMaxLen = 33;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.param), io(m.command), io(m.target_system), io(m.target_component), io(m.confirmation);
  }
};

template <>
struct Spec<CommandAck> {
  static constexpr std::uint8_t kCrcExtra = 143;
  static constexpr std::size_t kBaseLen = 3, kMaxLen = 10;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.command), io(m.result);
    io(m.progress), io(m.result_param2), io(m.target_system), io(m.target_component);
  }
};

template <>
struct Spec<SetAttitudeTarget> {
  static constexpr std::uint8_t kCrcExtra = 49;
  static constexpr std::size_t kBaseLen = 39, kMaxLen = 51;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.time_boot_ms), io(m.q), io(m.body_roll_rate_radps), io(m.body_pitch_rate_radps),
        io(m.body_yaw_rate_radps), io(m.thrust), io(m.target_system), io(m.target_component),
        io(m.type_mask);
    io(m.thrust_body);
  }
};

template <>
struct Spec<VisionSpeedEstimate> {
  static constexpr std::uint8_t kCrcExtra = 208;
  static constexpr std::size_t kBaseLen = 20, kMaxLen = 57;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.usec), io(m.x_mps), io(m.y_mps), io(m.z_mps);
    io(m.covariance), io(m.reset_counter);
  }
};

template <>
struct Spec<HighresImu> {
  static constexpr std::uint8_t kCrcExtra = 93;
  static constexpr std::size_t kBaseLen = 62, kMaxLen = 63;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.time_usec), io(m.xacc_mps2), io(m.yacc_mps2), io(m.zacc_mps2), io(m.xgyro_radps),
        io(m.ygyro_radps), io(m.zgyro_radps), io(m.xmag_gauss), io(m.ymag_gauss), io(m.zmag_gauss),
        io(m.abs_pressure_hpa), io(m.diff_pressure_hpa), io(m.pressure_alt_m),
        io(m.temperature_degc), io(m.fields_updated);
    io(m.id);
  }
};

template <>
struct Spec<Statustext> {
  static constexpr std::uint8_t kCrcExtra = 83;
  static constexpr std::size_t kBaseLen = 51, kMaxLen = 54;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.severity), io(m.text);
    io(m.id), io(m.chunk_seq);
  }
};

template <>
struct Spec<Timesync> {
  static constexpr std::uint8_t kCrcExtra = 34;
  static constexpr std::size_t kBaseLen = 16, kMaxLen = 18;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.tc1_ns), io(m.ts1_ns);
    io(m.target_system), io(m.target_component);
  }
};

template <>
struct Spec<Odometry> {
  static constexpr std::uint8_t kCrcExtra = 91;
  static constexpr std::size_t kBaseLen = 230, kMaxLen = 233;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.time_usec), io(m.x_m), io(m.y_m), io(m.z_m), io(m.q), io(m.vx_mps), io(m.vy_mps),
        io(m.vz_mps), io(m.rollspeed_radps), io(m.pitchspeed_radps), io(m.yawspeed_radps),
        io(m.pose_covariance), io(m.velocity_covariance), io(m.frame_id), io(m.child_frame_id);
    io(m.reset_counter), io(m.estimator_type), io(m.quality_pct);
  }
};

template <>
struct Spec<ParamRequestRead> {
  static constexpr std::uint8_t kCrcExtra = 214;
  static constexpr std::size_t kBaseLen = 20, kMaxLen = 20;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.param_index), io(m.target_system), io(m.target_component), io(m.param_id);
  }
};

template <>
struct Spec<ParamRequestList> {
  static constexpr std::uint8_t kCrcExtra = 159;
  static constexpr std::size_t kBaseLen = 2, kMaxLen = 2;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.target_system), io(m.target_component);
  }
};

template <>
struct Spec<ParamValue> {
  static constexpr std::uint8_t kCrcExtra = 220;
  static constexpr std::size_t kBaseLen = 25, kMaxLen = 25;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.param_value), io(m.param_count), io(m.param_index), io(m.param_id), io(m.param_type);
  }
};

template <>
struct Spec<ParamSet> {
  static constexpr std::uint8_t kCrcExtra = 168;
  static constexpr std::size_t kBaseLen = 23, kMaxLen = 23;
  template <typename Io, typename M>
  static constexpr void wire(Io& io, M& m) {
    io(m.param_value), io(m.target_system), io(m.target_component), io(m.param_id),
        io(m.param_type);
  }
};

// The field lists above must add up to the lengths of common.xml.
template <typename M>
constexpr std::size_t wire_length() {
  std::size_t n = 0;
  auto count = [&n](const auto& v) {
    using T = std::remove_cvref_t<decltype(v)>;
    if constexpr (std::is_arithmetic_v<T>) {
      n += sizeof(T);
    } else {
      n += sizeof(typename T::value_type) * std::tuple_size_v<T>;
    }
  };
  M m{};
  Spec<M>::wire(count, m);
  return n;
}
template <typename... Ms>
constexpr bool lengths_match(std::variant<Ms...>*) {
  return ((wire_length<Ms>() == Spec<Ms>::kMaxLen) && ...);
}
static_assert(lengths_match(static_cast<Message*>(nullptr)));

struct MessageInfo {
  std::uint8_t crc_extra;
  std::size_t base_len;
  std::size_t max_len;
  std::size_t variant_index;
};

template <typename... Ms>
constexpr bool find_info(std::uint32_t id, MessageInfo& out, std::variant<Ms...>*) {
  std::size_t index = 0;
  bool found = false;
  ((found = found ||
            [&] {
              const bool hit = Ms::kId == id;
              if (hit) out = {Spec<Ms>::kCrcExtra, Spec<Ms>::kBaseLen, Spec<Ms>::kMaxLen, index};
              ++index;
              return hit;
            }()),
   ...);
  return found;
}

bool message_info(std::uint32_t id, MessageInfo& out) {
  return find_info(id, out, static_cast<Message*>(nullptr));
}

template <std::size_t I = 0>
void decode_payload(std::size_t index, const std::uint8_t* payload, Message& message) {
  if constexpr (I < std::variant_size_v<Message>) {
    if (index == I) {
      auto& m = message.emplace<I>();
      Reader reader(payload);
      Spec<std::variant_alternative_t<I, Message>>::wire(reader, m);
      return;
    }
    decode_payload<I + 1>(index, payload, message);
  }
}

bool is_start(std::uint8_t byte) { return byte == kStxV2 || byte == kStxV1; }

}  // namespace

std::uint16_t crc16_mcrf4xx(std::span<const std::uint8_t> bytes, std::uint16_t crc) {
  for (const std::uint8_t b : bytes) crc = crc_accumulate(b, crc);
  return crc;
}

Encoder::Encoder(std::uint8_t system_id, std::uint8_t component_id)
    : system_id_(system_id), component_id_(component_id) {}

std::size_t Encoder::encode(const Message& message, std::span<std::uint8_t, kMaxFrameSize> out) {
  std::uint8_t* payload = out.data() + kHeaderV2;
  std::uint32_t id = 0;
  std::uint8_t crc_extra = 0;
  std::size_t length = 0;
  std::visit(
      [&](const auto& m) {
        using M = std::remove_cvref_t<decltype(m)>;
        Writer writer(payload);
        Spec<M>::wire(writer, m);
        id = M::kId;
        crc_extra = Spec<M>::kCrcExtra;
        length = writer.offset();
      },
      message);
  // MAVLink 2 trims trailing zero bytes of the payload, keeping at least one.
  while (length > 1 && payload[length - 1] == 0) --length;
  out[0] = kStxV2;
  out[1] = static_cast<std::uint8_t>(length);
  out[2] = 0;  // incompat_flags: unsigned
  out[3] = 0;  // compat_flags
  out[4] = sequence_++;
  out[5] = system_id_;
  out[6] = component_id_;
  out[7] = static_cast<std::uint8_t>(id & 0xFF);
  out[8] = static_cast<std::uint8_t>((id >> 8) & 0xFF);
  out[9] = static_cast<std::uint8_t>((id >> 16) & 0xFF);
  std::uint16_t crc = crc16_mcrf4xx(std::span<const std::uint8_t>(out.data() + 1, 9 + length));
  crc = crc_accumulate(crc_extra, crc);
  out[kHeaderV2 + length] = static_cast<std::uint8_t>(crc & 0xFF);
  out[kHeaderV2 + length + 1] = static_cast<std::uint8_t>(crc >> 8);
  return kHeaderV2 + length + kCrcSize;
}

void Parser::end_of_datagram() {
  if (size_ > 0) {
    ++counters_.truncated;
    size_ = 0;
  }
}

std::size_t Parser::accumulate(std::span<const std::uint8_t> bytes, bool& complete) {
  std::size_t used = 0;
  for (;;) {
    // The buffer starts with a start byte or is empty (after a failed candidate it may not).
    if (size_ > 0 && !is_start(buf_[0])) {
      std::size_t i = 1;
      while (i < size_ && !is_start(buf_[i])) ++i;
      counters_.garbage_bytes += i;
      std::memmove(buf_, buf_ + i, size_ - i);
      size_ -= i;
    }
    if (size_ == 0) {
      std::size_t i = used;
      while (i < bytes.size() && !is_start(bytes[i])) ++i;
      counters_.garbage_bytes += i - used;
      used = i;
      if (used == bytes.size()) return used;
      buf_[0] = bytes[used++];
      size_ = 1;
    }
    const bool v2 = buf_[0] == kStxV2;
    const std::size_t header = v2 ? kHeaderV2 : kHeaderV1;
    std::size_t need = header;
    if (size_ >= header) {
      if (v2 && (buf_[2] & ~kIncompatSigned) != 0) {
        // An incompatibility flag this codec does not implement: the frame cannot be understood.
        ++counters_.bad_length;
        std::memmove(buf_, buf_ + 1, size_ - 1);
        --size_;
        continue;
      }
      need =
          header + buf_[1] + kCrcSize + ((v2 && (buf_[2] & kIncompatSigned)) ? kSignatureSize : 0);
    }
    // After a failed candidate the buffer may already hold more than this frame.
    const std::size_t take = size_ >= need ? 0 : std::min(need - size_, bytes.size() - used);
    // memcpy from the null data() of an empty span is undefined even for 0 bytes (UBSan).
    if (take > 0) std::memcpy(buf_ + size_, bytes.data() + used, take);
    size_ += take;
    used += take;
    if (size_ < need) return used;  // all input used, the frame continues in the next chunk
    if (need == header) continue;   // header complete: now the frame length is known
    complete = true;
    return used;
  }
}

void Parser::consume_frame(std::size_t frame_size) {
  // Bytes after this frame stay for the next candidate (they are there after a resync).
  std::memmove(buf_, buf_ + frame_size, size_ - frame_size);
  size_ -= frame_size;
}

Parser::Candidate Parser::check_candidate(RawFrame& frame, Message& message) {
  const bool v2 = buf_[0] == kStxV2;
  const std::size_t header_size = v2 ? kHeaderV2 : kHeaderV1;
  const std::size_t length = buf_[1];
  const std::size_t frame_size = header_size + length + kCrcSize +
                                 ((v2 && (buf_[2] & kIncompatSigned) != 0) ? kSignatureSize : 0);
  auto drop_start_byte = [&] {
    std::memmove(buf_, buf_ + 1, size_ - 1);
    --size_;
  };

  const std::uint32_t id =
      v2 ? static_cast<std::uint32_t>(buf_[7] | (buf_[8] << 8) | (buf_[9] << 16)) : buf_[5];
  FrameHeader& header = frame.header;
  header.v1 = !v2;
  header.is_signed = v2 && (buf_[2] & kIncompatSigned) != 0;
  header.sequence = v2 ? buf_[4] : buf_[2];
  header.system_id = v2 ? buf_[5] : buf_[3];
  header.component_id = v2 ? buf_[6] : buf_[4];
  header.message_id = id;
  frame.bytes = std::span<const std::uint8_t>(buf_, frame_size);

  MessageInfo info{};
  const bool decodable = message_info(id, info);
  const MessageTargets* routed = decodable ? nullptr : find_message_targets(id);
  if (!decodable && routed == nullptr) {
    // Well framed but known nowhere: its CRC cannot be checked without the CRC_EXTRA, so trust
    // the length and hand the frame on whole, unchecked, for a router to forward.
    ++counters_.unknown_id;
    frame.crc_checked = false;
    return Candidate::kRawOnly;
  }
  std::uint16_t crc =
      crc16_mcrf4xx(std::span<const std::uint8_t>(buf_ + 1, header_size - 1 + length));
  crc = crc_accumulate(decodable ? info.crc_extra : routed->crc_extra, crc);
  const std::uint16_t received = static_cast<std::uint16_t>(buf_[header_size + length] |
                                                            (buf_[header_size + length + 1] << 8));
  if (crc != received) {
    ++counters_.bad_crc;
    drop_start_byte();  // a real frame may begin inside this one
    return Candidate::kDropped;
  }
  frame.crc_checked = true;
  if (!decodable) {
    ++counters_.undecoded;
    return Candidate::kRawOnly;
  }
  // MAVLink 1 frames carry no extensions; one that does anyway (node-mavlink writes them) is
  // accepted and its extension bytes ignored.
  if (length > info.max_len) {
    ++counters_.bad_length;
    consume_frame(frame_size);
    return Candidate::kDropped;
  }
  std::uint8_t payload[kMaxPayload]{};  // zero padding restores trimmed bytes and extensions
  std::memcpy(payload, buf_ + header_size, v2 ? length : std::min(length, info.base_len));
  decode_payload(info.variant_index, payload, message);
  ++counters_.frames;
  if (!v2) ++counters_.v1_frames;
  return Candidate::kDecoded;
}

}  // namespace hq::mavlink
