#pragma once
// Private helpers of io/ for its text files: field-by-field parsing with errors that name file,
// line, field and column, and per-frame file names. The general text helpers (exact numbers, line
// splitting, "file:line: message" errors, atomic writes) live in common/ and are named here too, so
// that io/ code reaches all of them as io_detail::. Not installed.

#include <string>
#include <vector>

#include "dqo_map/common/text_util.h"

namespace dqo {
namespace io_detail {

using text::fail;
using text::format_double;
using text::format_float;
using text::located;
using text::parse_double;
using text::parse_float;
using text::parse_int;
using text::read_text_lines;
using text::TextLine;
using text::write_file_atomically;

// Field-by-field parsing of one line with errors that name file, line, field and column name.
class LineFields {
 public:
  LineFields(const std::string& path, const TextLine& line, std::string* error)
      : path_(path), line_(line), error_(error) {}

  // The line has between min and max fields; `columns` names them for the message.
  bool count(size_t min, size_t max, const char* columns) const;
  bool number(size_t k, const char* name, double* value) const;
  bool number(size_t k, const char* name, float* value) const;
  bool integer(size_t k, const char* name, long long min, long long max, long long* value) const;
  // Reports a message about this line; returns false.
  bool error(const std::string& message) const;

 private:
  const std::string& path_;
  const TextLine& line_;
  std::string* error_;
};

// File name of frame i inside a per-frame folder: 000042.png.
std::string frame_file_name(int index, const char* extension);

}  // namespace io_detail
}  // namespace dqo
