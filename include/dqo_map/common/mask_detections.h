#pragma once
// Detections from an instance mask (DESIGN.md: the node that turns instance masks into detections,
// for datasets that have masks and no detector; the offline runner's ground-truth object stage).
// One box per instance label, the instance image
// renumbered as a DetectionArray's (value k+1 = detection k), a class from a table keyed by label.
//
// Labels are plain integers: a mono8/mono16 mask's value, or a colour-coded mask's colour packed as
// (r << 16) | (g << 8) | b (pack_rgb). Label 0 (black) is "no instance". Decoding message bytes
// into labels is the node's job (src/ros); this part is Eigen/std only.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "dqo_map/common/dataset.h"
#include "dqo_map/common/image.h"

namespace dqo {

inline uint32_t pack_rgb(uint8_t r, uint8_t g, uint8_t b) {
  return (static_cast<uint32_t>(r) << 16) | (static_cast<uint32_t>(g) << 8) | b;
}

struct MaskClass {
  int class_id = 0;
  std::string class_name;
};

struct MaskDetectionParams {
  std::map<uint32_t, MaskClass> classes;  // label -> class
  // Labels missing from `classes`: skipped, or given default_class (a mask without a table still
  // yields boxes, e.g. to test association on class-agnostic instances).
  bool skip_unknown = false;
  MaskClass default_class{0, "object"};
  // Instances with fewer pixels are dropped: a few stray pixels of an anti-aliased or resized mask
  // would otherwise become detections.
  int min_pixels = 20;
  float score = 1.0f;  // masks are ground truth, or a segmenter's output already thresholded
};

struct MaskDetections {
  // Ascending by label (deterministic order). Boxes enclose the instance's pixels in continuous
  // coordinates ([u - 0.5, u + 0.5] per pixel, clipped to the image), as sim/ builds its boxes.
  std::vector<Detection2d> detections;
  std::vector<uint32_t> labels;   // [detection] the mask label it came from
  std::vector<int> pixel_counts;  // [detection]
  InstanceImage instance;         // mask size; k+1 where detection k, 0 elsewhere (dropped too)
  int dropped_small = 0;          // instances below min_pixels
  int dropped_unknown = 0;        // instances not in the table (skip_unknown)
  int dropped_too_many = 0;       // beyond 65535 kept instances (a uint16 image cannot number them)
};

// A uint16 instance image (a dataset's ground-truth IDs) as mask labels.
LabelImage mask_labels(const InstanceImage& instance);

// One pass over the mask plus one per kept instance count; labels.channels must be 1 (an empty
// result otherwise). Instances beyond 65535 (highest labels) are dropped and counted.
MaskDetections detections_from_mask(const LabelImage& labels, const MaskDetectionParams& params);

// The instance image of a keyframe's detections (value j+1 = detection j) from a ground-truth
// instance image (object IDs): detection j takes the pixels of the ground-truth object it came from
// (its gt_id, else the ID with most pixels in its box); where two claim one, the higher score wins.
// What a segmenting detector gives; the offline runner's --labels masks and the synthetic bags'
// detections (dqo_make_scene --masks) both make it here.
InstanceImage instance_for_detections(const InstanceImage& gt_instance,
                                      const std::vector<Detection2d>& detections);

}  // namespace dqo
