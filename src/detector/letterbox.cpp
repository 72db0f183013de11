#include "dqo_map/detector/letterbox.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace dqo::detector {

Letterbox Letterbox::make(int source_width, int source_height, int input_width, int input_height, bool top_left) {
  if (source_width <= 0 || source_height <= 0 || input_width <= 0 || input_height <= 0) {
    throw std::invalid_argument("Letterbox: sizes must be positive");
  }
  Letterbox l;
  l.source_width = source_width;
  l.source_height = source_height;
  l.input_width = input_width;
  l.input_height = input_height;
  l.scale = std::min(static_cast<double>(input_width) / source_width,
                     static_cast<double>(input_height) / source_height);
  if (top_left) {  // YOLOX: int(w * r), the image in the top-left corner
    l.resized_width = std::clamp(static_cast<int>(source_width * l.scale), 1, input_width);
    l.resized_height = std::clamp(static_cast<int>(source_height * l.scale), 1, input_height);
    return l;
  }
  l.resized_width = std::min(input_width, static_cast<int>(std::lround(source_width * l.scale)));
  l.resized_height = std::min(input_height, static_cast<int>(std::lround(source_height * l.scale)));
  // Ultralytics splits the padding as round(d - 0.1) before, the rest after.
  const double dw = 0.5 * (input_width - l.resized_width), dh = 0.5 * (input_height - l.resized_height);
  l.pad_left = static_cast<int>(std::lround(dw - 0.1));
  l.pad_top = static_cast<int>(std::lround(dh - 0.1));
  return l;
}

Box2d Letterbox::to_source(const Box2d& box_in) const {
  Box2d b;
  b.x_min = to_source_x(box_in.x_min);
  b.y_min = to_source_y(box_in.y_min);
  b.x_max = to_source_x(box_in.x_max);
  b.y_max = to_source_y(box_in.y_max);
  return b.clip(source_width, source_height);
}

}  // namespace dqo::detector
