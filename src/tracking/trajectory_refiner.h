#pragma once
// The end of an offline run: every tracked frame's pose refined once the map is final. Each frame
// brings a measured pose (its features re-registered against the globally adjusted map, or its
// pose relative to its reference keyframe); a batch smoother (Ceres) then holds consecutive frames
// to a bounded acceleration and angular acceleration. Frames tracked on weak evidence (degraded)
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

// The acceleration residual of three consecutive camera poses (tests): r = [a / σ_a; α / σ_α],
// a = (v₂ − v₁) / t̄ of the camera centres, α = (ω₂ − ω₁) / t̄ of the angular velocities in the
// world frame (ω from 2 vec(q) of each step's relative rotation), t̄ = (dt₁ + dt₂) / 2.
Eigen::Matrix<double, 6, 1> acceleration_residual(const SE3& T0, const SE3& T1, const SE3& T2,
                                                  double dt1, double dt2, const RefineParams& p);

// The refined poses, one per frame. Frames further apart than max_gap_s are not tied.
std::vector<SE3> refine_trajectory(const std::vector<RefinerFrame>& frames, const RefineParams& p);

}  // namespace dqo::tracking
