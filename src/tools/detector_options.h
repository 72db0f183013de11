#pragma once
// The detector options shared by dqo_detect and dqo_map_offline --model:
//   --model M.onnx  --classes names.txt  --input-size WxH  --layout auto|v5|v8|v11|v10|yolox
//   --channel-order auto|rgb|bgr  --input-scale auto|1|1/255  --letterbox auto|centre|top_left
//   --confidence C  --nms-iou T  --keep name,name  --ignore name,name
// The class names default to the source tree's config/coco.names (COCO's 80, the Ultralytics order).

#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <string>

#include "dqo_map/common/text_util.h"
#include "dqo_map/detector/yolo_detector.h"

namespace dqo::tools {

constexpr char kDetectorUsage[] =
    "  --model M.onnx     a YOLO model exported to ONNX (v5, v8/v11, v10 with the one-to-many head, -seg;\n"
    "                     YOLOX's raw export)\n"
    "  --classes FILE     class names, one per line in the model's order (default: COCO's, config/coco.names)\n"
    "  --input-size WxH   the size the model was exported with (default 640x640; YOLOX-Nano/Tiny: 416x416)\n"
    "  --layout L         auto (from the output shapes and the input size), v5, v8, v11, v10 or yolox\n"
    "  --channel-order O, --input-scale S, --letterbox P: the model's input convention, by default the\n"
    "                     layout's (rgb, 1/255, centre; yolox: bgr, 1, top_left)\n"
    "  --confidence C     score threshold (default 0.25); --nms-iou T: NMS overlap (default 0.45)\n"
    "  --keep a,b         only these classes (by name); --ignore a,b: not these\n";

inline std::string default_class_names() {
#ifdef DQO_SOURCE_DIR
  const std::string shipped = DQO_SOURCE_DIR "/config/coco.names";
  std::error_code ec;
  if (std::filesystem::is_regular_file(shipped, ec)) return shipped;
#endif
  return "coco.names";
}

// argv[*i] is one of the options above: takes its value (advancing *i) into *p and returns true;
// *error is set when the value is missing or malformed. False when argv[*i] is none of them.
inline bool parse_detector_option(int argc, char** argv, int* i, detector::YoloParams* p, std::string* error) {
  const std::string a = argv[*i];
  static const char* const kNames[] = {"--model",        "--classes",     "--input-size", "--layout",
                                       "--channel-order", "--input-scale", "--letterbox",  "--confidence",
                                       "--nms-iou",       "--keep",        "--ignore"};
  bool known = false;
  for (const char* n : kNames) known = known || a == n;
  if (!known) return false;
  if (*i + 1 >= argc) {
    *error = a + " needs a value";
    return true;
  }
  const std::string v = argv[++*i];
  char* end = nullptr;
  if (a == "--model") {
    p->model = v;
  } else if (a == "--classes") {
    p->classes = v;
  } else if (a == "--input-size") {
    int w = 0, h = 0;
    char x = 0;
    std::istringstream s(v);
    if (!(s >> w >> x >> h) || x != 'x' || !s.eof() || w <= 0 || h <= 0) *error = "--input-size takes WxH, e.g. 640x640";
    p->input_width = w, p->input_height = h;
  } else if (a == "--layout") {
    if (!detector::parse_yolo_layout(v, &p->layout)) *error = "--layout is auto, v5, v8, v11, v10 or yolox, not " + v;
  } else if (a == "--channel-order") {
    if (!detector::parse_channel_order(v, &p->input.channels)) *error = "--channel-order is auto, rgb or bgr, not " + v;
  } else if (a == "--input-scale") {
    if (!detector::parse_input_scale(v, &p->input.scale)) *error = "--input-scale is auto, 1, 1/255 or a number > 0, not " + v;
  } else if (a == "--letterbox") {
    if (!detector::parse_pad_placement(v, &p->input.pad)) *error = "--letterbox is auto, centre or top_left, not " + v;
  } else if (a == "--confidence" || a == "--nms-iou") {
    const double d = std::strtod(v.c_str(), &end);
    if (end == v.c_str() || *end != '\0' || !(d >= 0.0 && d <= 1.0)) *error = a + " takes a number in [0, 1]";
    (a == "--confidence" ? p->confidence : p->nms_iou) = static_cast<float>(d);
  } else if (a == "--keep") {
    p->keep_classes = text::split_list(v);
  } else {
    p->ignore_classes = text::split_list(v);
  }
  return true;
}

}  // namespace dqo::tools
