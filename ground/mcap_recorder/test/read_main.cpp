// hq-mcap-read FILE: reads an MCAP file with hq::mcap::McapReader (recovering a file without
// summary, as a SIGKILLed recorder leaves it) and prints what it found; exit 1 when it holds
// no message, 2 when the reader refuses it. For flight_mcap.sh.
#include "hq/base/error.hpp"
#include "hq/mcap/mcap.hpp"

#include <cstdio>
#include <fmt/format.h>
#include <string>

int main(int argc, char** argv) {
  if (argc != 2) {
    fmt::print(stderr, "usage: hq-mcap-read FILE.mcap\n");
    return 2;
  }
  try {
    const hq::mcap::McapReader r(argv[1]);
    const hq::mcap::ReadReport& report = r.report();
    fmt::print("hq::mcap::McapReader {}: {} messages, {} channels, {}, {}, {} of {} bytes\n",
               argv[1], r.messages().size(), r.channels().size(),
               report.has_summary ? "summary" : "no summary (recovered)",
               report.truncated ? "truncated tail" : "ends on a record boundary",
               static_cast<unsigned long long>(report.valid_end_bytes),
               static_cast<unsigned long long>(report.file_size_bytes));
    for (const std::string& w : report.warnings) {
      fmt::print(stderr, "hq-mcap-read: warning: {}\n", w);
    }
    return r.messages().empty() ? 1 : 0;
  } catch (const hq::InputError& e) {
    fmt::print(stderr, "hq-mcap-read: {}\n", e.what());
    return 2;
  }
}
