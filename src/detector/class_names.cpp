#include "dqo_map/detector/class_names.h"

#include <fstream>

namespace dqo::detector {

std::optional<std::vector<std::string>> read_class_names(const std::string& path, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    if (error) *error = path + ": cannot open the class-names file";
    return std::nullopt;
  }
  std::vector<std::string> names;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const size_t b = line.find_first_not_of(" \t\r");
    const size_t e = line.find_last_not_of(" \t\r");
    if (b == std::string::npos) {
      // A blank line at the very end is the file's last newline twice; anywhere else it would shift
      // every later class by one.
      std::string rest;
      bool more = false;
      while (std::getline(in, rest)) more = more || rest.find_first_not_of(" \t\r") != std::string::npos;
      if (more) {
        if (error) *error = path + ":" + std::to_string(number) + ": blank line (one class name per line)";
        return std::nullopt;
      }
      break;
    }
    names.push_back(line.substr(b, e - b + 1));
  }
  if (names.empty()) {
    if (error) *error = path + ": no class names";
    return std::nullopt;
  }
  return names;
}

}  // namespace dqo::detector
