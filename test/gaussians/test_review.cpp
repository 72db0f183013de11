// The review's per-Gaussian step (math/review.h) on hand-made cases: what it skips (behind the
// camera, out of the image, hidden behind the measured surface, no depth), the usefulness
// (first view, then the decayed maximum), the count of views of (almost) no contribution, and the
// votes that move a label after relabel_keyframes keyframes in a row.

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "dqo_map/gaussians/math/review.h"

namespace dqo::gs {
namespace {

// A 4×3 view from the identity pose, f = 2, principal point (1.5, 1), depth 2 m everywhere,
// pixel (2, 1) labelled 7 and the rest 0.
struct Fixture {
  std::vector<float> depth = std::vector<float>(12, 2.f);
  std::vector<uint32_t> labels = std::vector<uint32_t>(12, 0u);
  ReviewView view{};
  ReviewSettings settings{};
  Fixture() {
    // The trainer's defaults (trainer.h).
    settings.min_depth = 0.3f;
    settings.depth_error = 0.1f;
    settings.min_contribution = 0.05f;
    settings.relabel_fraction = 0.8f;
    settings.budget_decay = 0.9f;
    settings.relabel_keyframes = 2;
    settings.check_visibility = true;
    settings.check_labels = true;
    for (int i = 0; i < 3; ++i) view.R[i][i] = 1.f;
    view.fx = view.fy = 2.0;
    view.cx = 1.5, view.cy = 1.0;
    view.width = 4, view.height = 3;
    labels[1 * 4 + 2] = 7;
    view.depth = depth.data();
    view.labels = labels.data();
  }
  // The Gaussian at camera point (x, y, z), label `label`, sums (c0, c1, c2).
  struct Result {
    bool relabel;
    uint32_t new_label;
  };
  Result review(float x, float y, float z, uint32_t label, float c0, float c1, float c2, float* usefulness,
                uint16_t* invisible, uint8_t* votes) {
    const float position[3] = {x, y, z}, sums[3] = {c0, c1, c2};
    uint32_t new_label = 12345;
    const bool r = review_gaussian(view, settings, position, label, sums, usefulness, invisible, votes, &new_label);
    return {r, new_label};
  }
};

TEST(Review, SkipsWhatTheViewCannotJudge) {
  Fixture f;
  const float inf = std::numeric_limits<float>::infinity();
  for (const auto& xyz : std::vector<std::array<float, 3>>{{0.f, 0.f, 0.2f},     // nearer than min_depth
                                                           {0.f, 0.f, -2.f},     // behind the camera
                                                           {5.f, 0.f, 2.f},      // right of the image
                                                           {0.f, 0.f, 2.15f}}) {  // behind the surface
    float usefulness = inf;
    uint16_t invisible = 3;
    uint8_t votes = 1;
    EXPECT_FALSE(f.review(xyz[0], xyz[1], xyz[2], 0, 0.f, 0.f, 0.f, &usefulness, &invisible, &votes).relabel);
    EXPECT_TRUE(std::isinf(usefulness)) << xyz[0] << " " << xyz[2];
    EXPECT_EQ(invisible, 3);
    EXPECT_EQ(votes, 1);
  }
  // No depth measured at its pixel: skipped too.
  f.depth[1 * 4 + 2] = std::numeric_limits<float>::quiet_NaN();
  float usefulness = inf;
  uint16_t invisible = 0;
  uint8_t votes = 0;
  f.review(0.25f, 0.f, 2.f, 0, 1.f, 1.f, 0.f, &usefulness, &invisible, &votes);  // pixel (1.75 → 2, 1)
  EXPECT_TRUE(std::isinf(usefulness));
}

TEST(Review, UsefulnessAndInvisibleCount) {
  Fixture f;
  float usefulness = std::numeric_limits<float>::infinity();
  uint16_t invisible = 0;
  uint8_t votes = 0;
  // Pixel (1.5 + 2·(−0.5)/2, 1) = (1, 1), label 0, on the surface.
  f.review(-0.5f, 0.f, 2.f, 0, 0.01f, 0.01f, 0.f, &usefulness, &invisible, &votes);
  EXPECT_FLOAT_EQ(usefulness, 0.01f) << "first view: its contribution";
  EXPECT_EQ(invisible, 1) << "below min_contribution";
  f.review(-0.5f, 0.f, 2.f, 0, 0.02f, 0.02f, 0.f, &usefulness, &invisible, &votes);
  EXPECT_FLOAT_EQ(usefulness, 0.02f) << "the larger of 0.02 and 0.9 · 0.01";
  EXPECT_EQ(invisible, 2);
  f.review(-0.5f, 0.f, 2.f, 0, 0.001f, 0.001f, 0.f, &usefulness, &invisible, &votes);
  EXPECT_FLOAT_EQ(usefulness, 0.9f * 0.02f) << "decayed";
  f.review(-0.5f, 0.f, 2.f, 0, 0.5f, 0.5f, 0.f, &usefulness, &invisible, &votes);
  EXPECT_EQ(invisible, 0) << "seen again";
  EXPECT_EQ(votes, 0) << "its own label";
  f.settings.check_visibility = false;
  f.review(-0.5f, 0.f, 2.f, 0, 0.001f, 0.001f, 0.f, &usefulness, &invisible, &votes);
  EXPECT_EQ(invisible, 0) << "not counted without check_visibility";
}

TEST(Review, LabelsFollowTheObservationsAfterEnoughVotes) {
  Fixture f;
  float usefulness = 0.f;
  uint16_t invisible = 0;
  uint8_t votes = 0;
  // A background Gaussian on pixel (2, 1), labelled 7, with 90 % of its contribution on object pixels.
  auto r = f.review(0.25f, 0.f, 2.f, 0, 1.f, 0.1f, 0.9f, &usefulness, &invisible, &votes);
  EXPECT_FALSE(r.relabel);
  EXPECT_EQ(votes, 1);
  r = f.review(0.25f, 0.f, 2.f, 0, 1.f, 0.1f, 0.9f, &usefulness, &invisible, &votes);
  EXPECT_TRUE(r.relabel) << "second keyframe in a row";
  EXPECT_EQ(r.new_label, 7u);
  // Too little on the object's pixels, or off the measured surface, or too little contribution:
  // the votes start over.
  votes = 1;
  f.review(0.25f, 0.f, 2.f, 0, 1.f, 0.3f, 0.7f, &usefulness, &invisible, &votes);
  EXPECT_EQ(votes, 0) << "70 % < relabel_fraction";
  votes = 1;
  f.review(0.25f, 0.f, 1.8f, 0, 1.f, 0.f, 1.f, &usefulness, &invisible, &votes);  // 0.2 m in front
  EXPECT_EQ(votes, 0) << "off the surface";
  votes = 1;
  f.review(0.25f, 0.f, 2.f, 0, 0.01f, 0.f, 0.01f, &usefulness, &invisible, &votes);
  EXPECT_EQ(votes, 0) << "contribution below min_contribution";
  // Already the pixel's label: no vote.
  votes = 1;
  f.review(0.25f, 0.f, 2.f, 7, 1.f, 0.f, 1.f, &usefulness, &invisible, &votes);
  EXPECT_EQ(votes, 0);
  // Without check_labels nothing moves.
  f.settings.check_labels = false;
  votes = 1;
  EXPECT_FALSE(f.review(0.25f, 0.f, 2.f, 0, 1.f, 0.f, 1.f, &usefulness, &invisible, &votes).relabel);
  EXPECT_EQ(votes, 1);
}

}  // namespace
}  // namespace dqo::gs
