// hq-mcap-read FILE: reads an MCAP file with hq::mcap::McapReader (recovering a file without
// summary, as a SIGKILLed recorder leaves it) and prints what it found; exit 1 when it holds
// no message, 2 when the reader refuses it. For flight_mcap.sh.
#include "hq/base/error.hpp"
#include "hq/mcap/mcap.hpp"

#include <cstdio>
#include <string>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: hq-mcap-read FILE.mcap\n");
    return 2;
  }
  try {
    const hq::mcap::McapReader r(argv[1]);
    const hq::mcap::ReadReport& report = r.report();
    std::printf("hq::mcap::McapReader %s: %zu messages, %zu channels, %s, %s, %llu of %llu bytes\n",
                argv[1], r.messages().size(), r.channels().size(),
                report.has_summary ? "summary" : "no summary (recovered)",
                report.truncated ? "truncated tail" : "ends on a record boundary",
                static_cast<unsigned long long>(report.valid_end_bytes),
                static_cast<unsigned long long>(report.file_size_bytes));
    for (const std::string& w : report.warnings) {
      std::fprintf(stderr, "hq-mcap-read: warning: %s\n", w.c_str());
    }
    return r.messages().empty() ? 1 : 0;
  } catch (const hq::InputError& e) {
    std::fprintf(stderr, "hq-mcap-read: %s\n", e.what());
    return 2;
  }
}
