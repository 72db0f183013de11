#include "dqo_map/detector/yolo_detector.h"

#include <chrono>
#include <filesystem>
#include <set>
#include <stdexcept>

#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>

#include "dqo_map/detector/class_names.h"
#include "dqo_map/detector/letterbox.h"
#include "dqo_map/detector/yolo_masks.h"

namespace dqo::detector {

struct YoloDetector::Impl {
  YoloParams params;
  std::vector<std::string> names;
  OutputLayout layout;
  DecodeParams decode;
  cv::dnn::Net net;
  std::vector<std::string> output_names;
  cv::Mat input;  // letterboxed image, reused
};

namespace {

std::unique_ptr<YoloDetector> fail(std::string* error, const std::string& message) {
  if (error) *error = message;
  return nullptr;
}

double ms_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

// OpenCV's messages run over several lines with the source position first: the last line says it.
std::string opencv_reason(const cv::Exception& e) {
  std::string m = e.err.empty() ? e.what() : e.err;
  while (!m.empty() && (m.back() == '\n' || m.back() == ' ')) m.pop_back();
  return m;
}

// The letterboxed image as the network's input blob: RGB, [0, 1], NCHW.
cv::Mat make_blob(const cv::Mat& rgb, const Letterbox& l, cv::Mat* canvas) {
  canvas->create(l.input_height, l.input_width, CV_8UC3);
  canvas->setTo(cv::Scalar(114, 114, 114));
  cv::Mat roi = (*canvas)(cv::Rect(l.pad_left, l.pad_top, l.resized_width, l.resized_height));
  if (l.resized_width == rgb.cols && l.resized_height == rgb.rows)
    rgb.copyTo(roi);
  else
    cv::resize(rgb, roi, roi.size(), 0, 0, cv::INTER_LINEAR);
  return cv::dnn::blobFromImage(*canvas, 1.0 / 255.0, cv::Size(), cv::Scalar(), /*swapRB=*/false, /*crop=*/false);
}

std::vector<int> shape_of(const cv::Mat& m) {
  std::vector<int> s;
  for (int d = 0; d < m.dims; ++d) s.push_back(m.size[d]);
  return s;
}

}  // namespace

YoloDetector::YoloDetector(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
YoloDetector::~YoloDetector() = default;

const OutputLayout& YoloDetector::layout() const { return impl_->layout; }
const std::vector<std::string>& YoloDetector::class_names() const { return impl_->names; }
const YoloParams& YoloDetector::params() const { return impl_->params; }

std::unique_ptr<YoloDetector> YoloDetector::create(const YoloParams& params, std::string* error) {
  auto impl = std::make_unique<Impl>();
  impl->params = params;
  if (params.input_width < 32 || params.input_height < 32 || params.input_width % 32 != 0 ||
      params.input_height % 32 != 0) {
    return fail(error, "input size " + std::to_string(params.input_width) + "x" + std::to_string(params.input_height) +
                           ": YOLO inputs are multiples of 32 (the size the model was exported with, e.g. 640x640)");
  }
  if (!(params.confidence >= 0.f && params.confidence <= 1.f) || !(params.nms_iou >= 0.f && params.nms_iou <= 1.f) ||
      !(params.mask_threshold > 0.f && params.mask_threshold < 1.f) || params.max_detections < 1) {
    return fail(error, "confidence and nms_iou must be in [0, 1], mask_threshold in (0, 1), max_detections >= 1");
  }
  // The names first: a wrong names file is cheaper to report than a model to load.
  auto names = read_class_names(params.classes, error);
  if (!names) return nullptr;
  impl->names = std::move(*names);

  std::error_code ec;
  if (params.model.empty()) return fail(error, "no model given (an .onnx file)");
  if (!std::filesystem::is_regular_file(params.model, ec)) return fail(error, params.model + ": model file not found");
  try {
    impl->net = cv::dnn::readNetFromONNX(params.model);
  } catch (const cv::Exception& e) {
    const std::string reason = opencv_reason(e);
    if (reason.find("TopK") != std::string::npos) {
      return fail(error, params.model + ": uses a TopK layer, which OpenCV " CV_VERSION
                                        "'s DNN module lacks: this is YOLOv10's NMS-free export; export the model "
                                        "with the one-to-many head instead (README: the detector)");
    }
    return fail(error, params.model + ": not an ONNX model OpenCV can load: " + reason);
  }
  if (impl->net.empty()) return fail(error, params.model + ": not an ONNX model OpenCV can load (empty network)");
  if (params.cuda) {
    impl->net.setPreferableBackend(cv::dnn::DNN_BACKEND_CUDA);
    impl->net.setPreferableTarget(cv::dnn::DNN_TARGET_CUDA);
  }
  impl->output_names = impl->net.getUnconnectedOutLayersNames();

  // One forward on a grey image: the outputs' shapes say the layout (OpenCV cannot tell them before).
  std::vector<cv::Mat> outputs;
  try {
    const Letterbox l = Letterbox::make(params.input_width, params.input_height, params.input_width, params.input_height);
    cv::Mat grey(params.input_height, params.input_width, CV_8UC3, cv::Scalar(114, 114, 114));
    impl->net.setInput(make_blob(grey, l, &impl->input));
    impl->net.forward(outputs, impl->output_names);
  } catch (const cv::Exception& e) {
    return fail(error, params.model + ": does not run at input " + std::to_string(params.input_width) + "x" +
                           std::to_string(params.input_height) + " (give input_size the size it was exported with): " +
                           opencv_reason(e));
  }
  std::vector<std::vector<int>> shapes;
  for (const cv::Mat& m : outputs) {
    if (m.type() != CV_32F) return fail(error, params.model + ": an output is not float32");
    shapes.push_back(shape_of(m));
  }
  std::string why;
  if (!identify_layout(shapes, params.layout, static_cast<int>(impl->names.size()), &impl->layout, &why)) {
    return fail(error, params.model + ": " + why);
  }

  // Classes to keep or ignore, by name.
  std::set<std::string> known(impl->names.begin(), impl->names.end());
  for (const auto* list : {&params.keep_classes, &params.ignore_classes}) {
    for (const std::string& n : *list) {
      if (!known.count(n)) return fail(error, "class '" + n + "' (keep_classes / ignore_classes) is not in " + params.classes);
    }
  }
  DecodeParams& d = impl->decode;
  d.confidence = params.confidence;
  d.nms_iou = params.nms_iou;
  d.max_detections = params.max_detections;
  if (!params.keep_classes.empty() || !params.ignore_classes.empty()) {
    const std::set<std::string> keep(params.keep_classes.begin(), params.keep_classes.end());
    const std::set<std::string> ignore(params.ignore_classes.begin(), params.ignore_classes.end());
    d.class_enabled.resize(impl->names.size());
    for (size_t c = 0; c < impl->names.size(); ++c) {
      d.class_enabled[c] = (keep.empty() || keep.count(impl->names[c])) && !ignore.count(impl->names[c]);
    }
  }
  return std::unique_ptr<YoloDetector>(new YoloDetector(std::move(impl)));
}

YoloDetections YoloDetector::detect(const ImageRgb8& rgb) {
  if (rgb.empty() || rgb.channels != 3 || rgb.width <= 0 || rgb.height <= 0) {
    throw std::invalid_argument("YoloDetector::detect: expects a non-empty 3-channel RGB image");
  }
  Impl& s = *impl_;
  YoloDetections out;
  auto t = std::chrono::steady_clock::now();
  const Letterbox l = Letterbox::make(rgb.width, rgb.height, s.params.input_width, s.params.input_height);
  const cv::Mat image(rgb.height, rgb.width, CV_8UC3, const_cast<uint8_t*>(rgb.data.data()));
  s.net.setInput(make_blob(image, l, &s.input));
  out.preprocess_ms = ms_since(t);
  t = std::chrono::steady_clock::now();
  std::vector<cv::Mat> outputs;
  s.net.forward(outputs, s.output_names);
  out.inference_ms = ms_since(t);
  t = std::chrono::steady_clock::now();
  const cv::Mat& det = outputs[s.layout.detection_output];
  const float* data = det.ptr<float>();
  const std::vector<Candidate> kept = non_max_suppression(decode_candidates(data, s.layout, s.decode), s.decode);
  for (const Candidate& c : kept) {
    Detection2d d;
    d.class_id = c.class_id;
    d.class_name = s.names[c.class_id];
    d.score = c.score;
    d.box = l.to_source(c.box);
    out.detections.push_back(d);
  }
  if (s.layout.proto_output >= 0) {
    out.instance = instance_from_masks(data, outputs[s.layout.proto_output].ptr<float>(), s.layout, kept, l,
                                       s.params.mask_threshold);
  }
  out.decode_ms = ms_since(t);
  return out;
}

}  // namespace dqo::detector
