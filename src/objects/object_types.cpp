#include "dqo_map/objects/object_params.h"
#include "dqo_map/objects/object_types.h"

#include <algorithm>

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

}  // namespace dqo::objects
