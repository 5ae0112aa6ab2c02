#pragma once
/// fmt into a fixed char buffer, for the texts the hot paths fill (event texts at 1 kHz, labels
/// per frame): fmt::format_to_n writes in place and allocates nothing, where fmt::format would
/// build a std::string. Like the snprintf it replaces it truncates to the buffer and always ends
/// the text with '\0'; unlike snprintf the format is checked against the arguments at compile
/// time.

#include <cstddef>
#include <fmt/format.h>
#include <string_view>
#include <utility>

namespace hq {

/// Writes at most size - 1 characters and a '\0' into out; returns the text written.
template <typename... Args>
std::string_view format_into(char* out, std::size_t size, fmt::format_string<Args...> format,
                             Args&&... args) {
  if (size == 0) return {};
  const auto result = fmt::format_to_n(out, size - 1, format, std::forward<Args>(args)...);
  *result.out = '\0';
  return {out, static_cast<std::size_t>(result.out - out)};
}

template <std::size_t N, typename... Args>
std::string_view format_into(char (&out)[N], fmt::format_string<Args...> format, Args&&... args) {
  return format_into(out, N, format, std::forward<Args>(args)...);
}

}  // namespace hq
