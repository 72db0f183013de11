#include "detection_filter.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace dqo::objects {

FilteredDetections filter_detections(const std::vector<Detection2d>& detections, int image_width,
                                     int image_height, const DetectionFilterParams& params) {
  FilteredDetections out;
  out.rejected.assign(detections.size(), std::nullopt);
  const double image_area = static_cast<double>(image_width) * image_height;
  std::vector<int> passed;
  for (size_t i = 0; i < detections.size(); ++i) {
    const Detection2d& d = detections[i];
    std::optional<DetectionVerdict>& verdict = out.rejected[i];
    if (!d.box.valid() || !std::isfinite(d.score) || d.box.clip(image_width, image_height).area() <= 0.0) {
      verdict = DetectionVerdict::kInvalid;
    } else if (d.score < params.min_score) {
      verdict = DetectionVerdict::kLowScore;
    } else if (d.box.area() < params.min_area_px) {
      verdict = DetectionVerdict::kTooSmall;
    } else if (d.box.area() > params.max_area_fraction * image_area) {
      verdict = DetectionVerdict::kTooLarge;
    } else if (d.box.touches_border(image_width, image_height, params.border_margin_px)) {
      // A box cut by the border says nothing about the object's extent on that side.
      verdict = DetectionVerdict::kAtBorder;
    } else {
      passed.push_back(static_cast<int>(i));
    }
  }
  // Best score first (ties: input order), for the cap and for the suppression.
  std::stable_sort(passed.begin(), passed.end(), [&](int a, int b) {
    return detections[a].score > detections[b].score;
  });
  const size_t cap = static_cast<size_t>(std::max(0, params.max_detections));
  if (passed.size() > cap) {
    for (size_t k = cap; k < passed.size(); ++k) out.rejected[passed[k]] = DetectionVerdict::kOverLimit;
    passed.resize(cap);
  }
  std::vector<int> kept;
  for (const int i : passed) {
    bool duplicate = false;
    for (const int j : kept) {
      const double threshold = detections[i].class_id == detections[j].class_id
                                   ? params.duplicate_iou_same_class
                                   : params.duplicate_iou_other_class;
      if (iou(detections[i].box, detections[j].box) > threshold) {
        duplicate = true;
        break;
      }
    }
    if (duplicate) {
      out.rejected[i] = DetectionVerdict::kDuplicate;
    } else {
      kept.push_back(i);
    }
  }
  std::sort(kept.begin(), kept.end());
  out.kept = std::move(kept);
  return out;
}

}  // namespace dqo::objects
