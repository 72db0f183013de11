#include "dqo_map/detector/yolo_layout.h"

#include <sstream>

namespace dqo::detector {

bool parse_yolo_layout(const std::string& text, YoloLayout* out) {
  if (text == "auto") *out = YoloLayout::kAuto;
  else if (text == "v5") *out = YoloLayout::kV5;
  else if (text == "v8" || text == "v11") *out = YoloLayout::kV8;
  else if (text == "v10") *out = YoloLayout::kV10;
  else if (text == "yolox") *out = YoloLayout::kX;
  else return false;
  return true;
}

const char* to_string(YoloLayout layout) {
  switch (layout) {
    case YoloLayout::kAuto: return "auto";
    case YoloLayout::kV5: return "v5";
    case YoloLayout::kV8: return "v8";
    case YoloLayout::kV10: return "v10";
    case YoloLayout::kX: return "yolox";
  }
  return "?";
}

std::string shape_to_string(const std::vector<int>& shape) {
  std::ostringstream s;
  s << '[';
  for (size_t i = 0; i < shape.size(); ++i) s << (i ? ", " : "") << shape[i];
  s << ']';
  return s.str();
}

std::string OutputLayout::describe() const {
  std::ostringstream s;
 s << (layout == YoloLayout::kV5    ? "YOLOv5"
        : layout == YoloLayout::kV10 ? "YOLOv10 (one-to-many head)"
        : layout == YoloLayout::kX   ? "YOLOX (raw: boxes as offsets on the stride 8/16/32 grids)"
                                     : "YOLOv8/v11")
    << " layout, " << num_candidates << " candidates, " << num_classes << " classes";
  if (mask_dim > 0) s << ", " << mask_dim << " mask coefficients on " << proto_width << "x" << proto_height << " prototypes";
  return s.str();
}

int grid_points(int input_width, int input_height) {
  int g = 0;
  for (const int s : kGridStrides) g += (input_width / s) * (input_height / s);
  return g;
}

bool grid_cell(const OutputLayout& layout, int j, int* gx, int* gy, int* stride) {
  if (j < 0) return false;
  for (const int s : kGridStrides) {  // the levels one after another, each row-major
    const int w = layout.input_width / s, h = layout.input_height / s;
    if (j < w * h) {
      *gx = j % w, *gy = j / w, *stride = s;
      return true;
    }
    j -= w * h;
  }
  return false;
}

namespace {

bool fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return false;
}

// Without a leading batch of 1.
std::vector<int> unbatched(const std::vector<int>& shape) {
  if (!shape.empty() && shape[0] == 1 && shape.size() >= 3) return {shape.begin() + 1, shape.end()};
  return shape;
}

}  // namespace

bool identify_layout(const std::vector<std::vector<int>>& output_shapes, YoloLayout wanted, int expected_classes,
                     int input_width, int input_height, OutputLayout* out, std::string* error) {
  std::string shapes;
  for (const auto& s : output_shapes) shapes += (shapes.empty() ? "" : ", ") + shape_to_string(s);
  const std::string what = "outputs " + shapes;
  int det = -1, proto = -1;
  for (size_t i = 0; i < output_shapes.size(); ++i) {
    const std::vector<int> s = unbatched(output_shapes[i]);
    if (s.size() == 2 && det < 0) det = static_cast<int>(i);
    else if (s.size() == 3 && proto < 0) proto = static_cast<int>(i);
    else return fail(error, what + " match no YOLO export (one [1, A, B] detection output, and [1, nm, h, w] "
                                   "prototypes for -seg models)");
  }
  if (det < 0) return fail(error, what + " have no [1, A, B] detection output: not a YOLO detection model");
  const std::vector<int> d = unbatched(output_shapes[det]);
  OutputLayout l;
  l.detection_output = det;
  l.input_width = input_width;
  l.input_height = input_height;
  if (proto >= 0) {
    const std::vector<int> p = unbatched(output_shapes[proto]);
    l.proto_output = proto;
    l.mask_dim = p[0];
    l.proto_height = p[1];
    l.proto_width = p[2];
  }
  const int a = d[0], b = d[1];
  const int classes_v8 = a - 4 - l.mask_dim, classes_v5 = b - 5 - l.mask_dim;
  // YOLOv10's NMS-free export: [1, 300, 6] = x1 y1 x2 y2 score class, after a TopK layer (which
  // OpenCV 4.6 cannot load, so this is for runtimes that can).
  const bool fits_v8 = classes_v8 >= 1 && (expected_classes <= 0 || classes_v8 == expected_classes);
  const bool fits_v5 = classes_v5 >= 1 && (expected_classes <= 0 || classes_v5 == expected_classes);
  const bool nms_free = proto < 0 && b == 6 &&
                        ((wanted == YoloLayout::kV10 && !fits_v8) || (wanted == YoloLayout::kAuto && !fits_v8 && !fits_v5));
  if (nms_free) {
    return fail(error, what + " look like YOLOv10's NMS-free export (boxes, score, class per row): export it with "
                              "the one-to-many head instead (README: the detector)");
  }
  // Rows of 5 + nc: YOLOv5 or YOLOX, by the number of rows at this input size.
  const int g = grid_points(input_width, input_height);
  const int g64 = input_width % 64 == 0 && input_height % 64 == 0 ? (input_width / 64) * (input_height / 64) : -1;
  const bool rows_v5 = a == 3 * g || (g64 > 0 && a == 3 * (g + g64));  // 3 anchors per point (P6: + stride 64)
  const bool rows_x = a == g;
  const std::string size = std::to_string(input_width) + "x" + std::to_string(input_height);
  YoloLayout chosen = wanted;
  if (wanted == YoloLayout::kAuto) {
    if (fits_v8 && fits_v5) chosen = a < b ? YoloLayout::kV8 : YoloLayout::kV5;  // exports have N >> classes
    else if (fits_v8) chosen = YoloLayout::kV8;
    else if (fits_v5) chosen = YoloLayout::kV5;
    else if (classes_v8 < 1 && classes_v5 < 1)
      return fail(error, what + " are too small for any YOLO layout");
    else
      chosen = a < b ? YoloLayout::kV8 : YoloLayout::kV5;  // for the message below
    if (chosen == YoloLayout::kV5 && rows_x) {
      chosen = YoloLayout::kX;
    } else if (chosen == YoloLayout::kV5 && !rows_v5 && fits_v5) {
      return fail(error, what + ": " + std::to_string(a) + " rows of " + std::to_string(b) +
                             " values fit neither YOLOv5 at input " + size + " (3 anchors x " + std::to_string(g) +
                             " grid points = " + std::to_string(3 * g) + " rows) nor YOLOX (" + std::to_string(g) +
                             " rows): check input_size (the size the model was exported with) or set layout "
                             "(v5 or yolox)");
    }
  }
  if (chosen == YoloLayout::kX && proto >= 0) {
    return fail(error, what + ": YOLOX has no mask prototypes (no -seg export); set layout to the model's family");
  }
  if (chosen == YoloLayout::kX && a != g) {
    return fail(error, what + " do not fit the yolox layout at input " + size + ": YOLOX's output has one row per " +
                           "grid point of strides 8, 16, 32, " + std::to_string(g) +
                           " rows (check input_size, the size the model was exported with)");
  }
  l.layout = chosen;
  if (chosen == YoloLayout::kV5 || chosen == YoloLayout::kX) {
    l.num_candidates = a;
    l.num_classes = classes_v5;
  } else {
    l.num_candidates = b;
    l.num_classes = classes_v8;
  }
  if (l.num_classes < 1 || l.num_candidates < 1) {
    return fail(error, what + " do not fit the " + std::string(to_string(chosen)) + " layout");
  }
  if (expected_classes > 0 && l.num_classes != expected_classes) {
    return fail(error, "the class-names file has " + std::to_string(expected_classes) + " names but the model (" +
                           what + ", " + l.describe() + ") scores " + std::to_string(l.num_classes) +
                           " classes: give the names file the model was trained with (or set layout)");
  }
  *out = l;
  return true;
}

}  // namespace dqo::detector
