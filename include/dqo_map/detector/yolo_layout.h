#pragma once
// Stage: which YOLO export a model is, from the shapes of its outputs (and the `layout` parameter):
//   YOLOv5        [1, N, 5 + nc (+ nm)]   rows of cx cy w h objectness, class scores (mask coefficients)
//   YOLOv8 / v11  [1, 4 + nc (+ nm), N]   columns of cx cy w h, class scores (mask coefficients)
//   YOLOv10       as YOLOv8 when exported with the one-to-many head (NMS in the node); its NMS-free
//                 export ([1, 300, 6] after a TopK layer) is refused
//   YOLOX         [1, N, 5 + nc]          raw export (Megvii's tools/export_onnx.py): one row per grid
//                                         point of strides 8, 16, 32 (N = G below), dx dy lw lh obj
//                                         classes; the box still to decode: cx = (dx + gx) s,
//                                         w = exp(lw) s
//   -seg          a second output [1, nm, H/4, W/4]: the mask prototypes
// Box coordinates are input pixels of the letterboxed image. The number of classes is what the shape
// leaves after the box, objectness and mask columns; it must equal the class names' count.
//
// [1, N, 5 + nc] is both YOLOv5's and YOLOX's shape: N tells them apart, given the input size W x H.
// With G = sum over s in {8, 16, 32} of (H / s)(W / s) grid points, YOLOv5 has 3 anchors per point
// (N = 3 G; its P6 models add stride 64), YOLOX one (N = G). An N that is neither is refused under
// `auto`: set the layout. A YOLOX export with decoded boxes (decode_in_inference) has YOLOX's N
// but YOLOv5's box columns; its outputs, not its shape, show that (check_output below).

#include <string>
#include <vector>

namespace dqo::detector {

enum class YoloLayout { kAuto, kV5, kV8, kV10, kX };

bool parse_yolo_layout(const std::string& text, YoloLayout* out);  // auto, v5, v8, v11, v10, yolox
const char* to_string(YoloLayout layout);

struct OutputLayout {
  YoloLayout layout = YoloLayout::kAuto;  // resolved: kV5, kV8, kV10 or kX
  int detection_output = 0;               // index among the model's outputs
  int proto_output = -1;                  // -seg models: the prototypes' output; -1: none
  int num_candidates = 0;
  int num_classes = 0;
  int mask_dim = 0;  // mask coefficients per candidate (-seg), 0 otherwise
  int proto_height = 0, proto_width = 0;
  int input_width = 0, input_height = 0;  // the network's input (YOLOX: its grid)

  bool channels_first() const { return layout == YoloLayout::kV8 || layout == YoloLayout::kV10; }  // [1, C, N]
  bool objectness() const { return layout == YoloLayout::kV5 || layout == YoloLayout::kX; }
  bool grid_offsets() const { return layout == YoloLayout::kX; }  // boxes relative to their grid point
  int values_per_candidate() const { return (objectness() ? 5 : 4) + num_classes + mask_dim; }
  // "YOLOv8 layout, 8400 candidates, 80 classes, 32 mask coefficients on 160x160 prototypes"
  std::string describe() const;
};

// The strides of YOLOX's (and YOLOv5's) heads and their grid points at an input size: G above.
constexpr int kGridStrides[] = {8, 16, 32};
int grid_points(int input_width, int input_height);

// Candidate j of a YOLOX output: its grid point (gx, gy) and stride. False for j out of range.
bool grid_cell(const OutputLayout& layout, int j, int* gx, int* gy, int* stride);

// Output shapes as the model gives them (a leading batch of 1 may be absent), the network's input
// size (a multiple of 32). expected_classes: the class names' count (0: unknown; then the shape
// decides alone: fewer rows than columns is YOLOv8). False with *error when the outputs match no
// layout, the requested layout does not fit them, the class count differs from expected_classes,
// or (auto) a [1, N, 5 + nc] output's N is neither YOLOv5's nor YOLOX's at this input size.
bool identify_layout(const std::vector<std::vector<int>>& output_shapes, YoloLayout wanted, int expected_classes,
                     int input_width, int input_height, OutputLayout* out, std::string* error);

std::string shape_to_string(const std::vector<int>& shape);  // "[1, 84, 8400]"

}  // namespace dqo::detector
