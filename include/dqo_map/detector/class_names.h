#pragma once
// The class-names file of a detector: one name per line, line k naming class k (the order of the
// model's class scores; config/coco.names holds COCO's 80, the order of the Ultralytics models).
// Blank lines are errors (they would shift every later class); surrounding blanks are trimmed.

#include <optional>
#include <string>
#include <vector>

namespace dqo::detector {

std::optional<std::vector<std::string>> read_class_names(const std::string& path, std::string* error);

}  // namespace dqo::detector
