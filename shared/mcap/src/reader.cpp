#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/mcap/mcap.hpp"

#include "format.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <limits>
#include <optional>
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
  hq::format_into(text.data(), text.size(), "0x{:08x}", v);
  return text.data();
}

std::string hex8(std::uint8_t v) {
  std::array<char, 8> text{};
  hq::format_into(text.data(), text.size(), "0x{:02x}", v);
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

bool is_known_opcode(std::uint8_t opcode) { return opcode >= kHeader && opcode <= kDataEnd; }

// Messages the MessageIndex record at `at` lists (16 bytes an entry), or nullopt when no
// well-formed one is there.
std::optional<std::uint64_t> indexed_messages(Bytes bytes, std::uint64_t at) {
  RawRecord rec;
  if (!record_at(bytes, at, rec) || rec.opcode != kMessageIndex || rec.content.size() < 6) {
    return std::nullopt;
  }
  std::uint32_t length = 0;
  for (std::size_t i = 0; i < 4; ++i) length |= std::uint32_t{rec.content[2 + i]} << (8 * i);
  if (length % 16 != 0 || length != rec.content.size() - 6) return std::nullopt;
  return length / 16;
}

// A Chunk record's framing and payload look intact: cheap checks (the stored CRC of an
// uncompressed payload, the zstd frame's stated size), for finding the way back after damage.
bool chunk_looks_intact(const RawRecord& rec) {
  try {
    Fields f(rec.content, "");
    f.u64();
    f.u64();
    const std::uint64_t uncompressed_size = f.u64();
    const std::uint32_t uncompressed_crc = f.u32();
    const std::string compression = f.string();
    const Bytes payload = f.take(f.u64());
    if (!f.done()) return false;
    if (compression.empty()) {
      return payload.size() == uncompressed_size &&
             (uncompressed_crc == 0 || crc32_update(0, payload) == uncompressed_crc);
    }
    return compression == "zstd" &&
           ZSTD_getFrameContentSize(payload.data(), payload.size()) == uncompressed_size;
  } catch (const InputError&) {
    return false;
  }
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
    bool indexed = false;
    try {
      indexed = read_with_summary(bytes);
    } catch (const InputError& e) {
      // The summary only repeats what the data section holds: read that instead.
      warn(std::string(e.what()) + "; the summary is not used, the data section is scanned");
      reset_content();
    }
    if (!indexed) scan(bytes);
    std::stable_sort(
        r_.messages_.begin(), r_.messages_.end(),
        [](const Message& a, const Message& b) { return a.log_time_ns < b.log_time_ns; });
    r_.report_.messages_recovered = r_.messages_.size();
    if (!r_.report_.has_summary) count_statistics();
  }

 private:
  // A chunk the summary indexes, with where its MessageIndex records lie (to count what it
  // held should it be damaged).
  struct ChunkRef {
    std::uint64_t offset = 0;
    std::vector<std::uint64_t> message_index_offsets;
  };
  // Where the summary's indexes point.
  struct IndexedOffsets {
    std::vector<ChunkRef> chunks;
    std::vector<std::uint64_t> attachments;
    std::vector<std::uint64_t> metadata;
  };

  std::string where(const char* what, std::uint64_t offset) const {
    return path_ + ": " + what + " at offset " + std::to_string(offset);
  }

  void warn(std::string text) { r_.report_.warnings.push_back(std::move(text)); }

  // Everything read so far, for a fresh scan after an unusable summary (warnings kept).
  void reset_content() {
    std::vector<std::string> warnings = std::move(r_.report_.warnings);
    r_.profile_.clear();
    r_.library_.clear();
    r_.schemas_.clear();
    r_.channels_.clear();
    r_.messages_.clear();
    r_.attachments_.clear();
    r_.metadata_.clear();
    r_.statistics_ = Statistics{};
    const std::uint64_t file_size_bytes = r_.report_.file_size_bytes;
    r_.report_ = ReadReport{};
    r_.report_.file_size_bytes = file_size_bytes;
    r_.report_.warnings = std::move(warnings);
    schema_ids_.clear();
    channel_ids_.clear();
    has_statistics_ = false;
  }

  void drop_chunk(const std::string& reason, std::optional<std::uint64_t> messages) {
    ++r_.report_.chunks_dropped;
    if (messages) {
      r_.report_.messages_dropped += *messages;
    } else {
      ++r_.report_.chunks_dropped_uncounted;
    }
    warn(reason + "; chunk skipped, " +
         (messages ? std::to_string(*messages) + " messages lost"
                   : std::string("its message count unknown (no readable message index)")));
  }

  void skip_record(const std::string& reason) {
    ++r_.report_.records_skipped;
    warn(reason + "; record skipped");
  }

  ChunkRef read_chunk_index(Fields& g) {
    g.u64();  // message_start_time
    g.u64();  // message_end_time
    ChunkRef chunk;
    chunk.offset = g.u64();
    g.u64();  // chunk_length
    Fields index_offsets(g.take(g.u32()), g.where());
    while (!index_offsets.done()) {
      index_offsets.u16();  // channel id
      chunk.message_index_offsets.push_back(index_offsets.u64());
    }
    return chunk;
  }

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
          keep(parse_schema(g));
          break;
        case kChannel:
          keep(parse_channel(g));
          break;
        case kStatistics:
          read_statistics(g);
          break;
        case kChunkIndex:
          offsets.chunks.push_back(read_chunk_index(g));
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

  // The footer's summary and summary-offset starts, checked against the summary CRC; nullopt
  // when the file has no footer (a killed writer). @throws InputError when it is damaged.
  std::optional<std::pair<std::uint64_t, std::uint64_t>> read_footer(Bytes bytes) {
    const std::size_t footer_bytes = kRecordPrefixBytes + kFooterContentBytes;
    if (bytes.size() < 2 * kMagic.size() + footer_bytes) return std::nullopt;
    if (!std::equal(kMagic.begin(), kMagic.end(), bytes.end() - kMagic.size())) {
      return std::nullopt;
    }
    const std::uint64_t footer_at = bytes.size() - kMagic.size() - footer_bytes;
    RawRecord footer;
    if (!record_at(bytes, footer_at, footer) || footer.opcode != kFooter ||
        footer.content.size() != kFooterContentBytes) {
      return std::nullopt;
    }
    Fields f(footer.content, where("Footer", footer_at));
    const std::uint64_t summary_start = f.u64();
    const std::uint64_t summary_offset_start = f.u64();
    const std::uint32_t summary_crc = f.u32();
    if (summary_start == 0) return std::nullopt;
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
    return std::pair{summary_start, summary_offset_start != 0 ? summary_offset_start : footer_at};
  }

  // Footer, summary and DataEnd; false when the file has none (the caller then scans).
  // @throws InputError when the footer or summary is damaged (the caller then scans).
  bool read_with_summary(Bytes bytes) {
    const auto summary = read_footer(bytes);
    if (!summary) return false;
    const auto [summary_start, summary_end] = *summary;
    read_header(bytes);
    check_data_end(bytes, summary_start);
    const IndexedOffsets offsets = read_summary_section(bytes, summary_start, summary_end);
    for (const ChunkRef& chunk : offsets.chunks) read_indexed_chunk(bytes, chunk);
    for (const std::uint64_t at : offsets.attachments) {
      read_indexed_record(bytes, at, kAttachment, "Attachment");
    }
    for (const std::uint64_t at : offsets.metadata) {
      read_indexed_record(bytes, at, kMetadata, "Metadata");
    }
    // Messages may also sit outside chunks (unchunked writers), where no index points: when the
    // chunks do not hold every message the statistics count, the data section is scanned. (A
    // dropped chunk whose count is unknown leaves nothing to compare with.)
    const bool counts_differ =
        has_statistics_ && r_.report_.chunks_dropped_uncounted == 0 &&
        r_.messages_.size() + r_.report_.messages_dropped != r_.statistics_.message_count;
    if (offsets.chunks.empty() || counts_differ) {
      const Statistics statistics = r_.statistics_;
      reset_content();
      scan(bytes);
      r_.statistics_ = statistics;
      r_.report_.truncated = false;
    }
    r_.report_.has_summary = true;
    r_.report_.valid_end_bytes = bytes.size();
    return true;
  }

  void read_indexed_chunk(Bytes bytes, const ChunkRef& chunk) {
    RawRecord rec;
    try {
      if (!record_at(bytes, chunk.offset, rec) || rec.opcode != kChunk) {
        throw InputError(where("Chunk", chunk.offset) +
                         ": the summary's index points at no Chunk record (a damaged header)");
      }
      Fields f(rec.content, where("Chunk", rec.offset));
      read_chunk(f, rec.offset);
    } catch (const InputError& e) {
      std::optional<std::uint64_t> messages = 0;
      for (const std::uint64_t at : chunk.message_index_offsets) {
        const std::optional<std::uint64_t> n = indexed_messages(bytes, at);
        if (!n) {
          messages.reset();
          break;
        }
        *messages += *n;
      }
      if (chunk.message_index_offsets.empty()) messages.reset();
      drop_chunk(e.what(), messages);
    }
  }

  void read_indexed_record(Bytes bytes, std::uint64_t at, Opcode expected, const char* name) {
    RawRecord rec;
    if (!record_at(bytes, at, rec) || rec.opcode != expected) {
      skip_record(where(name, at) + ": the summary's index points at no " + name + " record");
      return;
    }
    handle_or_skip(rec);
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

  // Says that something in the data section is damaged; the chunks' and attachments' own CRCs
  // then say which, and only those are left out.
  void check_data_crc(Bytes bytes, const RawRecord& data_end) {
    Fields f(data_end.content, where("DataEnd", data_end.offset));
    const std::uint32_t stored = f.u32();
    if (stored == 0) return;
    const std::uint32_t crc = crc32_update(0, bytes.first(data_end.offset));
    if (crc != stored) {
      warn(where("DataEnd", data_end.offset) + ": data section CRC " + hex32(crc) +
           " does not match the stored " + hex32(stored) +
           " (the data section is damaged; records failing their own checks are skipped)");
    }
  }

  // The first offset from `from` where a chain of well-formed records leads to an intact chunk
  // or to the end of the data section: where the scan goes on after a damaged record header.
  // A chain never starts at a Message record, so that a damaged chunk's own inner records are
  // not taken for top-level ones.
  std::optional<std::uint64_t> resync(Bytes bytes, std::uint64_t from) const {
    for (std::uint64_t p = from; p < bytes.size(); ++p) {
      if (!is_known_opcode(bytes[p]) || bytes[p] == kMessage) continue;
      RawRecord rec;
      for (std::uint64_t at = p; record_at(bytes, at, rec) && is_known_opcode(rec.opcode);
           at = rec.end()) {
        if (rec.opcode == kChunk) {
          if (chunk_looks_intact(rec)) return p;
          break;
        }
        if ((rec.opcode == kDataEnd && rec.content.size() == 4) ||
            (rec.opcode == kFooter && rec.content.size() == kFooterContentBytes)) {
          return p;
        }
      }
    }
    return std::nullopt;
  }

  // A record left out in a scan, settled once the records after it say what it was: a chunk
  // when MessageIndex records follow (they count its messages) or its header said so.
  struct PendingDrop {
    bool active = false;
    std::string reason;
    bool chunk = false;
    bool counted = false;
    std::uint64_t messages = 0;
  };

  void settle(PendingDrop& pending) {
    if (!pending.active) return;
    if (pending.counted || pending.chunk) {
      drop_chunk(pending.reason,
                 pending.counted ? std::optional<std::uint64_t>(pending.messages) : std::nullopt);
    } else {
      skip_record(pending.reason);
    }
    pending = PendingDrop{};
  }

  [[nodiscard]] static bool framing_intact(Bytes bytes, std::uint64_t at, RawRecord& rec) {
    return record_at(bytes, at, rec) && is_known_opcode(rec.opcode) &&
           (rec.opcode != kFooter || rec.content.size() == kFooterContentBytes) &&
           (rec.opcode != kDataEnd || rec.content.size() == 4);
  }

  // No usable summary: every record from the start. A damaged chunk is dropped (its messages
  // counted from the MessageIndex records after it), a damaged record header stepped over to
  // the next intact record, and the scan stops cleanly at a truncated tail.
  void scan(Bytes bytes) {
    std::uint64_t at = kMagic.size();
    RawRecord rec;
    PendingDrop pending;
    while (at < bytes.size()) {
      if (!framing_intact(bytes, at, rec)) {
        const std::optional<std::uint64_t> next = resync(bytes, at + 1);
        if (!next) {
          r_.report_.truncated = true;  // a cut tail, not damage: nothing intact follows
          break;
        }
        settle(pending);
        pending.active = true;
        pending.reason = where("record", at) + " (opcode " + hex8(bytes[at]) +
                         "): damaged header; " + std::to_string(*next - at) +
                         " bytes skipped to the intact record at offset " + std::to_string(*next);
        pending.chunk = bytes[at] == kChunk;
        r_.report_.bytes_skipped += *next - at;
        at = *next;
        continue;
      }
      if (rec.opcode == kMessageIndex && pending.active) {
        if (const std::optional<std::uint64_t> n = indexed_messages(bytes, at)) {
          pending.messages += *n;
          pending.counted = true;
        }
        at = rec.end();
        continue;
      }
      settle(pending);
      if (rec.opcode == kFooter || rec.opcode == kDataEnd) {
        if (rec.opcode == kDataEnd) check_data_crc(bytes, rec);
        at = rec.end();
        break;
      }
      if (rec.opcode == kChunk) {
        try {
          Fields f(rec.content, where("Chunk", rec.offset));
          read_chunk(f, rec.offset);
        } catch (const InputError& e) {
          pending.active = true;
          pending.reason = e.what();
          pending.chunk = true;
        }
      } else {
        handle_or_skip(rec);
      }
      at = rec.end();
    }
    settle(pending);
    r_.report_.valid_end_bytes = at;
  }

  // A data-section record outside chunks; one whose fields or CRC are wrong is left out.
  void handle_or_skip(const RawRecord& rec) {
    try {
      handle(rec);
    } catch (const InputError& e) {
      skip_record(e.what());
    }
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
        keep(parse_schema(f));
        break;
      case kChannel:
        keep(parse_channel(f));
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

  static Schema parse_schema(Fields& f) {
    Schema s;
    s.id = f.u16();
    s.name = f.string();
    s.encoding = f.string();
    const Bytes data = f.take(f.u32());
    s.data.assign(data.begin(), data.end());
    return s;
  }

  static Channel parse_channel(Fields& f) {
    Channel c;
    c.id = f.u16();
    c.schema_id = f.u16();
    c.topic = f.string();
    c.message_encoding = f.string();
    c.metadata = f.key_values();
    return c;
  }

  void keep(Schema s) {
    if (schema_ids_.insert(s.id).second) r_.schemas_.push_back(std::move(s));
  }

  void keep(Channel c) {
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
    read_chunk_records(records, offset);
    ++r_.report_.chunk_count;
  }

  // All of a chunk's records or none: a damaged one leaves nothing of its chunk behind.
  void read_chunk_records(Bytes records, std::uint64_t offset) {
    const std::size_t messages_before = r_.messages_.size();
    std::vector<Schema> schemas;
    std::vector<Channel> channels;
    try {
      RawRecord rec;
      for (std::uint64_t at = 0; at < records.size(); at = rec.end()) {
        if (!record_at(records, at, rec)) {
          throw InputError(where("Chunk", offset) + ": record at chunk offset " +
                           std::to_string(at) + " runs past the chunk");
        }
        Fields g(rec.content, where("Chunk", offset) + ", chunk offset " + std::to_string(at));
        switch (rec.opcode) {
          case kSchema:
            schemas.push_back(parse_schema(g));
            break;
          case kChannel:
            channels.push_back(parse_channel(g));
            break;
          case kMessage:
            add_message(g);
            break;
          default:
            break;
        }
      }
    } catch (const InputError&) {
      r_.messages_.resize(messages_before);
      throw;
    }
    for (Schema& s : schemas) keep(std::move(s));
    for (Channel& c : channels) keep(std::move(c));
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
