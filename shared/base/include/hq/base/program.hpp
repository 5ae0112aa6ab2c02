#pragma once
/// What every program's command line shares, in one place: --version, --quiet, --verbose, and
/// the exit status of a usage error. CLI11 exits 105-109 on a parse error by itself; every
/// program here exits 2 on any usage error (an unknown option, a missing or out-of-range value,
/// options that exclude each other) as on any other bad input, and 0 for --help and --version.
///
///   CLI::App app{"hq-x: what it does"};
///   ... app.add_option(...) ...
///   if (const std::optional<int> exit = hq::parse_or_exit(app, argc, argv)) return *exit;

#include <CLI/CLI.hpp>

#include <optional>
#include <string>
#include <string_view>

namespace hq {

/// "<program> <project version> (<git describe at configure time>)", the line --version prints.
std::string version_line(std::string_view program);

/// The program's name as it prints it: argv[0] without its folder.
std::string program_name(const char* argv0);

/// Adds --version, --quiet and --verbose to `app`, parses, and sets the log level
/// (hq/base/log.hpp). Returns nullopt to go on, or the exit status once it has printed: 0 after
/// --help or --version (on stdout), 2 after a usage error ("<program>: <what>" and a pointer to
/// --help, on stderr).
std::optional<int> parse_or_exit(CLI::App& app, int argc, char** argv);

}  // namespace hq
