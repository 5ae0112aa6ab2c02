#include "hq/base/error.hpp"
#include "hq/mcap/mcap.hpp"

#include <algorithm>
#include <filesystem>
#include <map>

namespace hq::mcap {

namespace {

// Schemas and channels in the reader's order, mapped to the ids the writer gives them.
std::map<std::uint16_t, std::uint16_t> copy_channels(const McapReader& in, McapWriter& out) {
  std::map<std::uint16_t, std::uint16_t> schema_ids;
  for (const Schema& s : in.schemas()) {
    schema_ids[s.id] = out.add_schema(s.name, s.encoding, s.data);
  }
  std::map<std::uint16_t, std::uint16_t> channel_ids;
  for (const Channel& c : in.channels()) {
    const auto schema = schema_ids.find(c.schema_id);
    // A channel whose schema record was lost keeps its messages, without a schema (id 0).
    const std::uint16_t schema_id = schema == schema_ids.end() ? 0 : schema->second;
    channel_ids[c.id] = out.add_channel(schema_id, c.topic, c.message_encoding, c.metadata);
  }
  return channel_ids;
}

}  // namespace

RecoveryReport recover(const std::string& in_path, const std::string& out_path,
                       const WriterOptions& options) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(out_path, ec)) {
    throw InputError(out_path + ": exists; refusing to overwrite it, expected a new file");
  }
  const McapReader in(in_path);
  RecoveryReport report;
  report.read = in.report();
  if (!report.read.has_summary && report.read.file_size_bytes > report.read.valid_end_bytes) {
    report.bytes_dropped = report.read.file_size_bytes - report.read.valid_end_bytes;
  }
  McapWriter out;
  WriterOptions o = options;
  if (o.profile.empty()) o.profile = in.profile();
  out.open(out_path, o);
  const std::map<std::uint16_t, std::uint16_t> channel_ids = copy_channels(in, out);
  for (const Attachment& a : in.attachments()) {
    out.add_attachment(a.name, a.media_type, a.data, a.log_time_ns, a.create_time_ns);
  }
  bool any_written = false;
  for (const Message& m : in.messages()) {
    const auto channel = channel_ids.find(m.channel_id);
    if (channel == channel_ids.end()) {
      ++report.messages_without_channel;  // its Channel record was lost: nothing to name it by
      continue;
    }
    out.write(channel->second, m.sequence, m.log_time_ns, m.publish_time_ns, m.data);
    if (!any_written || m.log_time_ns < report.first_log_time_ns) {
      report.first_log_time_ns = m.log_time_ns;
    }
    report.last_log_time_ns = std::max(report.last_log_time_ns, m.log_time_ns);
    any_written = true;
  }
  for (const Metadata& m : in.metadata()) out.add_metadata(m.name, m.values);
  out.close();
  report.written = out.statistics();
  report.bytes_written = out.bytes_written();
  return report;
}

}  // namespace hq::mcap
