#include "line_reader.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <system_error>
#include <utility>

namespace hq::recording::detail {
namespace {

// int64 nanoseconds reach 9.22e9 s; larger stamps cannot be represented.
constexpr double kMaxAbsStampS = 9.2e9;

bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; }

}  // namespace

LineReader::LineReader(std::string path) : path_(std::move(path)), stream_(path_) {
  if (!stream_) throw InputError(path_ + ": cannot open for reading");
}

bool LineReader::next() {
  while (std::getline(stream_, line_)) {
    ++line_number_;
    fields_.clear();
    const std::string_view text(line_);
    std::size_t pos = 0;
    while (pos < text.size()) {
      while (pos < text.size() && is_blank(text[pos])) ++pos;
      if (pos == text.size()) break;
      std::size_t end = pos;
      while (end < text.size() && !is_blank(text[end])) ++end;
      fields_.push_back(text.substr(pos, end - pos));
      pos = end;
    }
    if (fields_.empty() || fields_.front().front() == '#') continue;
    return true;
  }
  if (stream_.bad())
    throw InputError(path_ + ": read error after line " + std::to_string(line_number_));
  return false;
}

std::string LineReader::where() const { return path_ + ":" + std::to_string(line_number_); }

void LineReader::expect_fields(std::size_t count, std::string_view format) const {
  if (fields_.size() != count) {
    std::string line = line_;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    throw InputError(where() + ": expected \"" + std::string(format) + "\" (" +
                     std::to_string(count) + " fields), got " + std::to_string(fields_.size()) +
                     " in \"" + line + "\"");
  }
}

double LineReader::number(std::size_t i, std::string_view field_name) const {
  HQ_ASSERT(i < fields_.size());
  const std::string_view field = fields_[i];
  double value = 0.0;
  const auto [end, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (ec != std::errc() || end != field.data() + field.size()) {
    throw InputError(where() + ": " + std::string(field_name) + " = \"" + std::string(field) +
                     "\", expected a number");
  }
  if (!std::isfinite(value)) {
    throw InputError(where() + ": " + std::string(field_name) + " = " + std::string(field) +
                     ", expected a finite number");
  }
  return value;
}

double LineReader::stamp_s() {
  const double t_s = number(0, "timestamp");
  if (std::abs(t_s) >= kMaxAbsStampS) {
    throw InputError(where() + ": timestamp " + std::string(fields_[0]) +
                     " s is out of range, expected |t| < 9.2e9 s");
  }
  if (has_previous_stamp_ && !(t_s > previous_stamp_s_)) {
    char previous[64];
    hq::format_into(previous, "{:.6f}", previous_stamp_s_);
    throw InputError(where() + ": timestamp " + std::string(fields_[0]) +
                     " is not after the previous one (" + previous +
                     "); expected strictly increasing stamps");
  }
  has_previous_stamp_ = true;
  previous_stamp_s_ = t_s;
  return t_s;
}

}  // namespace hq::recording::detail
