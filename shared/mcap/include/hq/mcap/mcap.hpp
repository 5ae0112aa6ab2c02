#pragma once
/// MCAP (https://mcap.dev/spec, major version 0) written from the specification: a chunked,
/// indexed writer for flight records and a reader that also recovers files without a summary
/// (a writer killed mid-flight). Little-endian records, CRC-32 (IEEE) on chunks, attachments,
/// the data section and the summary; chunk compression zstd or none.

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace hq::mcap {

/// Key-value maps of Channel and Metadata records (ordered, as the file stores them).
using KeyValues = std::map<std::string, std::string>;
using Bytes = std::span<const std::uint8_t>;

enum class Compression { kNone, kZstd };

struct WriterOptions {
  std::string profile;                        ///< Header profile, e.g. "" or "ros2"
  std::uint64_t chunk_size_bytes = 1u << 20;  ///< a chunk is closed once its records reach this
  Compression compression = Compression::kZstd;
  int zstd_level = 1;  ///< 1 is fast enough for a 1 kHz recorder thread
  /// write() closes the chunk once its first message is older than this (steady clock), so a
  /// writer killed with SIGKILL loses about this much (plus one message period); chunks reach
  /// the kernel with write(2). The check runs on write(): when messages stop, call flush().
  std::int64_t chunk_time_limit_ns = 1'000'000'000;
};

/// Counts as in the Statistics record; times are log times, 0 when there are no messages.
struct Statistics {
  std::uint64_t message_count = 0;
  std::uint16_t schema_count = 0;
  std::uint32_t channel_count = 0;
  std::uint32_t attachment_count = 0;
  std::uint32_t metadata_count = 0;
  std::uint32_t chunk_count = 0;
  std::uint64_t message_start_time_ns = 0;
  std::uint64_t message_end_time_ns = 0;
  std::map<std::uint16_t, std::uint64_t> channel_message_counts;
};

/// Writes one MCAP file. Not thread-safe: the recorder owns it on its own thread. Every write is
/// checked; failures throw hq::InputError naming the path and errno text
/// ("flight.mcap: write failed: No space left on device"), after which the writer is closed.
class McapWriter {
 public:
  McapWriter();
  /// Closes the file (summary and footer) if still open; errors are swallowed here, so call
  /// close() to see them.
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  /// Creates (truncates) path and writes the magic and Header record.
  void open(const std::string& path, const WriterOptions& options = {});
  [[nodiscard]] bool is_open() const;

  /// Returns the schema id (1, 2, ...; 0 means "no schema" for add_channel).
  std::uint16_t add_schema(const std::string& name, const std::string& encoding, Bytes data);
  /// Returns the channel id (0, 1, ...). schema_id is 0 or an id from add_schema.
  std::uint16_t add_channel(std::uint16_t schema_id, const std::string& topic,
                            const std::string& message_encoding, const KeyValues& metadata = {});
  /// Appends a Message record to the open chunk; flushes the chunk when full or too old.
  /// Allocates only by amortised growth of reused buffers.
  void write(std::uint16_t channel_id, std::uint32_t sequence, std::int64_t log_time_ns,
             std::int64_t publish_time_ns, Bytes data);
  /// Attachment record (outside chunks, as the specification requires).
  void add_attachment(const std::string& name, const std::string& media_type, Bytes data,
                      std::int64_t log_time_ns, std::int64_t create_time_ns = 0);
  void add_metadata(const std::string& name, const KeyValues& values);
  /// Closes the open chunk now (e.g. from an idle recorder thread) so it is on disk.
  void flush();
  /// Flushes, writes DataEnd, the summary section, SummaryOffset records, Footer and magic.
  void close();

  /// What has reached the file so far (the Statistics record close() writes): messages count
  /// once their chunk is written, so after a failed write they are what the file holds, not
  /// what write() was handed.
  [[nodiscard]] const Statistics& statistics() const;
  /// Bytes written to the file so far (those of a failed write that did reach it included).
  [[nodiscard]] std::uint64_t bytes_written() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct Schema {
  std::uint16_t id = 0;
  std::string name;
  std::string encoding;
  std::vector<std::uint8_t> data;
};

struct Channel {
  std::uint16_t id = 0;
  std::uint16_t schema_id = 0;
  std::string topic;
  std::string message_encoding;
  KeyValues metadata;
};

struct Message {
  std::uint16_t channel_id = 0;
  std::uint32_t sequence = 0;
  std::int64_t log_time_ns = 0;
  std::int64_t publish_time_ns = 0;
  std::vector<std::uint8_t> data;
};

struct Attachment {
  std::int64_t log_time_ns = 0;
  std::int64_t create_time_ns = 0;
  std::string name;
  std::string media_type;
  std::vector<std::uint8_t> data;
};

struct Metadata {
  std::string name;
  KeyValues values;
};

/// How the reader got its content, and what it had to leave out.
struct ReadReport {
  bool has_summary = false;  ///< footer and summary present and used (seeking by index)
  bool truncated = false;    ///< the file ends inside a record (scan stopped cleanly there)
  std::uint64_t file_size_bytes = 0;
  std::uint64_t valid_end_bytes = 0;  ///< offset just after the last complete record read
  std::uint64_t chunk_count = 0;      ///< chunks read
  std::uint64_t messages_recovered = 0;
  std::uint64_t chunks_dropped = 0;  ///< damaged chunks skipped (CRC, zstd data, record length)
  /// Messages of the dropped chunks, as their MessageIndex records list them.
  std::uint64_t messages_dropped = 0;
  /// Dropped chunks whose MessageIndex records were unreadable too: messages_dropped is then a
  /// lower bound.
  std::uint64_t chunks_dropped_uncounted = 0;
  std::uint64_t records_skipped = 0;  ///< other damaged records (attachment CRC, bad fields)
  std::uint64_t bytes_skipped = 0;    ///< stepped over after a damaged record header
  /// One line per damage, naming the file and the byte offset ("flight.mcap: Chunk at offset
  /// 4711: uncompressed CRC ...; chunk skipped, 250 messages lost").
  std::vector<std::string> warnings;
  [[nodiscard]] bool damaged() const { return !warnings.empty(); }
};

/// Reads a whole MCAP file. With a valid footer and summary the messages are found through the
/// chunk indexes; without one (a killed writer), or with a damaged one, the data section is
/// scanned from the start and the scan stops cleanly at a truncated tail. Damage costs only what
/// it touches: a chunk whose CRC, compressed data or inner record lengths are wrong is skipped
/// and its messages counted as dropped; a damaged record header is stepped over to the next
/// intact record; each is one line in report().warnings. Only a file that cannot be opened or
/// is not MCAP throws hq::InputError.
class McapReader {
 public:
  explicit McapReader(const std::string& path);

  [[nodiscard]] const std::string& profile() const { return profile_; }
  [[nodiscard]] const std::string& library() const { return library_; }
  [[nodiscard]] const std::vector<Schema>& schemas() const { return schemas_; }
  [[nodiscard]] const std::vector<Channel>& channels() const { return channels_; }
  [[nodiscard]] const Channel* channel(std::uint16_t id) const;
  [[nodiscard]] const Schema* schema(std::uint16_t id) const;
  /// Messages in log-time order (stable: equal stamps keep file order, so each channel's
  /// messages are in log-time order).
  [[nodiscard]] const std::vector<Message>& messages() const { return messages_; }
  [[nodiscard]] const std::vector<Attachment>& attachments() const { return attachments_; }
  [[nodiscard]] const std::vector<Metadata>& metadata() const { return metadata_; }
  /// The file's Statistics record when it has a summary, else counted from what was recovered.
  [[nodiscard]] const Statistics& statistics() const { return statistics_; }
  [[nodiscard]] const ReadReport& report() const { return report_; }

 private:
  std::string profile_;
  std::string library_;
  std::vector<Schema> schemas_;
  std::vector<Channel> channels_;
  std::vector<Message> messages_;
  std::vector<Attachment> attachments_;
  std::vector<Metadata> metadata_;
  Statistics statistics_;
  ReadReport report_;
  friend class ReaderImpl;
};

/// What recover() read and wrote.
struct RecoveryReport {
  ReadReport read;                  ///< how the input was read (summary or scan, truncated)
  std::uint64_t bytes_dropped = 0;  ///< input bytes after the last complete record (a cut tail)
  std::uint64_t messages_without_channel = 0;  ///< read but not written: no Channel record
  std::int64_t first_log_time_ns = 0;          ///< of the messages written; 0 without messages
  std::int64_t last_log_time_ns = 0;
  Statistics written;  ///< the output's Statistics record
  std::uint64_t bytes_written = 0;
};

/// Rewrites `in_path`, typically a file whose writer was killed (no summary, maybe a cut tail) or
/// a damaged one (read.warnings says what was dropped), into `out_path` as a complete, indexed
/// file: every schema, channel, message (its sequence and stamps kept), attachment and metadata
/// record McapReader recovered, with a summary.
/// Channel and schema ids are renumbered in file order. @throws hq::InputError if the input is
/// unreadable (as McapReader), `out_path` exists (never overwritten) or a write fails.
RecoveryReport recover(const std::string& in_path, const std::string& out_path,
                       const WriterOptions& options = {});

/// CRC-32 (IEEE 802.3, reflected, as zlib): crc32_update(0, ...) starts, chaining continues.
std::uint32_t crc32_update(std::uint32_t crc, Bytes data);

}  // namespace hq::mcap
