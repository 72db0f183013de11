#include "text_util.h"

#include <cstdio>

namespace dqo {
namespace io_detail {

bool LineFields::count(size_t min, size_t max, const char* columns) const {
  const size_t n = line_.tokens.size();
  if (n >= min && n <= max) return true;
  const std::string expected =
      min == max ? std::to_string(min) : std::to_string(min) + " or " + std::to_string(max);
  return error("expected " + expected + " fields (" + columns + "), found " + std::to_string(n));
}

bool LineFields::number(size_t k, const char* name, double* value) const {
  if (k < line_.tokens.size() && parse_double(line_.tokens[k], value)) return true;
  return error("field " + std::to_string(k + 1) + " (" + name + ") '" +
               (k < line_.tokens.size() ? line_.tokens[k] : std::string()) +
               "' is not a finite number");
}

bool LineFields::number(size_t k, const char* name, float* value) const {
  if (k < line_.tokens.size() && parse_float(line_.tokens[k], value)) return true;
  return error("field " + std::to_string(k + 1) + " (" + name + ") '" +
               (k < line_.tokens.size() ? line_.tokens[k] : std::string()) +
               "' is not a finite number");
}

bool LineFields::integer(size_t k, const char* name, long long min, long long max,
                         long long* value) const {
  if (k < line_.tokens.size() && parse_int(line_.tokens[k], value) && *value >= min &&
      *value <= max) {
    return true;
  }
  return error("field " + std::to_string(k + 1) + " (" + name + ") '" +
               (k < line_.tokens.size() ? line_.tokens[k] : std::string()) +
               "' is not an integer in [" + std::to_string(min) + ", " + std::to_string(max) +
               "]");
}

bool LineFields::error(const std::string& message) const {
  return fail(error_, located(path_, line_.number, message));
}

std::string frame_file_name(int index, const char* extension) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%06d.%s", index, extension);
  return buffer;
}

}  // namespace io_detail
}  // namespace dqo
