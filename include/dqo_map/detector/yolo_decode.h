#pragma once
// Stage: the raw detection output of a YOLO model (yolo_layout.h) into scored boxes, then per-class
// non-maximum suppression. Boxes stay in input pixels here; Letterbox::to_source maps them back.
//   YOLOv5: score = objectness · class score, the best class per candidate;
//   YOLOv8 / v10 (one-to-many head): score = the best class score.
// Candidates below `confidence` or of a class switched off are dropped before the NMS.

#include <cstdint>
#include <vector>

#include "dqo_map/detector/yolo_layout.h"
#include "dqo_map/geometry/box2d.h"

namespace dqo::detector {

struct DecodeParams {
  float confidence = 0.25f;          // score threshold
  float nms_iou = 0.45f;             // boxes of one class overlapping more than this: the best stays
  int max_detections = 100;          // after NMS, the best first
  std::vector<uint8_t> class_enabled;  // per class ID: 0 drops it; empty: every class
};

struct Candidate {
  int index = 0;  // the candidate's position in the output (for its mask coefficients)
  int class_id = 0;
  float score = 0.f;
  Box2d box;  // input pixels
};

// `data`: the detection output (num_candidates · values_per_candidate floats, in the layout's order).
std::vector<Candidate> decode_candidates(const float* data, const OutputLayout& layout, const DecodeParams& params);

// Class-aware NMS (OpenCV's NMSBoxes per class), the survivors by falling score (ties: by index),
// at most max_detections of them.
std::vector<Candidate> non_max_suppression(const std::vector<Candidate>& candidates, const DecodeParams& params);

}  // namespace dqo::detector
