#pragma once
/// Private: line-by-line reading of TUM text files with file:line error messages.

#include <cstddef>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

namespace hq::recording::detail {

/// Yields the data lines of a text file: blank lines and '#' comments are skipped, every other
/// line is split on blanks. Errors name "path:line".
class LineReader {
 public:
  /// Throws hq::InputError "path: cannot open" if the file is missing or unreadable.
  explicit LineReader(std::string path);

  /// Advances to the next data line; false at the end of the file.
  bool next();
  const std::vector<std::string_view>& fields() const { return fields_; }
  const std::string& line() const { return line_; }
  /// "path:line" of the current line.
  std::string where() const;

  /// Throws hq::InputError "path:line: expected <format>, got "<line>"" unless the line has
  /// exactly `count` fields.
  void expect_fields(std::size_t count, std::string_view format) const;
  /// Parses field i as a finite number; throws naming the field otherwise.
  double number(std::size_t i, std::string_view field_name) const;
  /// Parses field 0 as a stamp in seconds and checks it is after the previous line's.
  double stamp_s();

 private:
  std::string path_;
  std::ifstream stream_;
  std::string line_;
  std::vector<std::string_view> fields_;
  std::size_t line_number_ = 0;
  bool has_previous_stamp_ = false;
  double previous_stamp_s_ = 0.0;
};

}  // namespace hq::recording::detail
