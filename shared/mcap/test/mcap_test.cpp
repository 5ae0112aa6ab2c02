#include "hq/mcap/mcap.hpp"

#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <string>
#include <sys/resource.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace hq::mcap {
namespace {

using ::testing::HasSubstr;
namespace fs = std::filesystem;

class TempDir {
 public:
  TempDir() {
    std::string pattern = "/tmp/hq-mcap-test-XXXXXX";
    path_ = ::mkdtemp(pattern.data());
  }
  ~TempDir() { fs::remove_all(path_); }
  [[nodiscard]] std::string file(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

std::vector<std::uint8_t> payload(std::size_t size, std::uint32_t seed) {
  std::vector<std::uint8_t> out(size);
  for (std::size_t i = 0; i < size; ++i) {
    out[i] =
        static_cast<std::uint8_t>((std::size_t{seed * 2654435761u} + i * std::size_t{40503}) >> 13);
  }
  return out;
}

std::vector<std::uint8_t> read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_file(const std::string& path, const std::vector<std::uint8_t>& bytes, std::size_t n) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(n));
}

Bytes as_bytes(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// A recording as the ground station would write it: three channels at different rates and
// sizes, two attachments and two metadata records, messages in log-time order.
struct Recording {
  std::vector<Message> messages;
  Statistics statistics;
};

Recording write_recording(const std::string& path, Compression compression,
                          std::uint64_t chunk_size_bytes = 16 * 1024ULL) {
  McapWriter writer;
  WriterOptions options;
  options.profile = "hq";
  options.compression = compression;
  options.chunk_size_bytes = chunk_size_bytes;
  writer.open(path, options);
  const std::uint16_t state_schema =
      writer.add_schema("hq.State", "omgidl", as_bytes("struct State {};"));
  const std::uint16_t image_schema =
      writer.add_schema("hq.Image", "omgidl", as_bytes("struct Image {};"));
  const std::uint16_t state = writer.add_channel(state_schema, "/state", "cdr", {{"frame", "H"}});
  const std::uint16_t image = writer.add_channel(image_schema, "/camera/jpeg", "cdr");
  const std::uint16_t events = writer.add_channel(0, "/events", "json", {{"a", "1"}, {"b", "2"}});
  writer.add_metadata("flight", {{"vehicle", "hq-1"}, {"operator", "test"}});
  Recording r;
  std::array<std::uint32_t, 3> sequence = {0, 0, 0};
  for (int i = 0; i < 1000; ++i) {
    const std::int64_t t_ns = 1'000'000'000LL + i * 5'000'000LL;
    auto add = [&](std::uint16_t channel, std::size_t size) {
      Message m{channel, sequence[channel]++, t_ns, t_ns - 1000,
                payload(size, static_cast<std::uint32_t>(i * 3 + channel))};
      writer.write(m.channel_id, m.sequence, m.log_time_ns, m.publish_time_ns, m.data);
      r.messages.push_back(std::move(m));
    };
    add(state, 300);
    if (i % 20 == 0) add(image, 3000 + static_cast<std::size_t>(i));
    if (i % 250 == 0) add(events, 0);
  }
  writer.add_attachment("calib.yaml", "application/yaml", as_bytes("K: [1, 2, 3]"), 1'000'000'000);
  writer.add_attachment("empty", "application/octet-stream", {}, 2'000'000'000, 7);
  writer.add_metadata("end", {});
  writer.close();
  r.statistics = writer.statistics();
  return r;
}

void expect_same_messages(const std::vector<Message>& got, const std::vector<Message>& want,
                          std::size_t count) {
  ASSERT_LE(count, want.size());
  ASSERT_EQ(got.size(), count);
  for (std::size_t i = 0; i < count; ++i) {
    EXPECT_EQ(got[i].channel_id, want[i].channel_id) << i;
    EXPECT_EQ(got[i].sequence, want[i].sequence) << i;
    EXPECT_EQ(got[i].log_time_ns, want[i].log_time_ns) << i;
    EXPECT_EQ(got[i].publish_time_ns, want[i].publish_time_ns) << i;
    EXPECT_EQ(got[i].data, want[i].data) << i;
  }
}

class RoundTrip : public ::testing::TestWithParam<Compression> {};

TEST_P(RoundTrip, SchemasChannelsMessagesAttachmentsMetadataAndStatisticsSurvive) {
  const TempDir dir;
  const std::string path = dir.file("flight.mcap");
  const Recording written = write_recording(path, GetParam());

  const McapReader reader(path);
  EXPECT_TRUE(reader.report().has_summary);
  EXPECT_FALSE(reader.report().truncated);
  EXPECT_EQ(reader.profile(), "hq");
  ASSERT_EQ(reader.schemas().size(), 2u);
  EXPECT_EQ(reader.schemas()[0].id, 1);
  EXPECT_EQ(reader.schemas()[0].name, "hq.State");
  EXPECT_EQ(reader.schemas()[1].encoding, "omgidl");
  EXPECT_EQ(std::string(reader.schemas()[1].data.begin(), reader.schemas()[1].data.end()),
            "struct Image {};");
  ASSERT_EQ(reader.channels().size(), 3u);
  EXPECT_EQ(reader.channel(0)->topic, "/state");
  EXPECT_EQ(reader.channel(0)->metadata.at("frame"), "H");
  EXPECT_EQ(reader.channel(1)->schema_id, 2);
  EXPECT_EQ(reader.channel(2)->schema_id, 0);
  EXPECT_EQ(reader.channel(2)->metadata.size(), 2u);
  EXPECT_EQ(reader.channel(2)->message_encoding, "json");

  expect_same_messages(reader.messages(), written.messages, written.messages.size());
  EXPECT_GT(reader.report().chunk_count, 10u);

  ASSERT_EQ(reader.attachments().size(), 2u);
  EXPECT_EQ(reader.attachments()[0].name, "calib.yaml");
  EXPECT_EQ(reader.attachments()[0].media_type, "application/yaml");
  EXPECT_EQ(std::string(reader.attachments()[0].data.begin(), reader.attachments()[0].data.end()),
            "K: [1, 2, 3]");
  EXPECT_EQ(reader.attachments()[1].create_time_ns, 7);
  EXPECT_TRUE(reader.attachments()[1].data.empty());
  ASSERT_EQ(reader.metadata().size(), 2u);
  EXPECT_EQ(reader.metadata()[0].values.at("vehicle"), "hq-1");
  EXPECT_TRUE(reader.metadata()[1].values.empty());

  const Statistics& s = reader.statistics();
  EXPECT_EQ(s.message_count, written.messages.size());
  EXPECT_EQ(s.message_count, written.statistics.message_count);
  EXPECT_EQ(s.schema_count, 2);
  EXPECT_EQ(s.channel_count, 3u);
  EXPECT_EQ(s.attachment_count, 2u);
  EXPECT_EQ(s.metadata_count, 2u);
  EXPECT_EQ(s.chunk_count, reader.report().chunk_count);
  EXPECT_EQ(s.message_start_time_ns, 1'000'000'000u);
  EXPECT_EQ(s.message_end_time_ns, 1'000'000'000ULL + 999ULL * 5'000'000ULL);
  EXPECT_EQ(s.channel_message_counts.at(0), 1000u);
  EXPECT_EQ(s.channel_message_counts.at(1), 50u);
  EXPECT_EQ(s.channel_message_counts.at(2), 4u);
}

TEST_P(RoundTrip, FileTruncatedAnywhereRecoversAPrefixOfTheMessages) {
  const TempDir dir;
  const std::string path = dir.file("flight.mcap");
  const Recording written = write_recording(path, GetParam(), 8 * 1024ULL);
  const std::vector<std::uint8_t> bytes = read_file(path);
  const std::string cut_path = dir.file("cut.mcap");
  std::size_t previous = 0;
  const std::size_t step = std::max<std::size_t>(97, bytes.size() / 1500);
  for (std::size_t n = 0; n < bytes.size(); n += step) {
    write_file(cut_path, bytes, n);
    if (n < 8) {
      EXPECT_THAT(testing::input_error_message([&] { McapReader r(cut_path); }),
                  HasSubstr("not an MCAP file"));
      continue;
    }
    const McapReader reader(cut_path);
    EXPECT_FALSE(reader.report().has_summary) << n;
    EXPECT_LE(reader.report().valid_end_bytes, n);
    EXPECT_GE(reader.messages().size(), previous) << n;
    previous = reader.messages().size();
    expect_same_messages(reader.messages(), written.messages, reader.messages().size());
    EXPECT_EQ(reader.report().messages_recovered, reader.messages().size());
    if (HasFailure()) {
      ADD_FAILURE() << "at " << n << " of " << bytes.size() << " bytes";
      return;
    }
  }
  EXPECT_GT(previous, written.messages.size() / 2);
}

INSTANTIATE_TEST_SUITE_P(Compressions, RoundTrip,
                         ::testing::Values(Compression::kZstd, Compression::kNone),
                         [](const auto& param_info) {
                           return param_info.param == Compression::kZstd ? "zstd" : "none";
                         });

TEST(McapReader, FileWithoutSummaryIsScannedWithItsAttachmentsAndMetadata) {
  const TempDir dir;
  const std::string path = dir.file("flight.mcap");
  const Recording written = write_recording(path, Compression::kZstd);
  std::vector<std::uint8_t> bytes = read_file(path);
  // Cut right after the data section: magic and footer gone, as after a crash at close.
  const std::size_t footer_and_magic = 8 + 9 + 20;
  write_file(path, bytes, bytes.size() - footer_and_magic - 1);
  const McapReader reader(path);
  EXPECT_FALSE(reader.report().has_summary);
  expect_same_messages(reader.messages(), written.messages, written.messages.size());
  EXPECT_EQ(reader.attachments().size(), 2u);
  EXPECT_EQ(reader.metadata().size(), 2u);
  EXPECT_EQ(reader.statistics().message_count, written.messages.size());
  EXPECT_EQ(reader.statistics().channel_message_counts.at(1), 50u);
}

TEST(Recover, CutFileBecomesACompleteIndexedFileWithEverythingRecovered) {
  const TempDir dir;
  const std::string path = dir.file("killed.mcap");
  const Recording written = write_recording(path, Compression::kZstd, 8 * 1024ULL);
  const std::vector<std::uint8_t> bytes = read_file(path);
  // GIVEN a file cut in the middle of a record (a writer killed mid-flight),
  write_file(path, bytes, bytes.size() * 3 / 5 + 3);
  const McapReader cut(path);
  ASSERT_TRUE(cut.report().truncated);
  // WHEN recovered, THEN the output has a summary and exactly what the cut file held.
  const RecoveryReport report = recover(path, dir.file("recovered.mcap"));
  EXPECT_FALSE(report.read.has_summary);
  EXPECT_EQ(report.bytes_dropped, cut.report().file_size_bytes - cut.report().valid_end_bytes);
  EXPECT_GT(report.bytes_dropped, 0u);
  EXPECT_EQ(report.messages_without_channel, 0u);
  EXPECT_EQ(report.written.message_count, cut.messages().size());
  EXPECT_EQ(report.written.channel_count, 3u);
  EXPECT_EQ(report.first_log_time_ns, written.messages.front().log_time_ns);
  EXPECT_EQ(report.last_log_time_ns, cut.messages().back().log_time_ns);
  const McapReader recovered(dir.file("recovered.mcap"));
  EXPECT_TRUE(recovered.report().has_summary);
  EXPECT_FALSE(recovered.report().truncated);
  EXPECT_EQ(recovered.profile(), "hq");
  EXPECT_EQ(report.bytes_written, fs::file_size(dir.file("recovered.mcap")));
  expect_same_messages(recovered.messages(), written.messages, cut.messages().size());
  ASSERT_EQ(recovered.channels().size(), 3u);
  EXPECT_EQ(recovered.channels()[0].metadata.at("frame"), "H");
  EXPECT_EQ(recovered.schema(recovered.channels()[1].schema_id)->name, "hq.Image");
  EXPECT_EQ(recovered.metadata().size(), cut.metadata().size());
  // AND an existing output is never overwritten.
  EXPECT_THAT(testing::input_error_message([&] { recover(path, dir.file("recovered.mcap")); }),
              HasSubstr("recovered.mcap: exists"));
}

// The compression field of every top-level Chunk record (opcode 0x06), walking the records.
std::vector<std::string> chunk_compressions(const std::vector<std::uint8_t>& bytes) {
  std::vector<std::string> out;
  auto u64 = [&](std::size_t at) {
    std::uint64_t v = 0;
    for (std::size_t i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(bytes[at + i]) << (8 * i);
    return v;
  };
  for (std::size_t at = 8; at + 9 <= bytes.size(); at += 9 + u64(at + 1)) {
    if (bytes[at] != 0x06) continue;
    const std::size_t field = at + 9 + 8 + 8 + 8 + 4;
    const std::size_t length = bytes[field] | (bytes[field + 1] << 8);
    out.emplace_back(bytes.begin() + static_cast<std::ptrdiff_t>(field + 4),
                     bytes.begin() + static_cast<std::ptrdiff_t>(field + 4 + length));
  }
  return out;
}

TEST(McapWriter, ChunksZstdCannotShrinkAreStoredUncompressed) {
  const TempDir dir;
  const std::string path = dir.file("jpeg.mcap");
  std::vector<std::uint8_t> noise(20'000);
  std::uint64_t x = 88172645463325252ULL;
  std::vector<Message> written;
  {
    McapWriter writer;
    writer.open(path, {.profile = "", .chunk_size_bytes = 50'000});
    const std::uint16_t image = writer.add_channel(0, "/camera/jpeg", "raw");
    const std::uint16_t state = writer.add_channel(0, "/state", "raw");
    for (std::uint32_t i = 0; i < 20; ++i) {
      for (auto& b : noise) {  // xorshift: incompressible, as JPEG
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        b = static_cast<std::uint8_t>(x);
      }
      written.push_back({image, i, 100 * static_cast<std::int64_t>(i), 0, noise});
      writer.write(image, i, 100 * static_cast<std::int64_t>(i), 0, noise);
      if (i == 10) {  // one compressible chunk among the stored ones
        writer.flush();
        for (std::uint32_t k = 0; k < 200; ++k) {
          const std::vector<std::uint8_t> zeros(300, 0);
          written.push_back({state, k, 1000 + static_cast<std::int64_t>(k), 0, zeros});
          writer.write(state, k, 1000 + static_cast<std::int64_t>(k), 0, zeros);
        }
        writer.flush();
      }
    }
    writer.close();
  }
  const McapReader reader(path);
  std::stable_sort(written.begin(), written.end(), [](const Message& a, const Message& b) {
    return a.log_time_ns < b.log_time_ns;
  });
  expect_same_messages(reader.messages(), written, written.size());
  const std::vector<std::string> compressions = chunk_compressions(read_file(path));
  // The 200 compressible messages (66 kB) fill two chunks; the frames fill the rest.
  EXPECT_EQ(std::count(compressions.begin(), compressions.end(), "zstd"), 2);
  EXPECT_GE(std::count(compressions.begin(), compressions.end(), ""), 4);
}

TEST(McapReader, MessagesComeInLogTimeOrder) {
  const TempDir dir;
  const std::string path = dir.file("order.mcap");
  {
    McapWriter writer;
    writer.open(path, {.profile = "", .chunk_size_bytes = 256});
    const std::uint16_t a = writer.add_channel(0, "/a", "raw");
    const std::uint16_t b = writer.add_channel(0, "/b", "raw");
    const std::vector<std::uint8_t> data(40, 1);
    for (std::uint32_t i = 0; i < 50; ++i) {
      writer.write(a, i, 1000 + 10 * static_cast<std::int64_t>(i), 0, data);
      writer.write(b, i, 995 + 10 * static_cast<std::int64_t>(i), 0, data);  // 5 ns earlier
    }
    writer.close();
  }
  const McapReader reader(path);
  ASSERT_EQ(reader.messages().size(), 100u);
  for (std::size_t i = 1; i < reader.messages().size(); ++i) {
    EXPECT_LE(reader.messages()[i - 1].log_time_ns, reader.messages()[i].log_time_ns);
  }
  EXPECT_EQ(reader.messages().front().channel_id, 1);
}

std::uint64_t u64_at(const std::vector<std::uint8_t>& bytes, std::size_t at) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(bytes[at + i]) << (8 * i);
  return v;
}

// Offsets of the top-level Chunk records, walking the records from the magic.
std::vector<std::size_t> chunk_offsets(const std::vector<std::uint8_t>& bytes) {
  std::vector<std::size_t> out;
  for (std::size_t at = 8; at + 9 <= bytes.size(); at += 9 + u64_at(bytes, at + 1)) {
    if (bytes[at] == 0x06) out.push_back(at);
  }
  return out;
}

// Where a chunk's payload starts and how long it is: after opcode, length, start and end
// times, uncompressed size and CRC, the compression string and the payload size.
std::pair<std::size_t, std::size_t> chunk_payload(const std::vector<std::uint8_t>& bytes,
                                                  std::size_t chunk) {
  const std::size_t compression = chunk + 9 + 8 + 8 + 8 + 4;
  const std::size_t size_field =
      compression + 4 + (bytes[compression] | (bytes[compression + 1] << 8));
  return {size_field + 8, u64_at(bytes, size_field)};
}

// Every message read is one that was written, in order: a subsequence.
void expect_subsequence(const std::vector<Message>& got, const std::vector<Message>& want) {
  std::size_t w = 0;
  for (const Message& m : got) {
    while (w < want.size() &&
           !(want[w].channel_id == m.channel_id && want[w].sequence == m.sequence)) {
      ++w;
    }
    ASSERT_LT(w, want.size()) << "read a message never written: channel " << m.channel_id
                              << " sequence " << m.sequence;
    EXPECT_EQ(want[w].data, m.data);
    ++w;
  }
}

// The footer and closing magic cut off: no summary, so the reader scans (as after a crash at
// close, and as --recover reads a killed writer's file).
std::string without_summary(const TempDir& dir, const std::vector<std::uint8_t>& bytes) {
  std::string cut = dir.file("no_summary.mcap");
  write_file(cut, bytes, bytes.size() - (8 + 9 + 20) - 1);
  return cut;
}

// What a reader of a file with exactly one damaged chunk must give: the other chunks' messages,
// the lost ones counted, a warning naming the file and the chunk's offset.
void expect_one_chunk_dropped(const McapReader& reader, const std::string& path, std::size_t chunk,
                              const Recording& written) {
  const ReadReport& report = reader.report();
  EXPECT_EQ(report.chunks_dropped, 1u);
  EXPECT_EQ(report.chunks_dropped_uncounted, 0u);
  EXPECT_GT(report.messages_dropped, 0u);
  EXPECT_EQ(reader.messages().size() + report.messages_dropped, written.messages.size());
  EXPECT_GT(reader.messages().size(), written.messages.size() / 2);
  expect_subsequence(reader.messages(), written.messages);
  EXPECT_TRUE(report.damaged());
  const std::string all = ::testing::PrintToString(report.warnings);
  EXPECT_THAT(all, HasSubstr(path + ": "));
  EXPECT_THAT(all, HasSubstr("offset " + std::to_string(chunk)));
  EXPECT_THAT(all, HasSubstr(std::to_string(report.messages_dropped) + " messages lost"));
}

// GIVEN a valid file of many zstd chunks WHEN one bit flips inside one chunk's compressed data
// THEN the reader, with the summary and by a scan, returns the other chunks' messages and
// counts the dropped chunk and its messages; --recover writes what survived.
TEST(McapReader, OneFlippedBitInCompressedDataCostsOnlyItsChunk) {
  const TempDir dir;
  const std::string path = dir.file("flight.mcap");
  const Recording written = write_recording(path, Compression::kZstd);
  std::vector<std::uint8_t> bytes = read_file(path);
  const std::vector<std::size_t> chunks = chunk_offsets(bytes);
  ASSERT_GT(chunks.size(), 5u);
  const std::size_t chunk = chunks[3];
  const auto [payload_at, payload_size] = chunk_payload(bytes, chunk);
  bytes[payload_at + payload_size / 2] ^= 0x04;
  write_file(path, bytes, bytes.size());

  const McapReader indexed(path);
  EXPECT_TRUE(indexed.report().has_summary);
  expect_one_chunk_dropped(indexed, path, chunk, written);
  EXPECT_THAT(::testing::PrintToString(indexed.report().warnings), HasSubstr("data section CRC"));

  const std::string cut = without_summary(dir, bytes);
  const McapReader scanned(cut);
  EXPECT_FALSE(scanned.report().has_summary);
  expect_one_chunk_dropped(scanned, cut, chunk, written);

  const RecoveryReport recovered = recover(cut, dir.file("recovered.mcap"));
  EXPECT_EQ(recovered.read.chunks_dropped, 1u);
  EXPECT_EQ(recovered.written.message_count, scanned.messages().size());
  EXPECT_EQ(McapReader(dir.file("recovered.mcap")).messages().size(), scanned.messages().size());
}

// GIVEN uncompressed chunks WHEN a bit flips in a message's record length inside one chunk
// (with its CRC, and with the CRC left out as writers may) THEN only that chunk is dropped.
TEST(McapReader, FlippedBitInARecordLengthInsideAChunkCostsOnlyItsChunk) {
  const TempDir dir;
  const std::string path = dir.file("flight.mcap");
  const Recording written = write_recording(path, Compression::kNone);
  std::vector<std::uint8_t> bytes = read_file(path);
  const std::vector<std::size_t> chunks = chunk_offsets(bytes);
  ASSERT_GT(chunks.size(), 5u);
  const std::size_t chunk = chunks[2];
  const std::size_t first_record = chunk_payload(bytes, chunk).first;
  ASSERT_EQ(bytes[first_record], 0x05);  // a Message record
  bytes[first_record + 1 + 5] ^= 0x01;   // bit 40 of its length: far past the chunk's end
  const std::vector<std::uint8_t> with_crc = bytes;
  write_file(path, bytes, bytes.size());
  expect_one_chunk_dropped(McapReader(path), path, chunk, written);

  for (std::size_t i = 0; i < 4; ++i) bytes[chunk + 9 + 8 + 8 + 8 + i] = 0;  // "no CRC"
  write_file(path, bytes, bytes.size());
  const McapReader without_crc(path);
  expect_one_chunk_dropped(without_crc, path, chunk, written);
  EXPECT_THAT(::testing::PrintToString(without_crc.report().warnings),
              HasSubstr("runs past the chunk"));
  expect_one_chunk_dropped(McapReader(without_summary(dir, with_crc)), dir.file("no_summary.mcap"),
                           chunk, written);
}

// GIVEN a file without its summary WHEN a bit flips in a chunk's own record header (its length
// now runs past the end of the file) THEN the scan steps over it to the next intact record and
// reads on, instead of taking the rest for a truncated tail.
TEST(McapReader, FlippedBitInAChunkHeaderIsSteppedOver) {
  const TempDir dir;
  const std::string path = dir.file("flight.mcap");
  const Recording written = write_recording(path, Compression::kZstd);
  std::vector<std::uint8_t> bytes = read_file(path);
  const std::vector<std::size_t> chunks = chunk_offsets(bytes);
  ASSERT_GT(chunks.size(), 5u);
  const std::size_t chunk = chunks[4];
  bytes[chunk + 1 + 6] ^= 0x20;  // bit 53 of the record's length
  write_file(path, bytes, bytes.size());
  expect_one_chunk_dropped(McapReader(path), path, chunk, written);

  const std::string cut = without_summary(dir, bytes);
  const McapReader scanned(cut);
  expect_one_chunk_dropped(scanned, cut, chunk, written);
  EXPECT_FALSE(scanned.report().truncated);
  EXPECT_GT(scanned.report().bytes_skipped, 0u);
  EXPECT_EQ(scanned.attachments().size(), 2u);
}

// GIVEN a damaged summary (its CRC, or a chunk index pointing nowhere) WHEN read THEN the data
// section is scanned instead and everything is there, with a warning saying so.
TEST(McapReader, DamagedSummaryFallsBackToAScan) {
  const TempDir dir;
  const std::string path = dir.file("flight.mcap");
  const Recording written = write_recording(path, Compression::kZstd);
  std::vector<std::uint8_t> bytes = read_file(path);
  bytes[bytes.size() - 8 - 4] ^= 0x01;  // the footer's summary CRC
  write_file(path, bytes, bytes.size());
  const McapReader reader(path);
  EXPECT_FALSE(reader.report().has_summary);
  expect_same_messages(reader.messages(), written.messages, written.messages.size());
  EXPECT_EQ(reader.attachments().size(), 2u);
  EXPECT_EQ(reader.metadata().size(), 2u);
  ASSERT_EQ(reader.report().warnings.size(), 1u);
  EXPECT_THAT(reader.report().warnings[0], HasSubstr(path + ": Footer at offset"));
  EXPECT_THAT(reader.report().warnings[0], HasSubstr("summary CRC"));
  EXPECT_THAT(reader.report().warnings[0], HasSubstr("data section is scanned"));
}

TEST(McapWriter, FullDiskGivesAClearError) {
  McapWriter writer;
  const std::string message = testing::input_error_message([&] {
    writer.open("/dev/full");
    writer.add_channel(0, "/x", "raw");
    writer.close();
  });
  EXPECT_EQ(message, "/dev/full: write failed: No space left on device");
  EXPECT_FALSE(writer.is_open());
}

TEST(McapWriter, MissingFolderGivesAClearError) {
  McapWriter writer;
  EXPECT_EQ(testing::input_error_message([&] { writer.open("/nonexistent-hq/flight.mcap"); }),
            "/nonexistent-hq/flight.mcap: cannot open for writing: No such file or directory");
  EXPECT_THAT(testing::input_error_message([&] { writer.write(0, 0, 0, 0, {}); }),
              HasSubstr("not open"));
}

// Writes 300-byte messages to path under a file size limit of limit_bytes (a disk filling up:
// RLIMIT_FSIZE, SIGXFSZ ignored, else the kernel kills the process) until the writer throws;
// handed counts the messages handed to it. Returns the error's message.
std::string write_until_the_file_limit(const std::string& path, rlim_t limit_bytes,
                                       McapWriter& writer, std::uint32_t& handed) {
  rlimit saved{};
  if (::getrlimit(RLIMIT_FSIZE, &saved) != 0) return "getrlimit failed";
  const auto old_handler = ::signal(SIGXFSZ, SIG_IGN);
  rlimit limited = saved;
  limited.rlim_cur = limit_bytes;
  if (::setrlimit(RLIMIT_FSIZE, &limited) != 0) return "setrlimit failed";
  std::string message = testing::input_error_message([&] {
    writer.open(
        path, {.profile = "", .chunk_size_bytes = 16 * 1024ULL, .compression = Compression::kNone});
    const std::uint16_t channel = writer.add_channel(0, "/state", "raw");
    const std::vector<std::uint8_t> data = payload(300, 9);
    for (; handed < 100'000; ++handed) writer.write(channel, handed, handed, handed, data);
  });
  ::setrlimit(RLIMIT_FSIZE, &saved);
  ::signal(SIGXFSZ, old_handler);
  return message;
}

// GIVEN a recording under way WHEN the file may grow no further (RLIMIT_FSIZE, as a full disk
// mid-flight) THEN the chunk flush fails at once with the path and errno text, the writer is
// closed, and what reached the file before still reads.
TEST(McapWriter, DiskFullMidRecordingFailsClearlyAndKeepsWhatWasWritten) {
  const TempDir dir;
  const std::string path = dir.file("flight.mcap");
  McapWriter writer;
  std::uint32_t written = 0;
  const std::string message = write_until_the_file_limit(path, 200 * 1024ULL, writer, written);
  EXPECT_EQ(message, path + ": write failed: File too large");
  EXPECT_FALSE(writer.is_open());
  EXPECT_LT(written, 1000u);
  const McapReader reader(path);
  EXPECT_GT(reader.messages().size(), 300u);
  EXPECT_LE(reader.messages().size(), written);
}

// GIVEN a recording under way WHEN the disk fills (RLIMIT_FSIZE) THEN the writer's statistics
// count the messages that reached the file, not those it was handed, and the failure is thrown.
TEST(McapWriter, FullDiskCountsWhatReachedTheFileNotWhatWasHanded) {
  const TempDir dir;
  const std::string path = dir.file("flight.mcap");
  McapWriter writer;
  std::uint32_t handed = 0;
  const std::string message = write_until_the_file_limit(path, 100 * 1024ULL, writer, handed);
  EXPECT_EQ(message, path + ": write failed: File too large");
  const McapReader reader(path);
  ASSERT_GT(reader.messages().size(), 100u);
  EXPECT_LT(reader.messages().size(), handed + 1u);  // the failed chunk's messages are not there
  EXPECT_EQ(writer.statistics().message_count, reader.messages().size());
  EXPECT_EQ(writer.statistics().channel_message_counts.at(0), reader.messages().size());
  EXPECT_EQ(writer.statistics().chunk_count, reader.report().chunk_count);
  EXPECT_EQ(writer.bytes_written(), fs::file_size(path));
}

TEST(McapReader, MissingFileAndNonMcapFileGiveClearErrors) {
  const TempDir dir;
  EXPECT_EQ(testing::input_error_message([&] { McapReader r(dir.file("none.mcap")); }),
            dir.file("none.mcap") + ": cannot open: No such file or directory");
  write_file(dir.file("text.mcap"), {'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd'}, 11);
  EXPECT_THAT(testing::input_error_message([&] { McapReader r(dir.file("text.mcap")); }),
              HasSubstr("text.mcap: not an MCAP file"));
}

TEST(McapWriter, AllocatesOnlyPerChunkNotPerMessage) {
  const TempDir dir;
  McapWriter writer;
  writer.open(dir.file("alloc.mcap"),
              {.profile = "", .chunk_size_bytes = 64 * 1024ULL, .compression = Compression::kZstd});
  const std::uint16_t a = writer.add_channel(0, "/a", "raw");
  const std::uint16_t b = writer.add_channel(0, "/b", "raw");
  const std::vector<std::uint8_t> data = payload(100, 3);
  std::uint32_t seq = 0;
  auto burst = [&](int n) {
    for (int i = 0; i < n; ++i, ++seq) {
      writer.write(i % 2 == 0 ? a : b, seq, static_cast<std::int64_t>(seq) * 1000, 0, data);
    }
  };
  burst(5000);  // buffers grow to their working size
  const std::uint32_t chunks_before = writer.statistics().chunk_count;
  const long before = hq::testing::allocation_count();
  burst(20000);
  const long allocations = hq::testing::allocation_count() - before;
  const std::uint32_t chunks = writer.statistics().chunk_count - chunks_before;
  EXPECT_GT(chunks, 10u);
  // Per chunk: its index entry and the per-channel offsets of its message indexes.
  EXPECT_LE(allocations, 4L * chunks);
  writer.close();
}

// The SIGKILL bound rests on this rule: the write that finds the open chunk older than
// chunk_time_limit_ns closes it (and it reaches the file), whatever its size.
TEST(McapWriter, ChunkOlderThanTheTimeLimitIsWrittenOut) {
  const TempDir dir;
  McapWriter writer;
  writer.open(dir.file("timed.mcap"), {.profile = "", .chunk_time_limit_ns = 50'000'000});
  const std::uint16_t channel = writer.add_channel(0, "/state", "raw");
  const std::vector<std::uint8_t> data = payload(300, 5);
  writer.write(channel, 0, 0, 0, data);
  const std::uint64_t before = writer.bytes_written();
  EXPECT_EQ(writer.statistics().chunk_count, 0u);
  std::this_thread::sleep_for(std::chrono::milliseconds(60));
  writer.write(channel, 1, 1, 1, data);
  EXPECT_EQ(writer.statistics().chunk_count, 1u);
  EXPECT_GT(writer.bytes_written(), before);
  const McapReader reader(dir.file("timed.mcap"));  // before close: no summary yet
  EXPECT_EQ(reader.messages().size(), 2u);
  writer.close();
}

// GIVEN a child writing 100 Hz for 2.5 s WHEN it is SIGKILLed THEN the file opens and holds
// the messages up to the last closed chunk, at most chunk_time_limit (1 s) plus one period old.
TEST(McapWriter, SigkilledWriterLeavesARecoverableFile) {
  const TempDir dir;
  const std::string path = dir.file("killed.mcap");
  using Clock = std::chrono::steady_clock;
  auto now_ns = [] {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch())
        .count();
  };
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    try {
      McapWriter writer;
      writer.open(path);  // zstd, 1 MiB, 1 s
      const std::uint16_t channel = writer.add_channel(0, "/state", "raw");
      const std::vector<std::uint8_t> data = payload(300, 1);
      for (std::uint32_t i = 0;; ++i) {
        writer.write(channel, i, now_ns(), now_ns(), data);
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
    } catch (...) {
      ::_exit(3);
    }
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  ASSERT_EQ(::kill(child, SIGKILL), 0);
  const std::int64_t killed_ns = now_ns();
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status)) << "child exited with " << WEXITSTATUS(status);

  const McapReader reader(path);
  EXPECT_FALSE(reader.report().has_summary);
  ASSERT_FALSE(reader.messages().empty());
  const double lost_s =
      static_cast<double>(killed_ns - reader.messages().back().log_time_ns) * 1e-9;
  // 1 s chunk limit + 10 ms period; 0.1 s margin for a loaded machine.
  EXPECT_LT(lost_s, 1.11) << reader.messages().size() << " messages recovered";
  EXPECT_GT(reader.messages().size(), 100u);
  fmt::print("recovered {} messages, the last {:.3f} s before the kill\n", reader.messages().size(),
             lost_s);
  for (std::size_t i = 0; i < reader.messages().size(); ++i) {
    EXPECT_EQ(reader.messages()[i].sequence, i);
  }
}

}  // namespace
}  // namespace hq::mcap
