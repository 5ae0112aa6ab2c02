#pragma once
/// For error-path tests: the message of the hq::InputError that f throws.

#include "hq/base/error.hpp"

#include <gtest/gtest.h>

#include <string>

namespace hq::testing {

/// Runs f and returns the hq::InputError message; records a test failure and returns "" if f
/// throws nothing.
template <typename F>
std::string input_error_message(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected hq::InputError";
  return "";
}

}  // namespace hq::testing
