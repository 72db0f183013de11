#include "dqo_map/detector/yolo_decode.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include <opencv2/dnn.hpp>

namespace dqo::detector {

namespace {

// Value v of candidate j: [1, C, N] keeps a candidate's values N apart, [1, N, C] next to each other.
struct Values {
  const float* data;
  int n, per;
  bool channels_first;
  Values(const float* d, const OutputLayout& l)
      : data(d), n(l.num_candidates), per(l.values_per_candidate()), channels_first(l.channels_first()) {}
  float operator()(int j, int v) const {
    return channels_first ? data[static_cast<size_t>(v) * n + j] : data[static_cast<size_t>(j) * per + v];
  }
};

Box2d box_of(const Values& value, const OutputLayout& layout, int j) {
  double cx = value(j, 0), cy = value(j, 1), w = value(j, 2), h = value(j, 3);
  if (layout.grid_offsets()) {  // YOLOX: offsets from the grid point, log sizes, both in strides
    int gx = 0, gy = 0, s = 1;
    grid_cell(layout, j, &gx, &gy, &s);
    cx = (cx + gx) * s, cy = (cy + gy) * s;
    w = std::exp(w) * s, h = std::exp(h) * s;
  }
  return Box2d{cx - 0.5 * w, cy - 0.5 * h, cx + 0.5 * w, cy + 0.5 * h};
}

}  // namespace

Box2d candidate_box(const float* data, const OutputLayout& layout, int j) {
  return box_of(Values(data, layout), layout, j);
}

std::vector<Candidate> decode_candidates(const float* data, const OutputLayout& layout, const DecodeParams& params) {
  const int n = layout.num_candidates, nc = layout.num_classes;
  const int first_class = layout.objectness() ? 5 : 4;
  const Values value(data, layout);
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
    Candidate c;
    c.index = j;
    c.class_id = best;
    c.score = score;
    c.box = box_of(value, layout, j);
    if (!c.box.valid()) continue;  // NaN or a box of no size
    out.push_back(c);
  }
  return out;
}

bool check_output(const float* data, const OutputLayout& layout, std::string* error) {
  const int n = layout.num_candidates, per = layout.values_per_candidate();
  const int scores_end = (layout.objectness() ? 5 : 4) + layout.num_classes;
  const double W = layout.input_width, H = layout.input_height;
  const Values value(data, layout);
  size_t non_finite = 0;
  float score_min = 0.f, score_max = 0.f;
  bool first_score = true;
  int sized = 0, inside = 0;
  double x_lo = INFINITY, x_hi = -INFINITY, y_lo = INFINITY, y_hi = -INFINITY;
  for (int j = 0; j < n; ++j) {
    for (int v = 0; v < per; ++v) non_finite += !std::isfinite(value(j, v));
    for (int v = 4; v < scores_end; ++v) {
      const float s = value(j, v);
      if (!std::isfinite(s)) continue;
      score_min = first_score ? s : std::min(score_min, s);
      score_max = first_score ? s : std::max(score_max, s);
      first_score = false;
    }
    const Box2d b = box_of(value, layout, j);
    if (!b.valid()) continue;
    ++sized;
    const Eigen::Vector2d c = b.centre();
    if (c.x() < 0 || c.x() > W || c.y() < 0 || c.y() > H) continue;
    ++inside;
    x_lo = std::min(x_lo, c.x()), x_hi = std::max(x_hi, c.x());
    y_lo = std::min(y_lo, c.y()), y_hi = std::max(y_hi, c.y());
  }
  std::ostringstream why;
  why << "read as " << layout.describe() << " at input " << layout.input_width << "x" << layout.input_height << ", ";
  const double kEps = 1e-3;
  if (non_finite > 0) {
    why << non_finite << " of its " << static_cast<size_t>(n) * per << " output values are NaN or infinite";
  } else if (score_min < -kEps || score_max > 1.0 + kEps) {
    why << "its scores range over [" << score_min << ", " << score_max
        << "], not [0, 1] (an export without the final sigmoid, or another layout)";
  } else if (2 * inside < n) {
    why << "only " << inside << " of its " << n << " candidates are boxes of positive size centred inside the input ("
        << sized << " of positive size)";
  } else if (x_hi - x_lo < 0.25 * W || y_hi - y_lo < 0.25 * H) {
    why << "its candidates' centres cluster in x [" << x_lo << ", " << x_hi << "], y [" << y_lo << ", " << y_hi
        << "] instead of covering the input";
  } else {
    return true;
  }
  if (error) *error = why.str();
  return false;
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
