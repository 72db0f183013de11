#pragma once
// Private to tracking/: the per-frame quality of a tracked pose (ok / degraded / lost and why),
// from what the frame's two sources of evidence said. A pure function of the evidence, so that
// its rules are tested on constructed cases (test_tracking_quality.cpp) apart from the tracker.

#include <vector>

#include <Eigen/Core>

#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/tracking/tracker.h"

namespace dqo::tracking {

struct QualityEvidence {
  bool use_features = true;     // the tracker's configuration
  bool use_dense = true;
  int min_inliers = 15;         // TrackerParams::min_inliers_ok: fewer, the features failed
  int inliers = 0;              // feature inliers of the pose
  int depth_inliers = 0;        // ... with depth
  double spread = 0.0;          // inlier_spread() of them
  bool dense_tried = false;     // dense alignment ran on this frame (not at relocalisation)
  bool dense_ok = false;
  double dense_rms = 0.0;
  double dense_inlier_ratio = 0.0;
  // The dense alignment above started from the features' own pose (a check of it, not a second
  // estimate from the motion model): where it fails, nothing confirms the features.
  bool dense_from_features = false;
  bool compared = false;        // both gave a pose: the disagreement below is measured
  double disagreement_m = 0.0;
  double disagreement_deg = 0.0;
  bool predicted = false;       // neither held: the pose is the motion model's guess
};

struct QualityVerdict {
  TrackingState state = TrackingState::kLost;
  TrackQuality quality;
};

QualityVerdict assess_quality(const QualityEvidence& evidence, const QualityParams& params);

// Fraction of the image's 4x4 cells holding at least one of the points: inliers bunched in one
// corner constrain the pose far less than as many spread over the view.
double inlier_spread(const std::vector<Eigen::Vector2f>& uv, const PinholeCamera& camera);

}  // namespace dqo::tracking
