#pragma once
// A YOLO model (ONNX) run through OpenCV's DNN module: letterbox, inference, decoding, NMS and, for
// -seg models, the instance masks. Everything that can be wrong with a model shows at create():
// a missing file, a file that is not ONNX, a layer OpenCV lacks (YOLOv10's NMS-free TopK), an
// input size the model does not take, an output layout that matches no export, a class-names file
// of the wrong length, classes to keep or ignore that it does not name, and an output that is not
// boxes when read in the layout chosen (check_output on a first inference of a grey image: NaN,
// scores outside [0, 1], centres that do not cover the input). OpenCV stays in the .cpp.
// Not thread-safe (one network): one caller at a time.

#include <memory>
#include <string>
#include <vector>

#include "dqo_map/common/dataset.h"
#include "dqo_map/common/image.h"
#include "dqo_map/detector/yolo_decode.h"
#include "dqo_map/detector/yolo_input.h"
#include "dqo_map/detector/yolo_layout.h"

namespace dqo::detector {

struct YoloParams {
  std::string model;    // the .onnx file
  std::string classes;  // class-names file (class_names.h)
  int input_width = 640, input_height = 640;  // the size the model was exported for
  YoloLayout layout = YoloLayout::kAuto;
  InputConvention input;  // channel order, scale, letterbox placement; kAuto: the layout's (yolo_input.h)
  float confidence = 0.25f;
  float nms_iou = 0.45f;
  int max_detections = 100;
  float mask_threshold = 0.5f;
  // By name; empty keep: every class. A class in both lists is ignored.
  std::vector<std::string> keep_classes, ignore_classes;
  bool cuda = false;  // OpenCV DNN's CUDA backend (OpenCV must be built with it; Debian's is not)
};

struct YoloDetections {
  std::vector<Detection2d> detections;  // best first, boxes in image pixels (clipped)
  InstanceImage instance;               // -seg: k + 1 = detection k; empty otherwise
  double preprocess_ms = 0.0, inference_ms = 0.0, decode_ms = 0.0;
};

class YoloDetector {
 public:
  // nullptr and *error (one line saying what to do) when the model cannot be used.
  static std::unique_ptr<YoloDetector> create(const YoloParams& params, std::string* error);
  ~YoloDetector();
  YoloDetector(const YoloDetector&) = delete;
  YoloDetector& operator=(const YoloDetector&) = delete;

  // Throws std::invalid_argument for an image that is not 3-channel or is empty.
  YoloDetections detect(const ImageRgb8& rgb);

  const OutputLayout& layout() const;
  const InputConvention& input_convention() const;  // resolved
  const std::vector<std::string>& class_names() const;
  bool segments() const { return layout().proto_output >= 0; }
  const YoloParams& params() const;

 private:
  struct Impl;
  explicit YoloDetector(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace dqo::detector
