#include "dqo_map/objects/object_params.h"
#include "dqo_map/objects/object_types.h"

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

}  // namespace dqo::objects
