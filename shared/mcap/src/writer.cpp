#include "hq/base/error.hpp"
#include "hq/mcap/mcap.hpp"

#include "format.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fcntl.h>
#include <unistd.h>
#include <utility>
#include <zstd.h>

namespace hq::mcap {

using namespace format;  // NOLINT(google-build-using-namespace): record vocabulary, file-local

namespace {

constexpr const char* kLibrary = "hq-mcap 0.1";

struct ChunkIndexEntry {
  std::uint64_t message_start_time = 0;
  std::uint64_t message_end_time = 0;
  std::uint64_t chunk_start_offset = 0;
  std::uint64_t chunk_length = 0;
  std::vector<std::pair<std::uint16_t, std::uint64_t>> message_index_offsets;
  std::uint64_t message_index_length = 0;
  std::uint64_t compressed_size = 0;
  std::uint64_t uncompressed_size = 0;
  bool compressed = false;  // zstd, else stored
};

struct AttachmentIndexEntry {
  std::uint64_t offset = 0;
  std::uint64_t length = 0;
  std::uint64_t log_time = 0;
  std::uint64_t create_time = 0;
  std::uint64_t data_size = 0;
  std::string name;
  std::string media_type;
};

struct MetadataIndexEntry {
  std::uint64_t offset = 0;
  std::uint64_t length = 0;
  std::string name;
};

void put_key_values(std::vector<std::uint8_t>& out, const KeyValues& values) {
  const std::size_t at = out.size();
  put_u32(out, 0);
  for (const auto& [key, value] : values) {
    put_string(out, key);
    put_string(out, value);
  }
  patch_u32(out, at, static_cast<std::uint32_t>(out.size() - at - 4));
}

void put_schema(std::vector<std::uint8_t>& out, const Schema& s) {
  const std::size_t at = begin_record(out, kSchema);
  put_u16(out, s.id);
  put_string(out, s.name);
  put_string(out, s.encoding);
  put_u32(out, static_cast<std::uint32_t>(s.data.size()));
  put_raw(out, s.data.data(), s.data.size());
  end_record(out, at);
}

void put_channel(std::vector<std::uint8_t>& out, const Channel& c) {
  const std::size_t at = begin_record(out, kChannel);
  put_u16(out, c.id);
  put_u16(out, c.schema_id);
  put_string(out, c.topic);
  put_string(out, c.message_encoding);
  put_key_values(out, c.metadata);
  end_record(out, at);
}

}  // namespace

struct McapWriter::Impl {
  std::string path;
  WriterOptions options;
  int fd = -1;
  std::uint64_t position = 0;
  bool in_data_section = true;
  std::uint32_t data_crc = 0;     // running CRC of every byte before DataEnd (magic included)
  std::uint32_t summary_crc = 0;  // running CRC from the summary start (through the footer)

  std::vector<std::uint8_t> record;      // scratch for records written outside chunks
  std::vector<std::uint8_t> chunk;       // the open chunk's uncompressed records
  std::vector<std::uint8_t> compressed;  // its compressed form
  std::vector<std::vector<std::pair<std::uint64_t, std::uint64_t>>> message_index;  // by channel
  std::vector<std::uint16_t> chunk_channels;  // channels with messages in the open chunk
  std::uint64_t chunk_start_time = 0;
  std::uint64_t chunk_end_time = 0;
  std::chrono::steady_clock::time_point chunk_opened;
  ZSTD_CCtx* zstd = nullptr;

  std::vector<Schema> schemas;
  std::vector<Channel> channels;
  std::vector<ChunkIndexEntry> chunk_indexes;
  std::vector<AttachmentIndexEntry> attachment_indexes;
  std::vector<MetadataIndexEntry> metadata_indexes;
  std::vector<std::uint64_t> channel_counts;  // by channel id: no map lookup per message
  Statistics stats;

  void sync_channel_counts() {
    for (std::size_t id = 0; id < channel_counts.size(); ++id) {
      stats.channel_message_counts[static_cast<std::uint16_t>(id)] = channel_counts[id];
    }
  }

  ~Impl() {
    if (zstd != nullptr) ZSTD_freeCCtx(zstd);
    if (fd >= 0) ::close(fd);
  }

  [[noreturn]] void fail(const std::string& what, int error) {
    if (fd >= 0) ::close(fd);
    fd = -1;
    throw InputError(path + ": " + what + ": " + std::strerror(error));
  }

  void require_open(const char* call) const {
    if (fd < 0) throw InputError(path + ": " + call + " on a writer that is not open");
  }

  // write(2), not stdio: a chunk is in the kernel once flushed, so a SIGKILL cannot lose it.
  void write_all(const std::uint8_t* data, std::size_t size) {
    if (in_data_section) {
      data_crc = crc32_update(data_crc, Bytes(data, size));
    } else {
      summary_crc = crc32_update(summary_crc, Bytes(data, size));
    }
    std::size_t done = 0;
    while (done < size) {
      const ssize_t n = ::write(fd, data + done, size - done);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) fail("write failed", errno);
      if (n == 0) fail("write failed", ENOSPC);
      done += static_cast<std::size_t>(n);
      position += static_cast<std::size_t>(n);  // a failure later leaves these in the file
    }
  }

  // The open chunk's messages are in the file: only now do they count (a full disk must not
  // report what it refused).
  void count_chunk_messages() {
    std::uint64_t messages = 0;
    for (const std::uint16_t id : chunk_channels) {
      channel_counts[id] += message_index[id].size();
      messages += message_index[id].size();
    }
    if (stats.message_count == 0) {
      stats.message_start_time_ns = chunk_start_time;
      stats.message_end_time_ns = chunk_end_time;
    }
    stats.message_start_time_ns = std::min(stats.message_start_time_ns, chunk_start_time);
    stats.message_end_time_ns = std::max(stats.message_end_time_ns, chunk_end_time);
    stats.message_count += messages;
    ++stats.chunk_count;
  }
  void write_all(const std::vector<std::uint8_t>& bytes) { write_all(bytes.data(), bytes.size()); }

  void flush_chunk() {
    if (chunk.empty()) return;
    const std::uint32_t uncompressed_crc = crc32_update(0, Bytes(chunk));
    const std::uint8_t* payload = chunk.data();
    std::size_t payload_size = chunk.size();
    std::string compression;
    if (options.compression == Compression::kZstd) {
      const std::size_t bound = ZSTD_compressBound(chunk.size());
      if (compressed.size() < bound) compressed.resize(bound);
      const std::size_t n = ZSTD_compressCCtx(zstd, compressed.data(), compressed.size(),
                                              chunk.data(), chunk.size(), options.zstd_level);
      if (ZSTD_isError(n) != 0) {
        throw InputError(path + ": zstd compression failed: " + ZSTD_getErrorName(n));
      }
      // A chunk zstd cannot shrink (JPEG frames) is stored as it is: the specification names
      // the compression per chunk, and readers then skip a useless decompression.
      if (n < chunk.size()) {
        payload = compressed.data();
        payload_size = n;
        compression = "zstd";
      }
    }

    ChunkIndexEntry index;
    index.message_start_time = chunk_start_time;
    index.message_end_time = chunk_end_time;
    index.chunk_start_offset = position;
    index.compressed_size = payload_size;
    index.uncompressed_size = chunk.size();
    index.compressed = !compression.empty();

    record.clear();
    put_u8(record, kChunk);
    put_u64(record, 8 + 8 + 8 + 4 + 4 + compression.size() + 8 + payload_size);
    put_u64(record, chunk_start_time);
    put_u64(record, chunk_end_time);
    put_u64(record, chunk.size());
    put_u32(record, uncompressed_crc);
    put_string(record, compression);
    put_u64(record, payload_size);
    write_all(record);
    write_all(payload, payload_size);
    index.chunk_length = position - index.chunk_start_offset;
    count_chunk_messages();

    // One MessageIndex per channel, after the chunk, entries in log-time order.
    std::sort(chunk_channels.begin(), chunk_channels.end());
    record.clear();
    for (const std::uint16_t id : chunk_channels) {
      auto& entries = message_index[id];
      if (!std::is_sorted(entries.begin(), entries.end(),
                          [](const auto& a, const auto& b) { return a.first < b.first; })) {
        std::stable_sort(entries.begin(), entries.end(),
                         [](const auto& a, const auto& b) { return a.first < b.first; });
      }
      index.message_index_offsets.emplace_back(id, position + record.size());
      const std::size_t at = begin_record(record, kMessageIndex);
      put_u16(record, id);
      put_u32(record, static_cast<std::uint32_t>(entries.size() * 16));
      for (const auto& [time, offset] : entries) {
        put_u64(record, time);
        put_u64(record, offset);
      }
      end_record(record, at);
      entries.clear();
    }
    index.message_index_length = record.size();
    write_all(record);

    chunk_indexes.push_back(std::move(index));
    chunk.clear();
    chunk_channels.clear();
  }

  void put_statistics() {
    const std::size_t at = begin_record(record, kStatistics);
    put_u64(record, stats.message_count);
    put_u16(record, stats.schema_count);
    put_u32(record, stats.channel_count);
    put_u32(record, stats.attachment_count);
    put_u32(record, stats.metadata_count);
    put_u32(record, stats.chunk_count);
    put_u64(record, stats.message_start_time_ns);
    put_u64(record, stats.message_end_time_ns);
    put_u32(record, static_cast<std::uint32_t>(stats.channel_message_counts.size() * 10));
    for (const auto& [id, count] : stats.channel_message_counts) {
      put_u16(record, id);
      put_u64(record, count);
    }
    end_record(record, at);
  }

  void put_chunk_indexes() {
    for (const ChunkIndexEntry& c : chunk_indexes) {
      const std::size_t at = begin_record(record, kChunkIndex);
      put_u64(record, c.message_start_time);
      put_u64(record, c.message_end_time);
      put_u64(record, c.chunk_start_offset);
      put_u64(record, c.chunk_length);
      put_u32(record, static_cast<std::uint32_t>(c.message_index_offsets.size() * 10));
      for (const auto& [id, offset] : c.message_index_offsets) {
        put_u16(record, id);
        put_u64(record, offset);
      }
      put_u64(record, c.message_index_length);
      put_string(record, c.compressed ? "zstd" : "");
      put_u64(record, c.compressed_size);
      put_u64(record, c.uncompressed_size);
      end_record(record, at);
    }
  }

  void put_attachment_indexes() {
    for (const AttachmentIndexEntry& a : attachment_indexes) {
      const std::size_t at = begin_record(record, kAttachmentIndex);
      put_u64(record, a.offset);
      put_u64(record, a.length);
      put_u64(record, a.log_time);
      put_u64(record, a.create_time);
      put_u64(record, a.data_size);
      put_string(record, a.name);
      put_string(record, a.media_type);
      end_record(record, at);
    }
  }

  void put_metadata_indexes() {
    for (const MetadataIndexEntry& m : metadata_indexes) {
      const std::size_t at = begin_record(record, kMetadataIndex);
      put_u64(record, m.offset);
      put_u64(record, m.length);
      put_string(record, m.name);
      end_record(record, at);
    }
  }

  using SummaryGroups = std::vector<std::pair<Opcode, std::pair<std::uint64_t, std::uint64_t>>>;

  // The summary section, one group of records per opcode; returns where each group lies.
  SummaryGroups write_summary() {
    SummaryGroups groups;
    auto group = [&](Opcode opcode, auto&& fill) {
      record.clear();
      fill();
      if (record.empty()) return;
      groups.push_back({opcode, {position, record.size()}});
      write_all(record);
    };
    group(kSchema, [&] {
      for (const Schema& s : schemas) put_schema(record, s);
    });
    group(kChannel, [&] {
      for (const Channel& c : channels) put_channel(record, c);
    });
    group(kStatistics, [&] { put_statistics(); });
    group(kChunkIndex, [&] { put_chunk_indexes(); });
    group(kAttachmentIndex, [&] { put_attachment_indexes(); });
    group(kMetadataIndex, [&] { put_metadata_indexes(); });
    return groups;
  }

  void write_summary_and_footer() {
    flush_chunk();
    sync_channel_counts();
    record.clear();
    const std::size_t data_end_at = begin_record(record, kDataEnd);
    put_u32(record, data_crc);
    end_record(record, data_end_at);
    write_all(record);
    in_data_section = false;

    const std::uint64_t summary_start = position;
    const SummaryGroups groups = write_summary();
    const std::uint64_t summary_offset_start = position;
    record.clear();
    for (const auto& [opcode, extent] : groups) {
      const std::size_t at = begin_record(record, kSummaryOffset);
      put_u8(record, opcode);
      put_u64(record, extent.first);
      put_u64(record, extent.second);
      end_record(record, at);
    }
    write_all(record);

    // The summary CRC covers the summary and summary-offset sections and the footer up to
    // (not including) the CRC field itself.
    record.clear();
    put_u8(record, kFooter);
    put_u64(record, kFooterContentBytes);
    put_u64(record, summary_start);
    put_u64(record, summary_offset_start);
    write_all(record);
    record.clear();
    put_u32(record, summary_crc);
    put_raw(record, kMagic.data(), kMagic.size());
    write_all(record);
  }
};

McapWriter::McapWriter() : impl_(std::make_unique<Impl>()) {}

McapWriter::~McapWriter() {
  if (is_open()) {
    try {
      close();
    } catch (const std::exception&) {  // NOLINT(bugprone-empty-catch): see the header
    }
  }
}

void McapWriter::open(const std::string& path, const WriterOptions& options) {
  if (is_open()) close();
  impl_ = std::make_unique<Impl>();
  Impl& w = *impl_;
  w.path = path;
  w.options = options;
  if (options.chunk_size_bytes == 0)
    throw InputError(path + ": chunk_size_bytes = 0, expected > 0");
  if (options.compression == Compression::kZstd) {
    w.zstd = ZSTD_createCCtx();
    if (w.zstd == nullptr) throw InputError(path + ": ZSTD_createCCtx failed");
  }
  w.fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (w.fd < 0) throw InputError(path + ": cannot open for writing: " + std::strerror(errno));
  w.chunk.reserve(options.chunk_size_bytes + options.chunk_size_bytes / 8);
  w.record.clear();
  put_raw(w.record, kMagic.data(), kMagic.size());
  const std::size_t at = begin_record(w.record, kHeader);
  put_string(w.record, options.profile);
  put_string(w.record, kLibrary);
  end_record(w.record, at);
  w.write_all(w.record);
}

bool McapWriter::is_open() const { return impl_->fd >= 0; }

std::uint16_t McapWriter::add_schema(const std::string& name, const std::string& encoding,
                                     Bytes data) {
  Impl& w = *impl_;
  w.require_open("add_schema");
  if (w.schemas.size() >= 0xFFFF) throw InputError(w.path + ": more than 65535 schemas");
  Schema s;
  s.id = static_cast<std::uint16_t>(w.schemas.size() + 1);
  s.name = name;
  s.encoding = encoding;
  s.data.assign(data.begin(), data.end());
  // Written to the data section at once, before any chunk that uses it, so that a file without
  // its summary still streams.
  w.record.clear();
  put_schema(w.record, s);
  w.write_all(w.record);
  w.schemas.push_back(std::move(s));
  ++w.stats.schema_count;
  return w.schemas.back().id;
}

std::uint16_t McapWriter::add_channel(std::uint16_t schema_id, const std::string& topic,
                                      const std::string& message_encoding,
                                      const KeyValues& metadata) {
  Impl& w = *impl_;
  w.require_open("add_channel");
  if (schema_id > w.schemas.size()) {
    throw InputError(w.path + ": add_channel(" + topic + "): schema id " +
                     std::to_string(schema_id) + " was not added");
  }
  if (w.channels.size() >= 0xFFFF) throw InputError(w.path + ": more than 65535 channels");
  Channel c;
  c.id = static_cast<std::uint16_t>(w.channels.size());
  c.schema_id = schema_id;
  c.topic = topic;
  c.message_encoding = message_encoding;
  c.metadata = metadata;
  w.record.clear();
  put_channel(w.record, c);
  w.write_all(w.record);
  w.channels.push_back(std::move(c));
  w.message_index.emplace_back();
  ++w.stats.channel_count;
  w.channel_counts.push_back(0);
  return w.channels.back().id;
}

void McapWriter::write(std::uint16_t channel_id, std::uint32_t sequence, std::int64_t log_time_ns,
                       std::int64_t publish_time_ns, Bytes data) {
  Impl& w = *impl_;
  w.require_open("write");
  if (channel_id >= w.channels.size()) {
    throw InputError(w.path + ": write: channel id " + std::to_string(channel_id) +
                     " was not added");
  }
  const auto log_time = static_cast<std::uint64_t>(log_time_ns);
  if (w.chunk.empty()) {
    w.chunk_start_time = log_time;
    w.chunk_end_time = log_time;
    w.chunk_opened = std::chrono::steady_clock::now();
  }
  w.chunk_start_time = std::min(w.chunk_start_time, log_time);
  w.chunk_end_time = std::max(w.chunk_end_time, log_time);

  auto& entries = w.message_index[channel_id];
  if (entries.empty()) w.chunk_channels.push_back(channel_id);
  entries.emplace_back(log_time, w.chunk.size());

  std::vector<std::uint8_t>& out = w.chunk;
  put_u8(out, kMessage);
  put_u64(out, 2 + 4 + 8 + 8 + data.size());
  put_u16(out, channel_id);
  put_u32(out, sequence);
  put_u64(out, log_time);
  put_u64(out, static_cast<std::uint64_t>(publish_time_ns));
  put_raw(out, data.data(), data.size());

  if (w.chunk.size() >= w.options.chunk_size_bytes ||
      std::chrono::steady_clock::now() - w.chunk_opened >=
          std::chrono::nanoseconds(w.options.chunk_time_limit_ns)) {
    w.flush_chunk();
  }
}

void McapWriter::add_attachment(const std::string& name, const std::string& media_type, Bytes data,
                                std::int64_t log_time_ns, std::int64_t create_time_ns) {
  Impl& w = *impl_;
  w.require_open("add_attachment");
  AttachmentIndexEntry index;
  index.offset = w.position;
  index.log_time = static_cast<std::uint64_t>(log_time_ns);
  index.create_time = static_cast<std::uint64_t>(create_time_ns);
  index.data_size = data.size();
  index.name = name;
  index.media_type = media_type;
  w.record.clear();
  const std::size_t at = begin_record(w.record, kAttachment);
  put_u64(w.record, index.log_time);
  put_u64(w.record, index.create_time);
  put_string(w.record, name);
  put_string(w.record, media_type);
  put_u64(w.record, data.size());
  put_raw(w.record, data.data(), data.size());
  // The CRC covers the fields before it: log_time through data.
  const std::uint32_t crc = crc32_update(0, Bytes(w.record).subspan(at + 8));
  put_u32(w.record, crc);
  end_record(w.record, at);
  w.write_all(w.record);
  index.length = w.record.size();
  w.attachment_indexes.push_back(std::move(index));
  ++w.stats.attachment_count;
}

void McapWriter::add_metadata(const std::string& name, const KeyValues& values) {
  Impl& w = *impl_;
  w.require_open("add_metadata");
  MetadataIndexEntry index;
  index.offset = w.position;
  index.name = name;
  w.record.clear();
  const std::size_t at = begin_record(w.record, kMetadata);
  put_string(w.record, name);
  put_key_values(w.record, values);
  end_record(w.record, at);
  w.write_all(w.record);
  index.length = w.record.size();
  w.metadata_indexes.push_back(std::move(index));
  ++w.stats.metadata_count;
}

void McapWriter::flush() {
  impl_->require_open("flush");
  impl_->flush_chunk();
}

void McapWriter::close() {
  Impl& w = *impl_;
  w.require_open("close");
  w.write_summary_and_footer();
  const int fd = std::exchange(w.fd, -1);
  if (::close(fd) != 0) {
    throw InputError(w.path + ": close failed: " + std::strerror(errno));
  }
}

const Statistics& McapWriter::statistics() const {
  impl_->sync_channel_counts();
  return impl_->stats;
}

std::uint64_t McapWriter::bytes_written() const { return impl_->position; }

}  // namespace hq::mcap
