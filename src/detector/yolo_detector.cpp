#include "dqo_map/detector/yolo_detector.h"

#include <chrono>
#include <filesystem>
#include <set>
#include <stdexcept>

#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>

#include "dqo_map/detector/class_names.h"
#include "dqo_map/detector/letterbox.h"
#include "dqo_map/detector/yolo_masks.h"

namespace dqo::detector {

struct YoloDetector::Impl {
  YoloParams params;
  std::vector<std::string> names;
  OutputLayout layout;
  InputConvention input;  // resolved
  DecodeParams decode;
  cv::dnn::Net net;
  std::vector<std::string> output_names;
  std::vector<float> blob;  // the input tensor, reused

  // The network on an image; its outputs' memory lives until the next forward.
  void forward(const ImageRgb8& rgb, const Letterbox& l, std::vector<cv::Mat>* outputs) {
    make_input_blob(rgb, l, input, &blob);
    const int dims[] = {1, 3, l.input_height, l.input_width};
    net.setInput(cv::Mat(4, dims, CV_32F, blob.data()));
    net.forward(*outputs, output_names);
  }
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

std::vector<int> shape_of(const cv::Mat& m) {
  std::vector<int> s;
  for (int d = 0; d < m.dims; ++d) s.push_back(m.size[d]);
  return s;
}

}  // namespace

YoloDetector::YoloDetector(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
YoloDetector::~YoloDetector() = default;

const OutputLayout& YoloDetector::layout() const { return impl_->layout; }
const InputConvention& YoloDetector::input_convention() const { return impl_->input; }
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

  // One forward on a grey image: the outputs' shapes say the layout (OpenCV cannot tell them before),
  // then, in the input convention of that layout, their values whether it reads them right.
  const int iw = params.input_width, ih = params.input_height;
  const std::string size = std::to_string(iw) + "x" + std::to_string(ih);
  const ImageRgb8 grey(iw, ih, 3, 114);
  std::vector<cv::Mat> outputs;
  auto probe = [&](std::string* why) {
    try {
      impl->forward(grey, Letterbox::make(iw, ih, iw, ih, impl->input.top_left()), &outputs);
    } catch (const cv::Exception& e) {
      *why = params.model + ": does not run at input " + size + " (give input_size the size it was exported with): " +
             opencv_reason(e);
      return false;
    }
    for (const cv::Mat& m : outputs) {
      if (m.type() != CV_32F) {
        *why = params.model + ": an output is not float32";
        return false;
      }
    }
    return true;
  };
  std::string why;
  impl->input = resolve_input_convention(params.input, params.layout == YoloLayout::kAuto ? YoloLayout::kV8 : params.layout);
  if (!probe(&why)) return fail(error, why);
  std::vector<std::vector<int>> shapes;
  for (const cv::Mat& m : outputs) shapes.push_back(shape_of(m));
  if (!identify_layout(shapes, params.layout, static_cast<int>(impl->names.size()), iw, ih, &impl->layout, &why)) {
    return fail(error, params.model + ": " + why);
  }
  const InputConvention probed = impl->input;
  impl->input = resolve_input_convention(params.input, impl->layout.layout);
  if (impl->input.scale != probed.scale && !probe(&why)) return fail(error, why);  // grey: only the scale tells
  const float* values = outputs[impl->layout.detection_output].ptr<float>();
  if (!check_output(values, impl->layout, &why)) {
    OutputLayout decoded = impl->layout;  // YOLOX's N, decoded boxes: decode_in_inference, or another family
    decoded.layout = YoloLayout::kV5;
    std::string unused;
    if (params.layout == YoloLayout::kAuto && impl->layout.layout == YoloLayout::kX &&
        check_output(values, decoded, &unused)) {
      return fail(error, params.model + ": " + shape_to_string(shapes[impl->layout.detection_output]) +
                             " has one row per grid point as YOLOX's raw output at " + size +
                             ", but its boxes are decoded pixels, not grid offsets (a YOLOX export with "
                             "decode_in_inference, or another anchor-free model): set layout v5 (decoded rows) "
                             "and the input convention the model was trained with (YOLOX: channel_order bgr, "
                             "input_scale 1, letterbox top_left)");
    }
    return fail(error, params.model + ": its output is not what the " + to_string(impl->layout.layout) +
                           " layout gives: " + why + ". Set layout (v5, v8, v11, v10 or yolox, the family the "
                           "model was exported from; --layout for the tools) and input_size");
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
  const Letterbox l =
      Letterbox::make(rgb.width, rgb.height, s.params.input_width, s.params.input_height, s.input.top_left());
  make_input_blob(rgb, l, s.input, &s.blob);
  const int dims[] = {1, 3, l.input_height, l.input_width};
  s.net.setInput(cv::Mat(4, dims, CV_32F, s.blob.data()));
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
