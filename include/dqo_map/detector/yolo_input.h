#pragma once
// Stage: the network's input tensor from an RGB image. How a model wants its input belongs to its
// family, and is chosen with the layout (yolo_layout.h) unless a parameter says otherwise:
//   Ultralytics (YOLOv5, v8/v11, v10): RGB, values / 255, letterbox centred, padding 114;
//   YOLOX (Megvii's preproc):          BGR, values 0..255, letterbox top-left, padding 114.
// A model fed the other family's input still runs, and detects little: no error can show it, so
// the convention is part of the layout rather than a separate guess.

#include <cstdint>
#include <string>
#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/detector/letterbox.h"
#include "dqo_map/detector/yolo_layout.h"

namespace dqo::detector {

enum class ChannelOrder { kAuto, kRgb, kBgr };
enum class PadPlacement { kAuto, kCentre, kTopLeft };

struct InputConvention {
  ChannelOrder channels = ChannelOrder::kAuto;
  double scale = 0.0;  // multiplies the 0..255 values; 0: the layout's
  PadPlacement pad = PadPlacement::kAuto;
  uint8_t pad_value = 114;

  bool top_left() const { return pad == PadPlacement::kTopLeft; }
  // "BGR, 0..255, top-left letterbox (pad 114)"
  std::string describe() const;
};

// `wanted` with its kAuto / 0 fields replaced by the family's convention of `layout` (resolved).
InputConvention resolve_input_convention(const InputConvention& wanted, YoloLayout layout);

bool parse_channel_order(const std::string& text, ChannelOrder* out);   // auto, rgb, bgr
bool parse_pad_placement(const std::string& text, PadPlacement* out);   // auto, centre (center), top_left
bool parse_input_scale(const std::string& text, double* out);           // auto (0), 1, 1/255 or a number > 0

// The letterboxed image as NCHW floats [1, 3, input_height, input_width] in *blob (resized to fit),
// for a resolved convention and the letterbox of the image's size made with its placement.
void make_input_blob(const ImageRgb8& rgb, const Letterbox& letterbox, const InputConvention& convention,
                     std::vector<float>* blob);

}  // namespace dqo::detector
