#include "dqo_map/detector/yolo_masks.h"

#include <algorithm>
#include <cmath>

namespace dqo::detector {

InstanceImage instance_from_masks(const float* detection_output, const float* protos, const OutputLayout& layout,
                                  const std::vector<Candidate>& kept, const Letterbox& letterbox, float threshold) {
  InstanceImage instance(letterbox.source_width, letterbox.source_height, 1, 0);
  const int nm = layout.mask_dim, ph = layout.proto_height, pw = layout.proto_width;
  if (nm <= 0 || ph <= 0 || pw <= 0) return instance;
  const int first_mask = (layout.objectness() ? 5 : 4) + layout.num_classes;
  const int n = layout.num_candidates, stride = layout.values_per_candidate();
  const bool cf = layout.channels_first();
  // Prototype pixels per input pixel (the prototypes cover the whole input at a quarter of its size).
  const double sx = static_cast<double>(pw) / letterbox.input_width, sy = static_cast<double>(ph) / letterbox.input_height;
  const size_t plane = static_cast<size_t>(ph) * pw;
  std::vector<float> coeff(nm), logits;
  const size_t count = std::min<size_t>(kept.size(), 65535);  // mono16 values
  for (size_t k = 0; k < count; ++k) {
    const Candidate& c = kept[k];
    for (int m = 0; m < nm; ++m) {
      coeff[m] = cf ? detection_output[static_cast<size_t>(first_mask + m) * n + c.index]
                    : detection_output[static_cast<size_t>(c.index) * stride + first_mask + m];
    }
    const Box2d box = letterbox.to_source(c.box);
    if (!box.valid()) continue;
    // Image pixels whose centres lie in the box.
    const int x0 = std::max(0, static_cast<int>(std::ceil(box.x_min - 0.5))),
              x1 = std::min(letterbox.source_width - 1, static_cast<int>(std::floor(box.x_max - 0.5)));
    const int y0 = std::max(0, static_cast<int>(std::ceil(box.y_min - 0.5))),
              y1 = std::min(letterbox.source_height - 1, static_cast<int>(std::floor(box.y_max - 0.5)));
    if (x0 > x1 || y0 > y1) continue;
    // Their prototype coordinates (pixel centres, as a bilinear resize with half-pixel centres) and
    // the prototype window that covers them: the mask is computed there only.
    auto proto_x = [&](int x) { return letterbox.to_input_x(x + 0.5) * sx - 0.5; };
    auto proto_y = [&](int y) { return letterbox.to_input_y(y + 0.5) * sy - 0.5; };
    const int px0 = std::clamp(static_cast<int>(std::floor(proto_x(x0))), 0, pw - 1),
              px1 = std::clamp(static_cast<int>(std::floor(proto_x(x1))) + 1, 0, pw - 1);
    const int py0 = std::clamp(static_cast<int>(std::floor(proto_y(y0))), 0, ph - 1),
              py1 = std::clamp(static_cast<int>(std::floor(proto_y(y1))) + 1, 0, ph - 1);
    const int ww = px1 - px0 + 1, wh = py1 - py0 + 1;
    logits.assign(static_cast<size_t>(ww) * wh, 0.f);
    for (int m = 0; m < nm; ++m) {
      const float* p = protos + m * plane;
      for (int v = 0; v < wh; ++v)
        for (int u = 0; u < ww; ++u) logits[static_cast<size_t>(v) * ww + u] += coeff[m] * p[static_cast<size_t>(py0 + v) * pw + px0 + u];
    }
    for (float& l : logits) l = 1.f / (1.f + std::exp(-l));
    auto sample = [&](double fx, double fy) {
      // Bilinear on the window, clamped at the prototypes' edges.
      fx = std::clamp(fx, 0.0, static_cast<double>(pw - 1));
      fy = std::clamp(fy, 0.0, static_cast<double>(ph - 1));
      const int ix = std::min(static_cast<int>(fx), pw - 2 < 0 ? 0 : pw - 2);
      const int iy = std::min(static_cast<int>(fy), ph - 2 < 0 ? 0 : ph - 2);
      const double ax = pw > 1 ? fx - ix : 0.0, ay = ph > 1 ? fy - iy : 0.0;
      auto at = [&](int x, int y) {
        x = std::clamp(x, px0, px1);
        y = std::clamp(y, py0, py1);
        return static_cast<double>(logits[static_cast<size_t>(y - py0) * ww + (x - px0)]);
      };
      return (1 - ay) * ((1 - ax) * at(ix, iy) + ax * at(ix + 1, iy)) + ay * ((1 - ax) * at(ix, iy + 1) + ax * at(ix + 1, iy + 1));
    };
    const uint16_t value = static_cast<uint16_t>(k + 1);
    for (int y = y0; y <= y1; ++y) {
      const double fy = proto_y(y);
      for (int x = x0; x <= x1; ++x) {
        uint16_t& px = instance.at(x, y);
        if (px != 0) continue;  // a better detection has it
        if (sample(proto_x(x), fy) > threshold) px = value;
      }
    }
  }
  return instance;
}

}  // namespace dqo::detector
