#include "dqo_map/detector/yolo_decode.h"

#include <algorithm>
#include <map>

#include <opencv2/dnn.hpp>

namespace dqo::detector {

std::vector<Candidate> decode_candidates(const float* data, const OutputLayout& layout, const DecodeParams& params) {
  const int n = layout.num_candidates, nc = layout.num_classes;
  const int first_class = layout.objectness() ? 5 : 4;
  // Value v of candidate j: [1, C, N] keeps a candidate's values N apart, [1, N, C] next to each other.
  const bool cf = layout.channels_first();
  const int stride = layout.values_per_candidate();
  auto value = [&](int j, int v) { return cf ? data[static_cast<size_t>(v) * n + j] : data[static_cast<size_t>(j) * stride + v]; };
  std::vector<Candidate> out;
  for (int j = 0; j < n; ++j) {
    const float objectness = layout.objectness() ? value(j, 4) : 1.f;
    if (!(objectness >= params.confidence)) continue;  // no class can make it (scores <= 1)
    int best = -1;
    float best_score = 0.f;
    for (int c = 0; c < nc; ++c) {
      const float s = value(j, first_class + c);
      if (best < 0 || s > best_score) best = c, best_score = s;
    }
    const float score = objectness * best_score;
    if (!(score >= params.confidence)) continue;
    if (!params.class_enabled.empty() &&
        (best >= static_cast<int>(params.class_enabled.size()) || !params.class_enabled[best])) {
      continue;
    }
    const float cx = value(j, 0), cy = value(j, 1), w = value(j, 2), h = value(j, 3);
    Candidate c;
    c.index = j;
    c.class_id = best;
    c.score = score;
    c.box = Box2d{cx - 0.5 * w, cy - 0.5 * h, cx + 0.5 * w, cy + 0.5 * h};
    if (!c.box.valid()) continue;  // NaN or a box of no size
    out.push_back(c);
  }
  return out;
}

std::vector<Candidate> non_max_suppression(const std::vector<Candidate>& candidates, const DecodeParams& params) {
  std::map<int, std::vector<int>> by_class;
  for (size_t i = 0; i < candidates.size(); ++i) by_class[candidates[i].class_id].push_back(static_cast<int>(i));
  std::vector<Candidate> kept;
  for (const auto& [cls, members] : by_class) {
    std::vector<cv::Rect2d> boxes;
    std::vector<float> scores;
    for (const int i : members) {
      const Box2d& b = candidates[i].box;
      boxes.emplace_back(b.x_min, b.y_min, b.width(), b.height());
      scores.push_back(candidates[i].score);
    }
    std::vector<int> keep;
    // Scores were thresholded already; 0 keeps every survivor of the IoU test.
    cv::dnn::NMSBoxes(boxes, scores, 0.f, params.nms_iou, keep);
    for (const int k : keep) kept.push_back(candidates[members[k]]);
  }
  std::sort(kept.begin(), kept.end(), [](const Candidate& a, const Candidate& b) {
    return a.score > b.score || (a.score == b.score && a.index < b.index);
  });
  if (params.max_detections >= 0 && static_cast<int>(kept.size()) > params.max_detections) {
    kept.resize(params.max_detections);
  }
  return kept;
}

}  // namespace dqo::detector
