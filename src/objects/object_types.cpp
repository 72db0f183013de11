#include "dqo_map/objects/object_params.h"
#include "dqo_map/objects/object_types.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <sstream>

namespace dqo::objects {

const char* to_string(DetectionVerdict verdict) {
  switch (verdict) {
    case DetectionVerdict::kAssociated: return "associated";
    case DetectionVerdict::kNewObject: return "new object";
    case DetectionVerdict::kInvalid: return "invalid box";
    case DetectionVerdict::kLowScore: return "low score";
    case DetectionVerdict::kTooSmall: return "too small";
    case DetectionVerdict::kTooLarge: return "too large";
    case DetectionVerdict::kAtBorder: return "at the image border";
    case DetectionVerdict::kDuplicate: return "duplicate";
    case DetectionVerdict::kNoInit: return "no initial ellipsoid";
    case DetectionVerdict::kOverLimit: return "over the per-keyframe limit";
  }
  return "unknown";
}

const char* to_string(AssociationStrategy strategy) {
  switch (strategy) {
    case AssociationStrategy::kIou: return "iou";
    case AssociationStrategy::kQd: return "qd";
    case AssociationStrategy::kIouQd: return "iou+qd";
  }
  return "unknown";
}

bool parse_association_strategy(const std::string& text, AssociationStrategy* strategy) {
  AssociationStrategy s;
  if (text == "iou") {
    s = AssociationStrategy::kIou;
  } else if (text == "qd") {
    s = AssociationStrategy::kQd;
  } else if (text == "iou+qd") {
    s = AssociationStrategy::kIouQd;
  } else {
    return false;
  }
  if (strategy) *strategy = s;
  return true;
}

const char* to_string(FineQuadric source) {
  return source == FineQuadric::kBoxes ? "boxes" : "depth";
}

bool parse_fine_quadric(const std::string& text, FineQuadric* source) {
  FineQuadric s;
  if (text == "boxes") {
    s = FineQuadric::kBoxes;
  } else if (text == "depth") {
    s = FineQuadric::kDepth;
  } else {
    return false;
  }
  if (source) *source = s;
  return true;
}

InstanceImage renumber_instance(const InstanceImage& input, const std::vector<int>& filtered_source) {
  // lookup[k + 1] = j + 1 for the filtered detection j whose source is input detection k.
  int max_source = -1;
  for (const int s : filtered_source) max_source = std::max(max_source, s);
  std::vector<uint16_t> lookup(static_cast<size_t>(std::max(0, max_source + 2)), 0);
  for (size_t j = 0; j < filtered_source.size(); ++j) {
    if (filtered_source[j] >= 0 && j + 1 <= 0xffff) lookup[filtered_source[j] + 1] = static_cast<uint16_t>(j + 1);
  }
  InstanceImage out(input.width, input.height, 1, 0);
  for (size_t i = 0; i < input.data.size() && i < out.data.size(); ++i) {
    const uint16_t v = input.data[i];
    out.data[i] = v < lookup.size() ? lookup[v] : 0;
  }
  return out;
}

double ExistenceParams::recall_of(const std::string& class_name) const {
  const auto it = recall_by_class.find(class_name);
  return it != recall_by_class.end() ? it->second : recall;
}

// Both clamped away from 0 and 1 so that a parameter at a bound never gives an infinite step.
double ExistenceParams::log_odds_detected(const std::string& class_name) const {
  const double r = std::clamp(recall_of(class_name), 1e-3, 1.0 - 1e-3);
  const double f = std::clamp(false_alarm_rate, 1e-3, 1.0 - 1e-3);
  return std::log(r / f);
}

double ExistenceParams::log_odds_missed(const std::string& class_name) const {
  const double r = std::clamp(recall_of(class_name), 1e-3, 1.0 - 1e-3);
  const double f = std::clamp(false_alarm_rate, 1e-3, 1.0 - 1e-3);
  return std::log((1.0 - r) / (1.0 - f));
}

namespace {
std::string trimmed(const std::string& s) {
  size_t a = 0, b = s.size();
  while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) ++a;
  while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) --b;
  return s.substr(a, b - a);
}
}  // namespace

bool parse_recall_by_class(const std::string& text, std::map<std::string, double>* out, std::string* error) {
  std::map<std::string, double> result;
  std::stringstream list(text);
  std::string item;
  while (std::getline(list, item, ',')) {
    if (trimmed(item).empty()) continue;
    const size_t colon = item.rfind(':');
    const std::string name = colon == std::string::npos ? "" : trimmed(item.substr(0, colon));
    const std::string value = colon == std::string::npos ? "" : trimmed(item.substr(colon + 1));
    char* end = nullptr;
    const double r = value.empty() ? NAN : std::strtod(value.c_str(), &end);
    if (name.empty() || end == nullptr || *end != '\0' || !(r > 0.0 && r < 1.0)) {
      if (error) *error = "'" + trimmed(item) + "': expected 'class name: recall' with a recall in (0, 1)";
      return false;
    }
    result[name] = r;
  }
  *out = std::move(result);
  return true;
}

std::string recall_by_class_to_string(const std::map<std::string, double>& recall) {
  std::ostringstream s;
  s.precision(17);
  bool first = true;
  for (const auto& [name, r] : recall) {
    s << (first ? "" : ", ") << name << ": " << r;
    first = false;
  }
  return s.str();
}

std::vector<ClassShare> top_classes(const MapObject& object, int max, const std::map<int, std::string>& names) {
  double total = 0.0;
  std::vector<ClassShare> all;
  for (const auto& [class_id, votes] : object.class_votes) {
    total += votes;
    ClassShare c;
    c.class_id = class_id;
    c.share = votes;
    const auto n = names.find(class_id);
    c.class_name = n != names.end() ? n->second : class_id == object.class_id ? object.class_name : "";
    all.push_back(c);
  }
  std::stable_sort(all.begin(), all.end(), [](const ClassShare& a, const ClassShare& b) { return a.share > b.share; });
  if (max >= 0 && static_cast<int>(all.size()) > max) all.resize(static_cast<size_t>(max));
  for (ClassShare& c : all) c.share = total > 0.0 ? c.share / total : 0.0;
  return all;
}

double existence_probability(const MapObject& object) {
  return 1.0 / (1.0 + std::exp(-object.existence));
}

}  // namespace dqo::objects
