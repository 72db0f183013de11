#pragma once
// Stage: instance masks of a -seg model. A detection's mask is σ(Σ_m c_m P_m), its coefficients c
// (from its candidate's row) over the prototypes P ([nm, H/4, W/4], input image / 4), sampled
// bilinearly at each image pixel's place in the input (through the letterbox) and kept where it
// exceeds the threshold inside the detection's box, as Ultralytics crops it. Into one instance image
// of the source's size, value k + 1 = detection k; where masks overlap the higher-scoring detection
// takes the pixel (detections come best first).

#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/detector/letterbox.h"
#include "dqo_map/detector/yolo_decode.h"

namespace dqo::detector {

// detection_output and protos: the model's two outputs; kept: the detections (input-pixel boxes) in
// the order their numbers go, best first.
InstanceImage instance_from_masks(const float* detection_output, const float* protos, const OutputLayout& layout,
                                  const std::vector<Candidate>& kept, const Letterbox& letterbox, float threshold);

}  // namespace dqo::detector
