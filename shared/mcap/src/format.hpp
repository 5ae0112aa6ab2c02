#pragma once
// Record opcodes, the magic and little-endian encoding helpers shared by the writer and reader.
// Field layouts follow the MCAP specification (https://mcap.dev/spec), record by record.

#include <array>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace hq::mcap::format {

inline constexpr std::array<std::uint8_t, 8> kMagic = {0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
inline constexpr std::size_t kRecordPrefixBytes = 9;  // opcode u8 + content length u64
inline constexpr std::size_t kFooterContentBytes = 20;

enum Opcode : std::uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kMessageIndex = 0x07,
  kChunkIndex = 0x08,
  kAttachment = 0x09,
  kAttachmentIndex = 0x0A,
  kStatistics = 0x0B,
  kMetadata = 0x0C,
  kMetadataIndex = 0x0D,
  kSummaryOffset = 0x0E,
  kDataEnd = 0x0F,
};

inline void put_u8(std::vector<std::uint8_t>& out, std::uint8_t v) { out.push_back(v); }
template <typename T>
inline void put_le(std::vector<std::uint8_t>& out, T v) {
  const std::size_t at = out.size();
  out.resize(at + sizeof(T));
  for (std::size_t i = 0; i < sizeof(T); ++i) {
    out[at + i] = static_cast<std::uint8_t>(static_cast<std::uint64_t>(v) >> (8 * i));
  }
}
inline void put_u16(std::vector<std::uint8_t>& out, std::uint16_t v) { put_le(out, v); }
inline void put_u32(std::vector<std::uint8_t>& out, std::uint32_t v) { put_le(out, v); }
inline void put_u64(std::vector<std::uint8_t>& out, std::uint64_t v) { put_le(out, v); }
inline void put_raw(std::vector<std::uint8_t>& out, const void* data, std::size_t size) {
  if (size == 0) return;
  const std::size_t at = out.size();
  out.resize(at + size);
  std::memcpy(out.data() + at, data, size);
}
/// String: uint32 byte length, then UTF-8 bytes.
inline void put_string(std::vector<std::uint8_t>& out, const std::string& s) {
  put_u32(out, static_cast<std::uint32_t>(s.size()));
  put_raw(out, s.data(), s.size());
}
/// Opens a record; returns where its content length goes, for end_record.
inline std::size_t begin_record(std::vector<std::uint8_t>& out, Opcode opcode) {
  put_u8(out, opcode);
  const std::size_t at = out.size();
  put_u64(out, 0);
  return at;
}
inline void end_record(std::vector<std::uint8_t>& out, std::size_t length_at) {
  const std::uint64_t length = out.size() - length_at - 8;
  for (std::size_t i = 0; i < 8; ++i)
    out[length_at + i] = static_cast<std::uint8_t>(length >> (8 * i));
}
/// Patches a uint32 byte length (maps, arrays) written as a placeholder at `at`.
inline void patch_u32(std::vector<std::uint8_t>& out, std::size_t at, std::uint32_t v) {
  for (std::size_t i = 0; i < 4; ++i) out[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

}  // namespace hq::mcap::format
