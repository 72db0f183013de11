#pragma once
// Stage: what one keyframe tells of one Gaussian (GaussianTrainer::review_gaussians): whether it is
// in view and not hidden behind the measured surface, how much it gives the view (its usefulness
// for the Gaussian budget, its count of keyframes in a row where it gave almost nothing), and
// whether its label should follow the pixels it falls on. The inputs per Gaussian are its centre,
// its label and three sums over the pixels it reaches from one backward pass with
// dL/d(rgb) = (1, [label = 0], [label != 0]): Σ T α over the view, over background pixels and over
// object pixels.
//
// Written once for the host loop and a device kernel (the review on the GPU, issue 12's next step):
// the centre is moved into the camera as Eigen's Matrix3f · Vector3f computes it (a0 + (a1 + a2)
// per row) and projected in double, as the host loop did, so the host's results are unchanged to
// the bit.

#include <stdint.h>

#include "dqo_map/gaussians/math/types.h"

namespace dqo::gs {

// GaussianTrainer::Params' values of the same names (trainer.h explains and sets them).
struct ReviewSettings {
  float min_depth;         // metres: nearer centres are not reviewed
  float depth_error;       // metres: a centre this far behind the measured depth is hidden
  float min_contribution;  // Σ T α below this: the Gaussian gave (almost) nothing
  float relabel_fraction;  // share of the contribution on pixels of another label
  float budget_decay;      // older views' weight in the usefulness
  int relabel_keyframes;   // keyframes in a row that must vote for a new label
  bool check_visibility;   // count the keyframes of (almost) no contribution
  bool check_labels;       // let labels follow the observations
};

// The keyframe as the review sees it: world to camera (row-major rotation, translation), the
// intrinsics, and its measured depth (metres; 0 / NaN: none) and labels, width × height, row-major.
struct ReviewView {
  float R[3][3];
  float t[3];
  double fx, fy, cx, cy;
  int width, height;
  const float* depth;
  const uint32_t* labels;
};

// One Gaussian's bookkeeping, in place. Returns true when it is to take *new_label (its votes then
// start over). `position`: its centre [3]; `sums`: the three sums above [3].
DQO_HD bool review_gaussian(const ReviewView& view, const ReviewSettings& s, const float* position,
                            uint32_t label, const float* sums, float* usefulness, uint16_t* invisible,
                            uint8_t* votes, uint32_t* new_label) {
  const float x = position[0], y = position[1], z = position[2];
  const float cz = view.R[2][0] * x + (view.R[2][1] * y + view.R[2][2] * z) + view.t[2];
  if (cz < s.min_depth) return false;
  const float cx = view.R[0][0] * x + (view.R[0][1] * y + view.R[0][2] * z) + view.t[0];
  const float cy = view.R[1][0] * x + (view.R[1][1] * y + view.R[1][2] * z) + view.t[1];
  const long u = lround(view.fx * cx / cz + view.cx);
  const long v = lround(view.fy * cy / cz + view.cy);
  if (u < 0 || v < 0 || u >= view.width || v >= view.height) return false;
  const size_t p = static_cast<size_t>(v) * static_cast<size_t>(view.width) + static_cast<size_t>(u);
  const float d = view.depth[p];
  if (!(isfinite(d) && d > 0.f) || cz > d + s.depth_error) return false;  // unknown, or hidden
  const float contribution = sums[0];
  *usefulness = isinf(*usefulness) ? contribution : hd_max(contribution, s.budget_decay * *usefulness);
  if (s.check_visibility) {
    if (contribution < s.min_contribution) {
      if (*invisible < UINT16_MAX) ++*invisible;
    } else {
      *invisible = 0;
    }
  }
  if (!s.check_labels) return false;
  // On the measured surface, most of its contribution on pixels labelled otherwise than it is,
  // its centre on such a pixel: a vote for that label.
  const uint32_t seen = view.labels[p];
  const float on_label = seen == 0 ? sums[1] : sums[2];
  const bool disagrees = seen != label && contribution >= s.min_contribution &&
                         on_label >= s.relabel_fraction * contribution && hd_abs(cz - d) <= s.depth_error;
  if (!disagrees) {
    *votes = 0;
    return false;
  }
  if (++*votes < s.relabel_keyframes) return false;
  *new_label = seen;
  return true;
}

}  // namespace dqo::gs
