#pragma once
// Stage: the raw detection output of a YOLO model (yolo_layout.h) into scored boxes, then per-class
// non-maximum suppression. Boxes stay in input pixels here; Letterbox::to_source maps them back.
//   YOLOv5: score = objectness · class score, the best class per candidate;
//   YOLOv8 / v10 (one-to-many head): score = the best class score;
//   YOLOX: as YOLOv5, the box decoded from its grid point (yolo_layout.h).
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

// Candidate j's box in input pixels, decoded as the layout says.
Box2d candidate_box(const float* data, const OutputLayout& layout, int j);

// Whether a detection output read in `layout` looks like boxes at all (on any image a trained model
// places its candidates' centres over the input, one near each grid point or anchor): every value
// finite, scores within [0, 1], at least half the candidates of positive size with their centres
// inside the input, and the centres spread over at least a quarter of its width and height. What
// it catches: outputs read in the wrong layout (YOLOX's grid offsets read as pixels put every
// centre in the top-left corner), exports without the final sigmoid, NaN. False with *error
// saying what was seen.
bool check_output(const float* data, const OutputLayout& layout, std::string* error);

// `data`: the detection output (num_candidates · values_per_candidate floats, in the layout's order).
std::vector<Candidate> decode_candidates(const float* data, const OutputLayout& layout, const DecodeParams& params);

// Class-aware NMS (OpenCV's NMSBoxes per class), the survivors by falling score (ties: by index),
// at most max_detections of them.
std::vector<Candidate> non_max_suppression(const std::vector<Candidate>& candidates, const DecodeParams& params);

}  // namespace dqo::detector
