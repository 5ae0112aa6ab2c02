#pragma once
/// The one main() of every command-line program: bad input (hq::InputError) and anything else
/// a library throws (yaml-cpp, OpenCV, the standard library) is printed as "<tool>: <message>"
/// on stderr and the program exits with status 2, never a crash (exit 134 from an uncaught
/// exception's abort).

#include "hq/base/error.hpp"
#include "hq/base/log.hpp"

#include <exception>

namespace hq {

/// Runs `run(argc, argv)`, turning any exception into a message and exit status 2.
template <typename Run>
int run_tool(const char* tool_name, int argc, char** argv, Run run) {
  try {
    return run(argc, argv);
  } catch (const InputError& e) {
    log::error("{}: {}\n", tool_name, e.what());
  } catch (const std::exception& e) {
    // A library's own exception (yaml-cpp's bad conversion, std::filesystem, OpenCV): the
    // input reached a check we lack, still the operator's to fix, so it is reported the same.
    log::error("{}: {}\n", tool_name, e.what());
  } catch (...) {
    log::error("{}: unknown exception\n", tool_name);
  }
  return 2;
}

}  // namespace hq
