#pragma once
// Stage: which YOLO export a model is, from the shapes of its outputs (and the `layout` parameter):
//   YOLOv5        [1, N, 5 + nc (+ nm)]   rows of cx cy w h objectness, class scores (mask coefficients)
//   YOLOv8 / v11  [1, 4 + nc (+ nm), N]   columns of cx cy w h, class scores (mask coefficients)
//   YOLOv10       as YOLOv8 when exported with the one-to-many head (NMS in the node); its NMS-free
//                 export ([1, 300, 6] after a TopK layer) is refused
//   -seg          a second output [1, nm, H/4, W/4]: the mask prototypes
// Box coordinates are input pixels of the letterboxed image. The number of classes is what the shape
// leaves after the box, objectness and mask columns; it must equal the class names' count.

#include <string>
#include <vector>

namespace dqo::detector {

enum class YoloLayout { kAuto, kV5, kV8, kV10 };

bool parse_yolo_layout(const std::string& text, YoloLayout* out);  // auto, v5, v8, v11, v10
const char* to_string(YoloLayout layout);

struct OutputLayout {
  YoloLayout layout = YoloLayout::kAuto;  // resolved: kV5, kV8 or kV10
  int detection_output = 0;               // index among the model's outputs
  int proto_output = -1;                  // -seg models: the prototypes' output; -1: none
  int num_candidates = 0;
  int num_classes = 0;
  int mask_dim = 0;  // mask coefficients per candidate (-seg), 0 otherwise
  int proto_height = 0, proto_width = 0;

  bool channels_first() const { return layout != YoloLayout::kV5; }  // [1, C, N]
  bool objectness() const { return layout == YoloLayout::kV5; }
  int values_per_candidate() const { return (objectness() ? 5 : 4) + num_classes + mask_dim; }
  // "YOLOv8 layout, 8400 candidates, 80 classes, 32 mask coefficients on 160x160 prototypes"
  std::string describe() const;
};

// Output shapes as the model gives them (a leading batch of 1 may be absent). expected_classes:
// the class names' count (0: unknown; then the shape decides alone: fewer rows than columns is
// YOLOv8). False with *error when the outputs match no layout, the requested layout does not fit
// them, or the class count differs from expected_classes.
bool identify_layout(const std::vector<std::vector<int>>& output_shapes, YoloLayout wanted, int expected_classes,
                     OutputLayout* out, std::string* error);

std::string shape_to_string(const std::vector<int>& shape);  // "[1, 84, 8400]"

}  // namespace dqo::detector
