#pragma once
/// Errors that cross a component boundary: bad files, configs, arguments, DDS setup.

#include <stdexcept>
#include <string>
#include <utility>

namespace hq {

/// Thrown while loading or validating anything a user, file or sensor supplies. The message
/// names where (file:line or config key), what, the value found and what was expected.
/// Executables print it and exit with status 2.
class InputError : public std::runtime_error {
 public:
  explicit InputError(const std::string& message) : std::runtime_error(message) {}
};

/// A device the run needs (a camera, a serial port) is absent or busy right now: unlike other
/// input errors it may clear by itself (a USB device that enumerates late, an FC powered after
/// the companion), so a supervisor may start the program again. Programs that run under one
/// (hq-onboard) give it an exit status of its own; elsewhere it is an InputError like any other.
class DeviceUnavailableError : public InputError {
 public:
  explicit DeviceUnavailableError(const std::string& message) : InputError(message) {}
};

}  // namespace hq

/// Programmer errors only (broken invariants), checked in debug builds. Never for data.
#ifdef NDEBUG
#define HQ_ASSERT(condition) static_cast<void>(0)
#else
#include <cassert>
#define HQ_ASSERT(condition) assert(condition)
#endif
