#pragma once
// Stage: the letterbox of YOLO pre-processing and its inverse. The image is scaled by one factor to
// fit the network's input, r = min(W_in / w, H_in / h), and placed on a grey border, either
//   centred (Ultralytics' LetterBox, YOLOv5/v8/v10): resized size round(w r) × round(h r), the
//     padding split as round(d − 0.1) before and the rest after; or
//   top-left (YOLOX's preproc): resized size int(w r) × int(h r), all padding right and below.
// Boxes and mask samples the network gives in input pixels map back to the image by
// x = (x_in − pad_left) / r (pad_left = pad_top = 0 top-left). Pure arithmetic: the resize itself
// is in yolo_input.cpp (OpenCV).

#include "dqo_map/geometry/box2d.h"

namespace dqo::detector {

struct Letterbox {
  int source_width = 0, source_height = 0;  // the image
  int input_width = 0, input_height = 0;    // the network's input
  double scale = 1.0;                       // input pixels per image pixel
  int resized_width = 0, resized_height = 0;
  int pad_left = 0, pad_top = 0;

  // Throws std::invalid_argument for a size <= 0.
  static Letterbox make(int source_width, int source_height, int input_width, int input_height,
                        bool top_left = false);

  double to_source_x(double x_in) const { return (x_in - pad_left) / scale; }
  double to_source_y(double y_in) const { return (y_in - pad_top) / scale; }
  double to_input_x(double x) const { return x * scale + pad_left; }
  double to_input_y(double y) const { return y * scale + pad_top; }
  // A box in input pixels as a box of the image, clipped to it.
  Box2d to_source(const Box2d& box_in) const;
};

}  // namespace dqo::detector
