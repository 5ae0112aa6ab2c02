#include "hq/base/error.hpp"
#include "hq/mcap/mcap.hpp"

#include "format.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <limits>
#include <set>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zstd.h>

namespace hq::mcap {

using namespace format;  // NOLINT(google-build-using-namespace): record vocabulary, file-local

namespace {

std::string hex32(std::uint32_t v) {
  std::array<char, 16> text{};
  std::snprintf(text.data(), text.size(), "0x%08x", v);
  return text.data();
}

// Read-only mapping of the whole file; the reader copies out what it keeps.
class MappedFile {
 public:
  explicit MappedFile(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw InputError(path + ": cannot open: " + std::strerror(errno));
    struct stat st {};
    if (::fstat(fd, &st) != 0) {
      const int error = errno;
      ::close(fd);
      throw InputError(path + ": fstat failed: " + std::strerror(error));
    }
    size_ = static_cast<std::size_t>(st.st_size);
    if (size_ > 0) {
      void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
      if (p == MAP_FAILED) {
        const int error = errno;
        ::close(fd);
        throw InputError(path + ": mmap failed: " + std::strerror(error));
      }
      data_ = static_cast<const std::uint8_t*>(p);
    }
    ::close(fd);
  }
  ~MappedFile() {
    if (data_ != nullptr) ::munmap(const_cast<std::uint8_t*>(data_), size_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  [[nodiscard]] Bytes bytes() const { return {data_, size_}; }

 private:
  const std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
};

// Reads the fields of one complete record; running past its end means the record is malformed.
class Fields {
 public:
  Fields(Bytes content, std::string where) : content_(content), where_(std::move(where)) {}

  std::uint8_t u8() { return static_cast<std::uint8_t>(le(1)); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(le(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(le(4)); }
  std::uint64_t u64() { return le(8); }
  Bytes take(std::uint64_t n) {
    need(n);
    const Bytes out = content_.subspan(at_, static_cast<std::size_t>(n));
    at_ += static_cast<std::size_t>(n);
    return out;
  }
  std::string string() {
    const Bytes b = take(u32());
    return {reinterpret_cast<const char*>(b.data()), b.size()};
  }
  KeyValues key_values() {
    Fields map(take(u32()), where_);
    KeyValues out;
    while (!map.done()) {
      std::string key = map.string();
      out[std::move(key)] = map.string();
    }
    return out;
  }
  Bytes rest() { return take(content_.size() - at_); }
  [[nodiscard]] bool done() const { return at_ == content_.size(); }
  [[nodiscard]] Bytes consumed() const { return content_.first(at_); }
  [[nodiscard]] const std::string& where() const { return where_; }

 private:
  void need(std::uint64_t n) const {
    if (n > content_.size() - at_) {
      throw InputError(where_ + ": malformed record (a field runs past its end)");
    }
  }
  std::uint64_t le(std::size_t n) {
    need(n);
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < n; ++i)
      v |= static_cast<std::uint64_t>(content_[at_ + i]) << (8 * i);
    at_ += n;
    return v;
  }
  Bytes content_;
  std::size_t at_ = 0;
  std::string where_;
};

struct RawRecord {
  std::uint8_t opcode = 0;
  std::uint64_t offset = 0;  // of the opcode in the file (or chunk)
  Bytes content;
  [[nodiscard]] std::uint64_t end() const { return offset + kRecordPrefixBytes + content.size(); }
};

// The record at `offset` of `bytes`, or nullopt-like false if it does not fit (a truncated tail).
bool record_at(Bytes bytes, std::uint64_t offset, RawRecord& out) {
  if (offset > bytes.size() || bytes.size() - offset < kRecordPrefixBytes) return false;
  std::uint64_t length = 0;
  for (std::size_t i = 0; i < 8; ++i) {
    length |= static_cast<std::uint64_t>(bytes[offset + 1 + i]) << (8 * i);
  }
  if (length > bytes.size() - offset - kRecordPrefixBytes) return false;
  out.opcode = bytes[offset];
  out.offset = offset;
  out.content = bytes.subspan(offset + kRecordPrefixBytes, length);
  return true;
}

}  // namespace

class ReaderImpl {
 public:
  ReaderImpl(McapReader& r, std::string path) : r_(r), path_(std::move(path)) {}

  void read() {
    const MappedFile file(path_);
    const Bytes bytes = file.bytes();
    r_.report_.file_size_bytes = bytes.size();
    if (bytes.size() < kMagic.size() || !std::equal(kMagic.begin(), kMagic.end(), bytes.begin())) {
      throw InputError(path_ + ": not an MCAP file (no magic 0x89 MCAP0 at the start)");
    }
    if (!read_with_summary(bytes)) scan(bytes);
    std::stable_sort(
        r_.messages_.begin(), r_.messages_.end(),
        [](const Message& a, const Message& b) { return a.log_time_ns < b.log_time_ns; });
    r_.report_.messages_recovered = r_.messages_.size();
    if (!r_.report_.has_summary) count_statistics();
  }

 private:
  std::string where(const char* what, std::uint64_t offset) const {
    return path_ + ": " + what + " at offset " + std::to_string(offset);
  }

  // Where the summary's indexes point.
  struct IndexedOffsets {
    std::vector<std::uint64_t> chunks;
    std::vector<std::uint64_t> attachments;
    std::vector<std::uint64_t> metadata;
  };

  // The summary section's records: schemas, channels and statistics are taken, the indexes'
  // offsets returned.
  IndexedOffsets read_summary_section(Bytes bytes, std::uint64_t summary_start,
                                      std::uint64_t summary_end) {
    IndexedOffsets offsets;
    RawRecord rec;
    for (std::uint64_t at = summary_start; at < summary_end; at = rec.end()) {
      if (!record_at(bytes.first(summary_end), at, rec)) {
        throw InputError(where("summary record", at) + ": runs past the summary section");
      }
      Fields g(rec.content, where("summary record", at));
      switch (rec.opcode) {
        case kSchema:
          add_schema(g);
          break;
        case kChannel:
          add_channel(g);
          break;
        case kStatistics:
          read_statistics(g);
          break;
        case kChunkIndex:
          g.u64();  // message_start_time
          g.u64();  // message_end_time
          offsets.chunks.push_back(g.u64());
          break;
        case kAttachmentIndex:
          offsets.attachments.push_back(g.u64());
          break;
        case kMetadataIndex:
          offsets.metadata.push_back(g.u64());
          break;
        default:
          break;
      }
    }
    return offsets;
  }

  // Footer, summary and DataEnd; false when the file has none (the caller then scans).
  bool read_with_summary(Bytes bytes) {
    const std::size_t footer_bytes = kRecordPrefixBytes + kFooterContentBytes;
    if (bytes.size() < 2 * kMagic.size() + footer_bytes) return false;
    if (!std::equal(kMagic.begin(), kMagic.end(), bytes.end() - kMagic.size())) return false;
    const std::uint64_t footer_at = bytes.size() - kMagic.size() - footer_bytes;
    RawRecord footer;
    if (!record_at(bytes, footer_at, footer) || footer.opcode != kFooter ||
        footer.content.size() != kFooterContentBytes) {
      return false;
    }
    Fields f(footer.content, where("Footer", footer_at));
    const std::uint64_t summary_start = f.u64();
    const std::uint64_t summary_offset_start = f.u64();
    const std::uint32_t summary_crc = f.u32();
    if (summary_start == 0) return false;
    if (summary_start > footer_at || summary_offset_start > footer_at) {
      throw InputError(where("Footer", footer_at) + ": summary offset beyond the footer");
    }
    if (summary_crc != 0) {
      const std::uint32_t crc = crc32_update(
          0, bytes.subspan(summary_start, footer_at + footer_bytes - 4 - summary_start));
      if (crc != summary_crc) {
        throw InputError(where("Footer", footer_at) + ": summary CRC " + hex32(crc) +
                         " does not match the stored " + hex32(summary_crc));
      }
    }
    read_header(bytes);
    check_data_end(bytes, summary_start);

    const std::uint64_t summary_end = summary_offset_start != 0 ? summary_offset_start : footer_at;
    const IndexedOffsets offsets = read_summary_section(bytes, summary_start, summary_end);
    const std::vector<std::uint64_t>& chunk_offsets = offsets.chunks;
    for (const std::uint64_t at : chunk_offsets) read_record_at(bytes, at, kChunk, "Chunk");
    for (const std::uint64_t at : offsets.attachments) {
      read_record_at(bytes, at, kAttachment, "Attachment");
    }
    for (const std::uint64_t at : offsets.metadata) {
      read_record_at(bytes, at, kMetadata, "Metadata");
    }
    // Messages may also sit outside chunks (unchunked writers), where no index points: when the
    // chunks do not hold every message the statistics count, the data section is scanned.
    if (chunk_offsets.empty() ||
        (has_statistics_ && r_.messages_.size() != r_.statistics_.message_count)) {
      r_.messages_.clear();
      r_.attachments_.clear();
      r_.metadata_.clear();
      r_.report_.chunk_count = 0;
      scan(bytes);
      r_.report_.truncated = false;
    }
    r_.report_.has_summary = true;
    r_.report_.valid_end_bytes = bytes.size();
    return true;
  }

  void read_record_at(Bytes bytes, std::uint64_t at, Opcode expected, const char* name) {
    RawRecord rec;
    if (!record_at(bytes, at, rec) || rec.opcode != expected) {
      throw InputError(where(name, at) + ": the summary's index points at no " + name + " record");
    }
    handle(rec);
  }

  void read_header(Bytes bytes) {
    RawRecord rec;
    if (!record_at(bytes, kMagic.size(), rec) || rec.opcode != kHeader) {
      throw InputError(where("Header", kMagic.size()) + ": missing Header record");
    }
    handle(rec);
  }

  void check_data_end(Bytes bytes, std::uint64_t summary_start) {
    const std::uint64_t size = kRecordPrefixBytes + 4;
    if (summary_start < kMagic.size() + size) return;
    RawRecord rec;
    const std::uint64_t at = summary_start - size;
    if (record_at(bytes.first(summary_start), at, rec) && rec.opcode == kDataEnd &&
        rec.content.size() == 4) {
      check_data_crc(bytes, rec);
    }
  }

  void check_data_crc(Bytes bytes, const RawRecord& data_end) {
    Fields f(data_end.content, where("DataEnd", data_end.offset));
    const std::uint32_t stored = f.u32();
    if (stored == 0) return;
    const std::uint32_t crc = crc32_update(0, bytes.first(data_end.offset));
    if (crc != stored) {
      throw InputError(where("DataEnd", data_end.offset) + ": data section CRC " + hex32(crc) +
                       " does not match the stored " + hex32(stored));
    }
  }

  // No usable summary: every record from the start, stopping cleanly at a truncated tail.
  void scan(Bytes bytes) {
    std::uint64_t at = kMagic.size();
    RawRecord rec;
    while (true) {
      if (at == bytes.size()) break;
      if (!record_at(bytes, at, rec)) {
        r_.report_.truncated = true;
        break;
      }
      if (rec.opcode == kFooter) {
        at = rec.end();
        break;
      }
      if (rec.opcode == kDataEnd) {
        check_data_crc(bytes, rec);
        at = rec.end();
        break;
      }
      handle(rec);
      at = rec.end();
    }
    r_.report_.valid_end_bytes = at;
  }

  // A data-section record (also from inside a chunk).
  void handle(const RawRecord& rec) {
    Fields f(rec.content, where("record", rec.offset));
    switch (rec.opcode) {
      case kHeader:
        r_.profile_ = f.string();
        r_.library_ = f.string();
        break;
      case kSchema:
        add_schema(f);
        break;
      case kChannel:
        add_channel(f);
        break;
      case kMessage:
        add_message(f);
        break;
      case kChunk:
        read_chunk(f, rec.offset);
        break;
      case kAttachment:
        add_attachment(f, rec.offset);
        break;
      case kMetadata: {
        Metadata m;
        m.name = f.string();
        m.values = f.key_values();
        r_.metadata_.push_back(std::move(m));
        break;
      }
      default:
        break;  // MessageIndex and records this reader does not need
    }
  }

  void add_schema(Fields& f) {
    Schema s;
    s.id = f.u16();
    s.name = f.string();
    s.encoding = f.string();
    const Bytes data = f.take(f.u32());
    s.data.assign(data.begin(), data.end());
    if (schema_ids_.insert(s.id).second) r_.schemas_.push_back(std::move(s));
  }

  void add_channel(Fields& f) {
    Channel c;
    c.id = f.u16();
    c.schema_id = f.u16();
    c.topic = f.string();
    c.message_encoding = f.string();
    c.metadata = f.key_values();
    if (channel_ids_.insert(c.id).second) r_.channels_.push_back(std::move(c));
  }

  void add_message(Fields& f) {
    Message m;
    m.channel_id = f.u16();
    m.sequence = f.u32();
    m.log_time_ns = static_cast<std::int64_t>(f.u64());
    m.publish_time_ns = static_cast<std::int64_t>(f.u64());
    const Bytes data = f.rest();
    m.data.assign(data.begin(), data.end());
    r_.messages_.push_back(std::move(m));
  }

  void add_attachment(Fields& f, std::uint64_t offset) {
    Attachment a;
    a.log_time_ns = static_cast<std::int64_t>(f.u64());
    a.create_time_ns = static_cast<std::int64_t>(f.u64());
    a.name = f.string();
    a.media_type = f.string();
    const Bytes data = f.take(f.u64());
    const Bytes covered = f.consumed();  // the CRC covers log_time through data
    const std::uint32_t stored = f.u32();
    if (stored != 0) {
      const std::uint32_t crc = crc32_update(0, covered);
      if (crc != stored) {
        throw InputError(where("Attachment", offset) + " (" + a.name + "): CRC " + hex32(crc) +
                         " does not match the stored " + hex32(stored));
      }
    }
    a.data.assign(data.begin(), data.end());
    r_.attachments_.push_back(std::move(a));
  }

  void read_chunk(Fields& f, std::uint64_t offset) {
    f.u64();  // message_start_time
    f.u64();  // message_end_time
    const std::uint64_t uncompressed_size = f.u64();
    const std::uint32_t uncompressed_crc = f.u32();
    const std::string compression = f.string();
    const Bytes payload = f.take(f.u64());
    Bytes records;
    if (compression.empty()) {
      records = payload;
    } else if (compression == "zstd") {
      // Frames without a content size (streaming encoders) are decoded into the size the record
      // states; a stated size beyond 4 GiB is corruption, not a chunk.
      const unsigned long long frame = ZSTD_getFrameContentSize(payload.data(), payload.size());
      if (frame == ZSTD_CONTENTSIZE_ERROR) {
        throw InputError(where("Chunk", offset) + ": the payload is not a zstd frame");
      }
      if ((frame != ZSTD_CONTENTSIZE_UNKNOWN && frame != uncompressed_size) ||
          uncompressed_size > (std::uint64_t{1} << 32)) {
        throw InputError(where("Chunk", offset) + ": zstd frame holds " +
                         (frame == ZSTD_CONTENTSIZE_UNKNOWN ? std::string("an unknown size")
                                                            : std::to_string(frame) + " bytes") +
                         ", the record says " + std::to_string(uncompressed_size));
      }
      buffer_.resize(uncompressed_size);
      const std::size_t n =
          ZSTD_decompress(buffer_.data(), buffer_.size(), payload.data(), payload.size());
      if (ZSTD_isError(n) != 0 || n != uncompressed_size) {
        throw InputError(where("Chunk", offset) + ": zstd decompression failed: " +
                         (ZSTD_isError(n) != 0 ? ZSTD_getErrorName(n) : "short output"));
      }
      records = Bytes(buffer_);
    } else {
      throw InputError(where("Chunk", offset) + ": compression \"" + compression +
                       "\" is not supported (zstd or none)");
    }
    if (records.size() != uncompressed_size) {
      throw InputError(where("Chunk", offset) + ": " + std::to_string(records.size()) +
                       " record bytes, the record says " + std::to_string(uncompressed_size));
    }
    if (uncompressed_crc != 0) {
      const std::uint32_t crc = crc32_update(0, records);
      if (crc != uncompressed_crc) {
        throw InputError(where("Chunk", offset) + ": uncompressed CRC " + hex32(crc) +
                         " does not match the stored " + hex32(uncompressed_crc));
      }
    }
    RawRecord rec;
    for (std::uint64_t at = 0; at < records.size(); at = rec.end()) {
      if (!record_at(records, at, rec)) {
        throw InputError(where("Chunk", offset) + ": record at chunk offset " + std::to_string(at) +
                         " runs past the chunk");
      }
      Fields g(rec.content, where("Chunk", offset) + ", chunk offset " + std::to_string(at));
      switch (rec.opcode) {
        case kSchema:
          add_schema(g);
          break;
        case kChannel:
          add_channel(g);
          break;
        case kMessage:
          add_message(g);
          break;
        default:
          break;
      }
    }
    ++r_.report_.chunk_count;
  }

  void read_statistics(Fields& f) {
    has_statistics_ = true;
    Statistics& s = r_.statistics_;
    s.message_count = f.u64();
    s.schema_count = f.u16();
    s.channel_count = f.u32();
    s.attachment_count = f.u32();
    s.metadata_count = f.u32();
    s.chunk_count = f.u32();
    s.message_start_time_ns = f.u64();
    s.message_end_time_ns = f.u64();
    Fields counts(f.take(f.u32()), f.where());
    while (!counts.done()) {
      const std::uint16_t id = counts.u16();
      s.channel_message_counts[id] = counts.u64();
    }
  }

  void count_statistics() {
    Statistics& s = r_.statistics_;
    s = Statistics{};
    s.message_count = r_.messages_.size();
    s.schema_count = static_cast<std::uint16_t>(r_.schemas_.size());
    s.channel_count = static_cast<std::uint32_t>(r_.channels_.size());
    s.attachment_count = static_cast<std::uint32_t>(r_.attachments_.size());
    s.metadata_count = static_cast<std::uint32_t>(r_.metadata_.size());
    s.chunk_count = static_cast<std::uint32_t>(r_.report_.chunk_count);
    for (const Channel& c : r_.channels_) s.channel_message_counts[c.id] = 0;
    for (const Message& m : r_.messages_) ++s.channel_message_counts[m.channel_id];
    if (!r_.messages_.empty()) {
      s.message_start_time_ns = static_cast<std::uint64_t>(r_.messages_.front().log_time_ns);
      s.message_end_time_ns = static_cast<std::uint64_t>(r_.messages_.back().log_time_ns);
    }
  }

  McapReader& r_;
  std::string path_;
  std::set<std::uint16_t> schema_ids_;
  std::set<std::uint16_t> channel_ids_;
  std::vector<std::uint8_t> buffer_;
  bool has_statistics_ = false;
};

McapReader::McapReader(const std::string& path) { ReaderImpl(*this, path).read(); }

const Channel* McapReader::channel(std::uint16_t id) const {
  for (const Channel& c : channels_) {
    if (c.id == id) return &c;
  }
  return nullptr;
}

const Schema* McapReader::schema(std::uint16_t id) const {
  for (const Schema& s : schemas_) {
    if (s.id == id) return &s;
  }
  return nullptr;
}

}  // namespace hq::mcap
