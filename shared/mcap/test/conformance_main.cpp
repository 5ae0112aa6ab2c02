// Writes MCAP files for the @mcap/core checker (conformance.cjs) and, beside each, what the
// writer reports as JSON: channels, schemas, statistics and every message's stamps and bytes.
//   hq-mcap-conformance write DIR
// DIR/zstd.mcap (zstd chunks), DIR/none.mcap (uncompressed chunks), DIR/nosummary.mcap (the
// bytes on disk after a flush, before close: what a killed writer leaves), each with .json.

#include "hq/base/error.hpp"
#include "hq/mcap/mcap.hpp"

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
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

void write_json(const std::string& path, const hq::mcap::McapWriter& writer,
                const std::vector<std::string>& topics, const std::vector<std::string>& schemas,
                const std::vector<Written>& messages, bool with_summary) {
  const hq::mcap::Statistics& s = writer.statistics();
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
  options.chunk_size_bytes = 64 * 1024;  // many chunks for the index to seek through
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
  std::uint32_t sequence[3] = {0, 0, 0};
  auto add = [&](std::uint16_t channel, std::int64_t t_ns, std::size_t size) {
    data.resize(size);
    std::uint32_t sum = 0;
    for (std::size_t i = 0; i < size; ++i) {
      data[i] = static_cast<std::uint8_t>((t_ns / 1000 + i * 7) & 0xFF);
      sum += data[i];
    }
    // Jitter in publish time so that log and publish stamps differ.
    const std::int64_t publish_ns = t_ns - 1234 * (channel + 1);
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
    write_json(dir + "/nosummary.json", writer, topics, schemas, messages, false);
  }
  writer.close();
  write_json(dir + "/" + name + ".json", writer, topics, schemas, messages, true);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3 || std::string(argv[1]) != "write") {
    std::fprintf(stderr, "usage: hq-mcap-conformance write DIR\n");
    return 2;
  }
  try {
    write_files(argv[2], "zstd", Compression::kZstd, true);
    write_files(argv[2], "none", Compression::kNone, false);
  } catch (const hq::InputError& e) {
    std::fprintf(stderr, "hq-mcap-conformance: %s\n", e.what());
    return 2;
  }
  return 0;
}
