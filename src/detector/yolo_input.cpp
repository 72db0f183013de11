#include "dqo_map/detector/yolo_input.h"

#include <cstdlib>
#include <sstream>
#include <stdexcept>

#include <opencv2/core.hpp>
#include <opencv2/dnn.hpp>
#include <opencv2/imgproc.hpp>

namespace dqo::detector {

std::string InputConvention::describe() const {
  std::ostringstream s;
  s << (channels == ChannelOrder::kBgr ? "BGR" : channels == ChannelOrder::kRgb ? "RGB" : "auto") << ", ";
  if (scale == 1.0) s << "0..255";
  else if (std::abs(scale - 1.0 / 255.0) < 1e-12) s << "0..1";
  else if (scale == 0.0) s << "auto scale";
  else s << "x" << scale;
  s << ", " << (pad == PadPlacement::kTopLeft ? "top-left" : pad == PadPlacement::kCentre ? "centred" : "auto")
    << " letterbox (pad " << static_cast<int>(pad_value) << ")";
  return s.str();
}

InputConvention resolve_input_convention(const InputConvention& wanted, YoloLayout layout) {
  const bool yolox = layout == YoloLayout::kX;
  InputConvention c = wanted;
  if (c.channels == ChannelOrder::kAuto) c.channels = yolox ? ChannelOrder::kBgr : ChannelOrder::kRgb;
  if (!(c.scale > 0.0)) c.scale = yolox ? 1.0 : 1.0 / 255.0;
  if (c.pad == PadPlacement::kAuto) c.pad = yolox ? PadPlacement::kTopLeft : PadPlacement::kCentre;
  return c;
}

bool parse_channel_order(const std::string& text, ChannelOrder* out) {
  if (text == "auto") *out = ChannelOrder::kAuto;
  else if (text == "rgb") *out = ChannelOrder::kRgb;
  else if (text == "bgr") *out = ChannelOrder::kBgr;
  else return false;
  return true;
}

bool parse_pad_placement(const std::string& text, PadPlacement* out) {
  if (text == "auto") *out = PadPlacement::kAuto;
  else if (text == "centre" || text == "center") *out = PadPlacement::kCentre;
  else if (text == "top_left") *out = PadPlacement::kTopLeft;
  else return false;
  return true;
}

bool parse_input_scale(const std::string& text, double* out) {
  if (text == "auto") *out = 0.0;
  else if (text == "1/255") *out = 1.0 / 255.0;
  else {
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (end == text.c_str() || *end != '\0' || !(v > 0.0 && v < 1e6)) return false;
    *out = v;
  }
  return true;
}

void make_input_blob(const ImageRgb8& rgb, const Letterbox& l, const InputConvention& c, std::vector<float>* blob) {
  if (rgb.empty() || rgb.channels != 3 || rgb.width != l.source_width || rgb.height != l.source_height) {
    throw std::invalid_argument("make_input_blob: expects a 3-channel image of the letterbox's source size");
  }
  cv::Mat canvas(l.input_height, l.input_width, CV_8UC3, cv::Scalar::all(c.pad_value));
  const cv::Mat image(rgb.height, rgb.width, CV_8UC3, const_cast<uint8_t*>(rgb.data.data()));
  cv::Mat roi = canvas(cv::Rect(l.pad_left, l.pad_top, l.resized_width, l.resized_height));
  if (l.resized_width == rgb.width && l.resized_height == rgb.height)
    image.copyTo(roi);
  else
    cv::resize(image, roi, roi.size(), 0, 0, cv::INTER_LINEAR);
  blob->resize(static_cast<size_t>(3) * l.input_width * l.input_height);
  const int dims[] = {1, 3, l.input_height, l.input_width};
  cv::Mat out(4, dims, CV_32F, blob->data());  // blobFromImage writes into the caller's memory
  cv::dnn::blobFromImage(canvas, out, c.scale, cv::Size(), cv::Scalar(), /*swapRB=*/c.channels == ChannelOrder::kBgr,
                         /*crop=*/false, CV_32F);
  if (out.data != reinterpret_cast<uchar*>(blob->data())) {  // never expected: OpenCV reallocated
    std::copy(out.ptr<float>(), out.ptr<float>() + blob->size(), blob->begin());
  }
}

}  // namespace dqo::detector
