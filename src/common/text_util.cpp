#include "dqo_map/common/text_util.h"

#include <algorithm>

#include <unistd.h>

#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

namespace dqo::text {

namespace fs = std::filesystem;

std::string format_double(double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

std::string format_float(float value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

namespace {

template <typename T>
bool parse_floating(const std::string& token, T* value, bool allow_non_finite) {
  if (token.empty()) return false;
  const char* begin = token.data();
  const char* end = token.data() + token.size();
  // from_chars rejects a leading '+', which some tools print.
  if (*begin == '+') ++begin;
  T parsed{};
  const auto result = std::from_chars(begin, end, parsed);
  if (result.ec != std::errc() || result.ptr != end) return false;
  if (!allow_non_finite && !std::isfinite(parsed)) return false;
  *value = parsed;
  return true;
}

}  // namespace

bool parse_double(const std::string& token, double* value, bool allow_non_finite) {
  return parse_floating(token, value, allow_non_finite);
}

bool parse_float(const std::string& token, float* value) {
  return parse_floating(token, value, false);
}

bool parse_int(const std::string& token, long long* value) {
  if (token.empty()) return false;
  const char* begin = token.data();
  const char* end = token.data() + token.size();
  if (*begin == '+') ++begin;
  long long parsed = 0;
  const auto result = std::from_chars(begin, end, parsed);
  if (result.ec != std::errc() || result.ptr != end) return false;
  *value = parsed;
  return true;
}

bool read_text_lines(const std::string& path, std::vector<TextLine>* lines, std::string* error) {
  std::ifstream in(path);
  if (!in) return fail(error, path + ": cannot open for reading");
  lines->clear();
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    ++number;
    if (!text.empty() && text.back() == '\r') text.pop_back();
    const size_t first = text.find_first_not_of(" \t");
    if (first == std::string::npos || text[first] == '#') continue;
    TextLine line;
    line.number = number;
    line.text = text;
    std::istringstream tokens(text);
    std::string token;
    while (tokens >> token) line.tokens.push_back(token);
    lines->push_back(std::move(line));
  }
  if (in.bad()) return fail(error, path + ": read error");
  return true;
}

std::string located(const std::string& path, int line, const std::string& message) {
  return path + ":" + std::to_string(line) + ": " + message;
}

bool fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

bool write_file_atomically(const std::string& path, const std::string& content,
                           std::string* error) {
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  std::string pattern = (dir / ("." + target.filename().string() + ".tmp-XXXXXX")).string();
  const int fd = ::mkstemp(pattern.data());
  if (fd < 0) return fail(error, path + ": cannot create a temporary file beside it");
  size_t written = 0;
  while (written < content.size()) {
    const ssize_t n = ::write(fd, content.data() + written, content.size() - written);
    if (n <= 0) {
      ::close(fd);
      ::unlink(pattern.c_str());
      return fail(error, path + ": write failed");
    }
    written += static_cast<size_t>(n);
  }
  if (::close(fd) != 0) {
    ::unlink(pattern.c_str());
    return fail(error, path + ": write failed");
  }
  // mkstemp creates 0600; give the file the usual permissions of a new file.
  std::error_code ec;
  fs::permissions(pattern,
                  fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read |
                      fs::perms::others_read,
                  ec);
  fs::rename(pattern, target, ec);
  if (ec) {
    ::unlink(pattern.c_str());
    return fail(error, path + ": cannot rename the temporary file into place: " + ec.message());
  }
  return true;
}

std::vector<std::string> split_list(const std::string& text, char separator) {
  std::vector<std::string> out;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = std::min(text.find(separator, start), text.size());
    if (end > start) out.push_back(text.substr(start, end - start));
    start = end + 1;
  }
  return out;
}

}  // namespace dqo::text
