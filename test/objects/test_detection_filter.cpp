// The detection filter (METHOD.md §2.1): each threshold against hand-made boxes, and bad input.
#include <cmath>
#include <limits>
#include <gtest/gtest.h>
#include "../../src/objects/detection_filter.h"

namespace dqo::objects {
namespace {

constexpr int kW = 640, kH = 480;

Detection2d det(double x0, double y0, double x1, double y1, int class_id = 1, float score = 0.9f) {
  Detection2d d;
  d.box = {x0, y0, x1, y1};
  d.class_id = class_id;
  d.score = score;
  return d;
}

std::optional<DetectionVerdict> verdict_of(const Detection2d& d, const DetectionFilterParams& p = {}) {
  return filter_detections({d}, kW, kH, p).rejected[0];
}

TEST(DetectionFilter, ScoreThreshold) {
  DetectionFilterParams p;
  p.min_score = 0.2;
  EXPECT_EQ(verdict_of(det(100, 100, 200, 200, 1, 0.19f), p), DetectionVerdict::kLowScore);
  EXPECT_FALSE(verdict_of(det(100, 100, 200, 200, 1, 0.21f), p).has_value());
  p.min_score = 0.5;
  EXPECT_EQ(verdict_of(det(100, 100, 200, 200, 1, 0.3f), p), DetectionVerdict::kLowScore);
}

TEST(DetectionFilter, AreaThresholds) {
  DetectionFilterParams p;  // 300 px² .. 0.5 · 640 · 480 = 153600 px²
  EXPECT_EQ(verdict_of(det(100, 100, 117, 117), p), DetectionVerdict::kTooSmall);   // 289
  EXPECT_FALSE(verdict_of(det(100, 100, 118, 118), p).has_value());                 // 324
  EXPECT_EQ(verdict_of(det(10, 10, 410, 410), p), DetectionVerdict::kTooLarge);     // 160000
  EXPECT_FALSE(verdict_of(det(10, 10, 390, 410), p).has_value());                   // 152000
  p.min_area_px = 400.0;
  EXPECT_EQ(verdict_of(det(100, 100, 118, 118), p), DetectionVerdict::kTooSmall);
  p.max_area_fraction = 0.4;
  EXPECT_EQ(verdict_of(det(10, 10, 390, 410), p), DetectionVerdict::kTooLarge);
}

TEST(DetectionFilter, BorderMargin) {
  DetectionFilterParams p;  // 5 px
  EXPECT_EQ(verdict_of(det(4, 100, 100, 200), p), DetectionVerdict::kAtBorder);
  EXPECT_FALSE(verdict_of(det(6, 100, 100, 200), p).has_value());
  EXPECT_EQ(verdict_of(det(100, 100, 637, 200), p), DetectionVerdict::kAtBorder);
  EXPECT_EQ(verdict_of(det(100, 100, 200, 476), p), DetectionVerdict::kAtBorder);
  p.border_margin_px = 20.0;
  EXPECT_EQ(verdict_of(det(15, 100, 100, 200), p), DetectionVerdict::kAtBorder);
}

TEST(DetectionFilter, DuplicatesKeepTheBetterScore) {
  DetectionFilterParams p;  // same class 0.5, other class 0.6
  // IoU of these two: 80x100 overlap of two 100x100 boxes = 8000 / 12000 = 0.667.
  const Detection2d a = det(100, 100, 200, 200, 1, 0.9f);
  const Detection2d b = det(120, 100, 220, 200, 1, 0.8f);
  auto r = filter_detections({b, a}, kW, kH, p);
  EXPECT_EQ(r.rejected[0], DetectionVerdict::kDuplicate);  // b loses to a
  EXPECT_FALSE(r.rejected[1].has_value());
  EXPECT_EQ(r.kept, std::vector<int>({1}));
  // Other class: 0.667 > 0.6 still a duplicate; at IoU 0.5 (< 0.6) both stay.
  EXPECT_EQ(filter_detections({a, det(120, 100, 220, 200, 2, 0.8f)}, kW, kH, p).rejected[1],
            DetectionVerdict::kDuplicate);
  const Detection2d c2 = det(133.34, 100, 233.34, 200, 2, 0.8f);  // IoU 0.5
  EXPECT_FALSE(filter_detections({a, c2}, kW, kH, p).rejected[1].has_value());
  // Same class at IoU 0.43: two chairs side by side, one partly behind the other, both stay (the
  // paper's 0.3 kept one); at 0.55 one is a duplicate.
  const Detection2d beside = det(140, 100, 240, 200, 1, 0.8f);  // 6000 / 14000 = 0.43
  EXPECT_FALSE(filter_detections({a, beside}, kW, kH, p).rejected[1].has_value());
  const Detection2d over = det(129, 100, 229, 200, 1, 0.8f);  // 7100 / 12900 = 0.55
  EXPECT_EQ(filter_detections({a, over}, kW, kH, p).rejected[1], DetectionVerdict::kDuplicate);
  // Disjoint boxes are never duplicates.
  EXPECT_EQ(filter_detections({a, det(300, 300, 400, 400)}, kW, kH, p).kept.size(), 2u);
}

TEST(DetectionFilter, InvalidBoxes) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(verdict_of(det(nan, 100, 200, 200)), DetectionVerdict::kInvalid);
  EXPECT_EQ(verdict_of(det(100, 100, inf, 200)), DetectionVerdict::kInvalid);
  EXPECT_EQ(verdict_of(det(200, 100, 100, 200)), DetectionVerdict::kInvalid);  // negative width
  EXPECT_EQ(verdict_of(det(100, 200, 200, 200)), DetectionVerdict::kInvalid);  // zero height
  EXPECT_EQ(verdict_of(det(700, 100, 800, 200)), DetectionVerdict::kInvalid);  // outside the image
  EXPECT_EQ(verdict_of(det(-300, -300, -100, -100)), DetectionVerdict::kInvalid);
  Detection2d bad_score = det(100, 100, 200, 200);
  bad_score.score = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(verdict_of(bad_score), DetectionVerdict::kInvalid);
}

TEST(DetectionFilter, CapKeepsTheBestScores) {
  DetectionFilterParams p;
  p.max_detections = 3;
  std::vector<Detection2d> dets;
  for (int k = 0; k < 6; ++k) {
    dets.push_back(det(20 + 100 * k, 100, 90 + 100 * k, 200, 1, 0.3f + 0.1f * static_cast<float>(k)));
  }
  const auto r = filter_detections(dets, kW, kH, p);
  EXPECT_EQ(r.kept, std::vector<int>({3, 4, 5}));
  for (int k = 0; k < 3; ++k) EXPECT_EQ(r.rejected[k], DetectionVerdict::kOverLimit);
}

TEST(DetectionFilter, ThousandDetections) {
  std::vector<Detection2d> dets;
  for (int k = 0; k < 1000; ++k) {
    const double x = 10 + (k % 30) * 20, y = 10 + (k / 30) * 13;
    dets.push_back(det(x, y, x + 25, y + 25, k % 5, 0.2f + 0.0007f * static_cast<float>(k)));
  }
  const auto r = filter_detections(dets, kW, kH, DetectionFilterParams());
  ASSERT_EQ(r.rejected.size(), 1000u);
  EXPECT_LE(r.kept.size(), 200u);
  for (const int i : r.kept) EXPECT_FALSE(r.rejected[i].has_value());
}

}  // namespace
}  // namespace dqo::objects
