#pragma once
/// hq::Result<T>: a value or the reason there is none, for callers that branch on failure.
/// Shaped like std::expected so that it can become that under C++23.

#include "hq/base/error.hpp"

#include <string>
#include <utility>
#include <variant>

namespace hq {

/// The reason carried by a failed Result.
struct Error {
  std::string message;
};

template <typename T>
class Result {
 public:
  Result(T value) : storage_(std::in_place_index<0>, std::move(value)) {}      // NOLINT: implicit
  Result(Error error) : storage_(std::in_place_index<1>, std::move(error)) {}  // NOLINT: implicit

  [[nodiscard]] bool has_value() const { return storage_.index() == 0; }
  explicit operator bool() const { return has_value(); }

  /// @pre has_value(); otherwise throws hq::InputError with the error message.
  const T& value() const& {
    if (!has_value()) throw InputError(error().message);
    return std::get<0>(storage_);
  }
  T& value() & {
    if (!has_value()) throw InputError(error().message);
    return std::get<0>(storage_);
  }
  T&& value() && {
    if (!has_value()) throw InputError(error().message);
    return std::get<0>(std::move(storage_));
  }
  /// @pre !has_value()
  const Error& error() const { return std::get<1>(storage_); }

 private:
  std::variant<T, Error> storage_;
};

}  // namespace hq
