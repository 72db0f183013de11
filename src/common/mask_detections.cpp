#include "dqo_map/common/mask_detections.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <limits>

namespace dqo {
namespace {

struct Extent {
  int min_x = INT_MAX, min_y = INT_MAX, max_x = -1, max_y = -1;
  int pixels = 0;
};

}  // namespace

LabelImage mask_labels(const InstanceImage& instance) {
  LabelImage out(instance.width, instance.height, instance.channels, 0u);
  std::copy(instance.data.begin(), instance.data.end(), out.data.begin());
  return out;
}

MaskDetections detections_from_mask(const LabelImage& labels, const MaskDetectionParams& params) {
  MaskDetections out;
  if (labels.channels != 1 || labels.width <= 0 || labels.height <= 0 ||
      labels.data.size() != static_cast<size_t>(labels.width) * labels.height) {
    return out;
  }
  // std::map keeps labels ascending: the detection order does not depend on where instances lie.
  std::map<uint32_t, Extent> extents;
  for (int y = 0; y < labels.height; ++y) {
    for (int x = 0; x < labels.width; ++x) {
      const uint32_t l = labels.at(x, y);
      if (l == 0) continue;
      Extent& e = extents[l];
      e.min_x = std::min(e.min_x, x);
      e.max_x = std::max(e.max_x, x);
      e.min_y = std::min(e.min_y, y);
      e.max_y = std::max(e.max_y, y);
      ++e.pixels;
    }
  }

  std::map<uint32_t, uint16_t> index_of;  // label -> detection index + 1
  for (const auto& [label, e] : extents) {
    if (e.pixels < params.min_pixels) {
      ++out.dropped_small;
      continue;
    }
    MaskClass cls = params.default_class;
    const auto it = params.classes.find(label);
    if (it != params.classes.end()) {
      cls = it->second;
    } else if (params.skip_unknown) {
      ++out.dropped_unknown;
      continue;
    }
    if (out.detections.size() >= std::numeric_limits<uint16_t>::max()) {
      ++out.dropped_too_many;
      continue;
    }
    Detection2d det;
    det.class_id = cls.class_id;
    det.class_name = cls.class_name;
    det.score = params.score;
    // Pixel centres sit at integer coordinates; a pixel covers ±0.5 around its centre.
    det.box = Box2d{e.min_x - 0.5, e.min_y - 0.5, e.max_x + 0.5, e.max_y + 0.5}.clip(labels.width,
                                                                                    labels.height);
    out.detections.push_back(det);
    out.labels.push_back(label);
    out.pixel_counts.push_back(e.pixels);
    index_of[label] = static_cast<uint16_t>(out.detections.size());
  }

  out.instance = InstanceImage(labels.width, labels.height, 1, 0);
  if (index_of.empty()) return out;
  // Masks hold few labels in long runs: remember the last lookup.
  uint32_t last_label = 0;
  uint16_t last_value = 0;
  for (size_t i = 0; i < labels.data.size(); ++i) {
    const uint32_t l = labels.data[i];
    if (l == 0) continue;
    if (l != last_label) {
      const auto it = index_of.find(l);
      last_label = l;
      last_value = it == index_of.end() ? 0 : it->second;
    }
    out.instance.data[i] = last_value;
  }
  return out;
}

InstanceImage instance_for_detections(const InstanceImage& gt,
                                      const std::vector<Detection2d>& detections) {
  InstanceImage out(gt.width, gt.height, 1, 0);
  std::vector<float> best(gt.data.size(), -1.f);
  for (size_t j = 0; j < detections.size() && j < 65535; ++j) {
    const Detection2d& d = detections[j];
    const int u0 = std::max(0, static_cast<int>(std::ceil(d.box.x_min)));
    const int v0 = std::max(0, static_cast<int>(std::ceil(d.box.y_min)));
    const int u1 = std::min(gt.width - 1, static_cast<int>(std::floor(d.box.x_max)));
    const int v1 = std::min(gt.height - 1, static_cast<int>(std::floor(d.box.y_max)));
    uint32_t id = d.gt_id;
    if (id == 0) {
      std::map<uint16_t, int> counts;
      for (int v = v0; v <= v1; ++v) {
        for (int u = u0; u <= u1; ++u) {
          if (gt.at(u, v) != 0) ++counts[gt.at(u, v)];
        }
      }
      int most = 0;
      for (const auto& [k, n] : counts) {
        if (n > most) {
          most = n;
          id = k;
        }
      }
    }
    if (id == 0) continue;
    // The whole instance, not only its part inside the (possibly noisy) box: the mask is the
    // better outline, the box only says which instance the detection is.
    for (size_t p = 0; p < gt.data.size(); ++p) {
      if (gt.data[p] == id && d.score > best[p]) {
        best[p] = d.score;
        out.data[p] = static_cast<uint16_t>(j + 1);
      }
    }
  }
  return out;
}

}  // namespace dqo
