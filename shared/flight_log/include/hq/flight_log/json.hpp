#pragma once
/// The JSON text of one MCAP message, appended to a reused string: after the first messages of
/// each size, writing a message allocates nothing (the recorder thread writes thousands a
/// second). Numbers use %.9g (float-exact); a NaN or infinity becomes null (JSON has neither).
/// Not nlohmann::json: its document allocates a node per value and a string per key on every
/// message, and prints a float through its double (0.100000001490116 for 0.1f), where this
/// streams into one reused buffer and writes the float's own 9 digits.

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fmt/format.h>
#include <iterator>
#include <span>
#include <string>

namespace hq::flight_log {

class Json {
 public:
  std::string& text() { return text_; }
  void clear() { text_.clear(); }
  void raw(const char* s) { text_.append(s); }
  void number(double v) {
    if (!std::isfinite(v)) {
      text_.append("null");
      return;
    }
    fmt::format_to(std::back_inserter(text_), "{:.9g}", v);
  }
  void integer(long long v) { fmt::format_to(std::back_inserter(text_), "{}", v); }
  /// A string that needs no escaping (static names: modes, statuses, reasons).
  void string(const char* s) {
    text_.push_back('"');
    for (; *s != '\0'; ++s) {
      if (*s == '"' || *s == '\\') text_.push_back('\\');
      if (static_cast<unsigned char>(*s) >= 0x20) text_.push_back(*s);
    }
    text_.push_back('"');
  }
  /// Foxglove's time: {"sec":..,"nsec":..}.
  void stamp(std::int64_t t_ns) {
    raw("{\"sec\":");
    integer(t_ns / 1'000'000'000);
    raw(",\"nsec\":");
    integer(t_ns % 1'000'000'000);
    raw("}");
  }
  template <class V>
  void vector3(const V& v) {
    raw("{\"x\":");
    number(v[0]);
    raw(",\"y\":");
    number(v[1]);
    raw(",\"z\":");
    number(v[2]);
    raw("}");
  }
  /// RFC 4648 base64, as JSON-encoded bytes fields of Foxglove schemas expect.
  void base64(std::span<const std::uint8_t> data) {
    static constexpr char kAlphabet[] =
        "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    text_.push_back('"');
    std::size_t i = 0;
    for (; i + 3 <= data.size(); i += 3) {
      const std::uint32_t v =
          (std::uint32_t{data[i]} << 16) | (std::uint32_t{data[i + 1]} << 8) | data[i + 2];
      const char quad[4] = {kAlphabet[(v >> 18) & 63], kAlphabet[(v >> 12) & 63],
                            kAlphabet[(v >> 6) & 63], kAlphabet[v & 63]};
      text_.append(quad, 4);
    }
    if (i < data.size()) {
      const bool two = i + 1 < data.size();
      const std::uint32_t v =
          (std::uint32_t{data[i]} << 16) | (two ? std::uint32_t{data[i + 1]} << 8 : 0u);
      const char quad[4] = {kAlphabet[(v >> 18) & 63], kAlphabet[(v >> 12) & 63],
                            two ? kAlphabet[(v >> 6) & 63] : '=', '='};
      text_.append(quad, 4);
    }
    text_.push_back('"');
  }

 private:
  std::string text_;
};

}  // namespace hq::flight_log
