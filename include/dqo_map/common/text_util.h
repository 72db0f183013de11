#pragma once
// Helpers for the package's text files: exact number formatting, line splitting with line numbers,
// "file:line: message" errors, and atomic writes. Plain C++17 (POSIX for the atomic write).

#include <string>
#include <vector>

namespace dqo::text {

// Shortest text that parses back to exactly the same value (std::to_chars), so every number the
// writers print is read back bit for bit; plain decimal where that is as short as exponent form.
std::string format_double(double value);
std::string format_float(float value);

// The whole token must be a number (std::from_chars: locale independent). Rejects "nan"/"inf"
// unless allow_non_finite.
bool parse_double(const std::string& token, double* value, bool allow_non_finite = false);
bool parse_float(const std::string& token, float* value);
bool parse_int(const std::string& token, long long* value);

// The items of a separated list ("a,b,,c" -> a b c: empty items dropped), for command-line lists.
std::vector<std::string> split_list(const std::string& text, char separator = ',');

// One meaningful line of a text file: blank lines and lines whose first non-blank character is '#'
// are skipped, but line numbers count them.
struct TextLine {
  int number = 0;                   // 1-based line number in the file
  std::string text;                 // the line without trailing '\r'
  std::vector<std::string> tokens;  // split on blanks
};

bool read_text_lines(const std::string& path, std::vector<TextLine>* lines, std::string* error);

// "path:line: message" (compiler style, clickable in editors and terminals).
std::string located(const std::string& path, int line, const std::string& message);

// Sets *error when error is not null; returns false so callers can `return fail(error, ...)`.
bool fail(std::string* error, const std::string& message);

// Writes `content` to a temporary sibling and renames it over `path`, so readers never see a
// half-written file.
bool write_file_atomically(const std::string& path, const std::string& content,
                           std::string* error);

}  // namespace dqo::text
