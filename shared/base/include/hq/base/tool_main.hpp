#pragma once
/// The one main() of every command-line program: bad input (hq::InputError) is printed as
/// "<tool>: <message>" on stderr and the program exits with status 2, never a crash.

#include "hq/base/error.hpp"

#include <cstdio>

namespace hq {

/// Runs `run(argc, argv)`, turning an hq::InputError into a message and exit status 2.
template <typename Run>
int run_tool(const char* tool_name, int argc, char** argv, Run run) {
  try {
    return run(argc, argv);
  } catch (const InputError& e) {
    std::fprintf(stderr, "%s: %s\n", tool_name, e.what());
    return 2;
  }
}

}  // namespace hq
