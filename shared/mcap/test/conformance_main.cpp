// Both directions of the conformance check with @mcap/core (conformance.cjs).
//   hq-mcap-conformance write DIR
//       Writes DIR/zstd.mcap (zstd chunks), DIR/none.mcap (uncompressed chunks) and
//       DIR/nosummary.mcap (the bytes on disk after a flush, before close: what a killed writer
//       leaves), each with a .json of what the writer reports: channels, schemas, statistics
//       and every message's stamps and bytes; and DIR/recovered.mcap, nosummary.mcap rewritten
//       by hq::mcap::recover (hq-report --recover) into a complete indexed file.
//   hq-mcap-conformance check FILE.mcap FILE.txt
//       Reads a file @mcap/core wrote and checks it against the values it listed; then the
//       file cut in half (no summary) must recover a prefix of the messages.

#include "hq/base/error.hpp"
#include "hq/mcap/mcap.hpp"

#include <array>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fmt/format.h>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace {

using hq::mcap::Bytes;
using hq::mcap::Compression;

std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

struct Written {
  std::uint16_t channel_id;
  std::uint32_t sequence;
  std::int64_t log_time_ns;
  std::int64_t publish_time_ns;
  std::size_t size;
  std::uint32_t sum;
};

void write_json(const std::string& path, const hq::mcap::Statistics& s,
                const std::vector<std::string>& topics, const std::vector<std::string>& schemas,
                const std::vector<Written>& messages, bool with_summary) {
  std::ofstream out(path);
  out << "{\n\"summary\": " << (with_summary ? "true" : "false") << ",\n";
  out << "\"channels\": [";
  for (std::size_t i = 0; i < topics.size(); ++i) {
    out << (i == 0 ? "" : ", ") << "{\"id\": " << i << ", \"topic\": " << quoted(topics[i])
        << ", \"schema\": " << quoted(schemas[i]) << "}";
  }
  out << "],\n\"statistics\": {\"messages\": " << s.message_count
      << ", \"schemas\": " << s.schema_count << ", \"channels\": " << s.channel_count
      << ", \"attachments\": " << s.attachment_count << ", \"metadata\": " << s.metadata_count
      << ", \"chunks\": " << s.chunk_count << ", \"start\": \"" << s.message_start_time_ns
      << "\", \"end\": \"" << s.message_end_time_ns << "\"},\n";
  out << "\"attachments\": [{\"name\": \"calib.yaml\", \"media_type\": \"application/yaml\", "
         "\"size\": 12}, {\"name\": \"thumbnail.jpg\", \"media_type\": \"image/jpeg\", "
         "\"size\": 5000}],\n";
  out << "\"metadata\": [{\"name\": \"flight\", \"values\": {\"operator\": \"test\", "
         "\"vehicle\": \"hq-1\"}}],\n";
  out << "\"messages\": [\n";
  for (std::size_t i = 0; i < messages.size(); ++i) {
    const Written& m = messages[i];
    out << (i == 0 ? "" : ",\n") << "[" << m.channel_id << ", " << m.sequence << ", \""
        << m.log_time_ns << "\", \"" << m.publish_time_ns << "\", " << m.size << ", " << m.sum
        << "]";
  }
  out << "\n]}\n";
}

void write_files(const std::string& dir, const std::string& name, Compression compression,
                 bool keep_unclosed_copy) {
  const std::string path = dir + "/" + name + ".mcap";
  hq::mcap::McapWriter writer;
  hq::mcap::WriterOptions options;
  options.profile = "hq";
  options.compression = compression;
  options.chunk_size_bytes = 64 * 1024ULL;  // many chunks for the index to seek through
  writer.open(path, options);
  const std::string idl_state = "module hq { struct State { double v_H_mps[3]; }; };";
  const std::string idl_image = "module hq { struct Jpeg { sequence<octet> data; }; };";
  const std::uint16_t s_state = writer.add_schema(
      "hq::State", "omgidl",
      Bytes(reinterpret_cast<const std::uint8_t*>(idl_state.data()), idl_state.size()));
  const std::uint16_t s_image = writer.add_schema(
      "hq::Jpeg", "omgidl",
      Bytes(reinterpret_cast<const std::uint8_t*>(idl_image.data()), idl_image.size()));
  const std::vector<std::string> topics = {"/state", "/camera/jpeg", "/events"};
  const std::vector<std::string> schemas = {"hq::State", "hq::Jpeg", ""};
  writer.add_channel(s_state, topics[0], "cdr", {{"frame", "H"}});
  writer.add_channel(s_image, topics[1], "cdr");
  writer.add_channel(0, topics[2], "json");
  writer.add_metadata("flight", {{"vehicle", "hq-1"}, {"operator", "test"}});
  const std::string calib = "K: [1, 2, 3]";
  writer.add_attachment("calib.yaml", "application/yaml",
                        Bytes(reinterpret_cast<const std::uint8_t*>(calib.data()), calib.size()),
                        1'000'000'000);

  std::vector<Written> messages;
  std::vector<std::uint8_t> data;
  std::array<std::uint32_t, 3> sequence = {0, 0, 0};
  auto add = [&](std::uint16_t channel, std::int64_t t_ns, std::size_t size) {
    data.resize(size);
    std::uint32_t sum = 0;
    for (std::size_t i = 0; i < size; ++i) {
      data[i] = static_cast<std::uint8_t>((static_cast<std::uint64_t>(t_ns / 1000) + i * 7) & 0xFF);
      sum += data[i];
    }
    // Jitter in publish time so that log and publish stamps differ.
    const std::int64_t publish_ns = t_ns - std::int64_t{1234} * (channel + 1);
    writer.write(channel, sequence[channel], t_ns, publish_ns, data);
    messages.push_back({channel, sequence[channel], t_ns, publish_ns, size, sum});
    ++sequence[channel];
  };
  // 10 s of flight: 200 Hz state (300 B), 10 Hz images (2-20 kB), an event a second; every
  // stamp unique so log-time order is one order.
  for (int i = 0; i < 2000; ++i) {
    const std::int64_t t_ns = 1'700'000'000'000'000'000LL + i * 5'000'000LL;
    add(0, t_ns, 300);
    if (i % 20 == 0) add(1, t_ns + 1000, 2000 + static_cast<std::size_t>(i % 7) * 3000);
    if (i % 200 == 0) add(2, t_ns + 2000, 40);
  }
  std::vector<std::uint8_t> thumbnail(5000, 0xAB);
  writer.add_attachment("thumbnail.jpg", "image/jpeg", thumbnail, 1'700'000'005'000'000'000LL);
  writer.flush();
  if (keep_unclosed_copy) {
    const std::string copy = dir + "/nosummary.mcap";
    std::filesystem::copy_file(path, copy, std::filesystem::copy_options::overwrite_existing);
    write_json(dir + "/nosummary.json", writer.statistics(), topics, schemas, messages, false);
    // hq-report --recover's rewrite of it: the same messages, now with a summary and indexes.
    const std::string recovered = dir + "/recovered.mcap";
    std::filesystem::remove(recovered);
    const hq::mcap::RecoveryReport report = hq::mcap::recover(copy, recovered);
    write_json(dir + "/recovered.json", report.written, topics, schemas, messages, true);
  }
  writer.close();
  write_json(dir + "/" + name + ".json", writer.statistics(), topics, schemas, messages, true);
}

int failures = 0;

void expect(bool condition, const std::string& what) {
  if (!condition) {
    fmt::print(stderr, "hq-mcap-conformance: {}\n", what);
    ++failures;
  }
}

std::uint32_t byte_sum(const std::vector<std::uint8_t>& data) {
  std::uint32_t sum = 0;
  for (const std::uint8_t b : data) sum += b;
  return sum;
}

// Compares the first `count` of the listed messages with what the reader returned.
void expect_messages(const std::vector<hq::mcap::Message>& got, const std::vector<Written>& want,
                     std::size_t count, const std::string& how) {
  expect(got.size() == count,
         how + ": " + std::to_string(got.size()) + " messages, expected " + std::to_string(count));
  int shown = 0;
  for (std::size_t i = 0; i < std::min(got.size(), count); ++i) {
    const hq::mcap::Message& m = got[i];
    const Written& w = want[i];
    const bool same = m.channel_id == w.channel_id && m.sequence == w.sequence &&
                      m.log_time_ns == w.log_time_ns && m.publish_time_ns == w.publish_time_ns &&
                      m.data.size() == w.size && byte_sum(m.data) == w.sum;
    if (!same && shown++ < 5) expect(false, how + ": message " + std::to_string(i) + " differs");
  }
}

// What @mcap/core's writer listed (conformance.cjs write): one line per record.
struct Expected {
  std::vector<Written> messages;
  std::size_t channels = 0;
  std::size_t attachments = 0;
  std::size_t metadata = 0;
  std::uint64_t stat_messages = 0;
  std::uint64_t stat_chunks = 0;
};

void check_channel(const hq::mcap::McapReader& reader, std::istringstream& f) {
  unsigned id = 0;
  unsigned schema_id = 0;
  std::string topic;
  std::string encoding;
  std::string schema;
  std::size_t metadata_size = 0;
  f >> id >> schema_id >> topic >> encoding >> schema >> metadata_size;
  const hq::mcap::Channel* c = reader.channel(static_cast<std::uint16_t>(id));
  expect(c != nullptr, "channel " + std::to_string(id) + " missing");
  if (c == nullptr) return;
  expect(c->schema_id == schema_id && c->topic == topic && c->message_encoding == encoding &&
             c->metadata.size() == metadata_size,
         "channel " + std::to_string(id) + " is " + c->topic + " " + c->message_encoding);
  const hq::mcap::Schema* s = reader.schema(c->schema_id);
  expect((s == nullptr ? std::string("-") : s->name) == schema,
         "channel " + topic + ": schema differs from " + schema);
}

void check_attachment(const hq::mcap::McapReader& reader, std::istringstream& f,
                      std::size_t index) {
  std::string name;
  std::string media_type;
  std::size_t size = 0;
  f >> name >> media_type >> size;
  const bool found = index < reader.attachments().size();
  expect(found && reader.attachments()[index].name == name &&
             reader.attachments()[index].media_type == media_type &&
             reader.attachments()[index].data.size() == size,
         "attachment " + name + " differs");
}

void check_metadata(const hq::mcap::McapReader& reader, std::istringstream& f, std::size_t index) {
  std::string name;
  std::size_t count = 0;
  f >> name >> count;
  const bool found = index < reader.metadata().size();
  expect(found && reader.metadata()[index].name == name &&
             reader.metadata()[index].values.size() == count,
         "metadata " + name + " differs");
}

// Reads the listing, checking channels, attachments and metadata as they come.
Expected read_listing(const hq::mcap::McapReader& reader, const std::string& values_path) {
  std::ifstream in(values_path);
  Expected e;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream f(line);
    std::string kind;
    f >> kind;
    if (kind == "channel") {
      check_channel(reader, f);
      ++e.channels;
    } else if (kind == "message") {
      Written w{};
      unsigned channel = 0;
      f >> channel >> w.sequence >> w.log_time_ns >> w.publish_time_ns >> w.size >> w.sum;
      w.channel_id = static_cast<std::uint16_t>(channel);
      e.messages.push_back(w);
    } else if (kind == "attachment") {
      check_attachment(reader, f, e.attachments++);
    } else if (kind == "metadata") {
      check_metadata(reader, f, e.metadata++);
    } else if (kind == "statistics") {
      f >> e.stat_messages >> e.stat_chunks;
    }
  }
  return e;
}

void check_indexed(const hq::mcap::McapReader& reader, const Expected& e) {
  expect(reader.report().has_summary, "summary not read");
  expect(reader.profile() == "theirs", "profile " + reader.profile());
  expect(reader.channels().size() == e.channels, "channel count");
  expect(reader.attachments().size() == e.attachments, "attachment count");
  expect(reader.metadata().size() == e.metadata, "metadata count");
  expect(reader.statistics().message_count == e.stat_messages, "statistics: message count");
  expect(reader.statistics().chunk_count == e.stat_chunks, "statistics: chunk count");
  expect(reader.report().chunk_count == e.stat_chunks, "chunks read");
  expect_messages(reader.messages(), e.messages, e.messages.size(), "indexed");
}

// The same file without its summary, as a killed writer would leave it: a prefix recovered.
void check_cut(const hq::mcap::McapReader& reader, const std::string& mcap_path,
               const Expected& e) {
  const std::string cut = mcap_path + ".cut";
  const auto size = std::filesystem::file_size(mcap_path);
  std::filesystem::copy_file(mcap_path, cut, std::filesystem::copy_options::overwrite_existing);
  std::filesystem::resize_file(cut, size / 2);
  const hq::mcap::McapReader recovered(cut);
  expect(!recovered.report().has_summary && recovered.report().truncated, "cut file: report");
  expect(!recovered.messages().empty(), "cut file: nothing recovered");
  expect_messages(recovered.messages(), e.messages, recovered.messages().size(), "cut file");
  fmt::print(
      "{}: hq::mcap read {} messages in {} chunks, {} channels, {} attachments, {} metadata; cut "
      "at {} of {} bytes: {} messages recovered\n",
      mcap_path, reader.messages().size(),
      static_cast<unsigned long long>(reader.report().chunk_count), e.channels, e.attachments,
      e.metadata, static_cast<unsigned long long>(recovered.report().valid_end_bytes),
      static_cast<unsigned long long>(size), recovered.messages().size());
}

int check(const std::string& mcap_path, const std::string& values_path) {
  const hq::mcap::McapReader reader(mcap_path);
  const Expected expected = read_listing(reader, values_path);
  check_indexed(reader, expected);
  check_cut(reader, mcap_path, expected);
  return failures == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (!((argc == 3 && mode == "write") || (argc == 4 && mode == "check"))) {
    fmt::print(stderr, "usage: hq-mcap-conformance write DIR | check FILE.mcap FILE.txt\n");
    return 2;
  }
  try {
    if (mode == "check") return check(argv[2], argv[3]);
    write_files(argv[2], "zstd", Compression::kZstd, true);
    write_files(argv[2], "none", Compression::kNone, false);
  } catch (const hq::InputError& e) {
    fmt::print(stderr, "hq-mcap-conformance: {}\n", e.what());
    return 2;
  }
  return 0;
}
