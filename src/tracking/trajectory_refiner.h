#pragma once
// The end of an offline run: every tracked frame's pose refined once the map is final. Each frame
// brings a measured pose (its features re-registered against the globally adjusted map, or its
// pose relative to its reference keyframe); a batch smoother (Ceres) then holds consecutive frames
// to a bounded change of their velocity on SE(3) (in the camera's frame). Frames tracked on weak evidence (degraded)
// weigh less, so their neighbours carry them (fr1/desk's motion-blurred frames: many inliers
// agreeing on a pose several centimetres off).

#include <vector>

#include "dqo_map/geometry/se3.h"
#include "dqo_map/tracking/tracker_params.h"

namespace dqo::tracking {

struct RefinerFrame {
  double timestamp = 0.0;  // seconds, increasing along the vector
  SE3 T_wc;                // the measured pose
  bool degraded = false;   // weaker evidence: σ × RefineParams::degraded_sigma_scale
};

// The acceleration residual of three consecutive camera poses (tests): r = [a / σ_a; α / σ_α]
// with ξᵢ = [t; 2 vec(q)] / dtᵢ of each step T_prev,next (its motion in the earlier camera's
// frame, per second) and (a; α) = (ξ₂ − ξ₁) / t̄, t̄ = (dt₁ + dt₂) / 2: constant velocity on SE(3).
Eigen::Matrix<double, 6, 1> acceleration_residual(const SE3& T0, const SE3& T1, const SE3& T2,
                                                  double dt1, double dt2, const RefineParams& p);

// The refined poses, one per frame. Frames further apart than max_gap_s are not tied.
std::vector<SE3> refine_trajectory(const std::vector<RefinerFrame>& frames, const RefineParams& p);

}  // namespace dqo::tracking
