#pragma once
// Detections simulated from a frame's ground truth (the visible boxes), with detector-like noise.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "dqo_map/common/dataset.h"
#include "dqo_map/sim/noise.h"

namespace dqo::sim {

struct DetectionContext {
  int width = 0;  // image size, to clip boxes
  int height = 0;
  std::map<uint32_t, int> class_of_object;  // ground-truth object ID -> class ID
  std::map<int, std::string> class_names;   // the scene's classes (confusions and false positives
                                            // draw from it)
};

// One detection per ground-truth object in frame.objects that passes the visibility thresholds
// (a "detectable" object), in ascending ID order, with gt_id set. With `noise`: each detectable
// object is missed with miss_rate, otherwise its class is confused with confusion_rate, each box
// edge jittered by box_jitter_px (then clipped to the image) and a score drawn in [0.5, 1]; and,
// missed or not, it brings a false positive (gt_id 0, random class, random box, score in
// [0.3, 0.8]) with false_positive_rate. Without: the exact visible boxes with score 1.
// Deterministic in (seed, frame.index).
std::vector<Detection2d> simulate_detections(const Frame& frame, const DetectionContext& context,
                                             const DetectionNoiseParams& params, bool noise,
                                             uint64_t seed);

}  // namespace dqo::sim
