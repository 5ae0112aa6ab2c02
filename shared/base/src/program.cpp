#include "hq/base/program.hpp"

#include "hq/base/log.hpp"

#include <cstring>

namespace hq {

std::string version_line(std::string_view program) {
  std::string line = fmt::format("{} {}", program, HQ_PROJECT_VERSION);
  if (std::strlen(HQ_GIT_DESCRIBE) > 0) line += fmt::format(" ({})", HQ_GIT_DESCRIBE);
  return line;
}

std::string program_name(const char* argv0) {
  const std::string_view path = argv0 != nullptr ? argv0 : "hq";
  const std::size_t slash = path.rfind('/');
  return std::string(slash == std::string_view::npos ? path : path.substr(slash + 1));
}

std::optional<int> parse_or_exit(CLI::App& app, int argc, char** argv) {
  const std::string name = program_name(argc > 0 ? argv[0] : nullptr);
  app.set_version_flag("--version", version_line(name), "print the version and exit");
  bool quiet = false;
  bool verbose = false;
  CLI::Option* quiet_flag = app.add_flag("-q,--quiet", quiet, "print only warnings and errors");
  app.add_flag("-v,--verbose", verbose, "also print debug lines")->excludes(quiet_flag);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) {
      return app.exit(e);  // --help or --version, printed on stdout
    }
    log::error("{}: {}\nRun with --help for more information.\n", name, e.what());
    return 2;
  }
  log::set_level(quiet ? log::Level::kWarning : verbose ? log::Level::kDebug : log::Level::kInfo);
  return std::nullopt;
}

}  // namespace hq
