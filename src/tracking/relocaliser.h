#pragma once
// Pose from scratch against keyframes: descriptor matching with the keyframe's map points, PnP
// RANSAC (OpenCV), then pose-only refinement with depth. Used when tracking from a pose guess
// failed (against the last keyframe) and when lost (against a bounded set of candidates: Debian
// packages no bag-of-words vocabulary, so candidates are chosen by the tracker and tried in order
// of how many descriptors they share with the frame).

#include <cstdint>
#include <utility>
#include <vector>

#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/tracking/tracker_params.h"
#include "map_store.h"
#include "orb_frame.h"

namespace dqo::tracking {

struct PnpResult {
  bool ok = false;
  SE3 T_wc;
  uint64_t keyframe = kNoId;
  std::vector<std::pair<int, uint64_t>> matches;  // (keypoint, map point) kept as inliers
};

// Descriptor matches between the frame and the keyframe's map points, then PnP RANSAC and a
// refinement; ok when at least `min_inliers` survive.
PnpResult pnp_against_keyframe(const OrbFrame& frame, const KeyFrame& keyframe,
                               const MapStore& map, const PinholeCamera& camera,
                               const ScalePyramid& scales, const PoseOptimiserParams& pose_params,
                               int min_inliers);

// Tries the candidates, the most promising first (by descriptor matches), at most `max_pnp` of
// them through PnP, then the same through a 3-point rigid RANSAC on the matches with depth (a
// hypothesis from as few as 8 matches agreeing in 3D: the caller must confirm it against the
// local map); returns the first that succeeds.
PnpResult relocalise(const OrbFrame& frame, const MapStore& map,
                     const std::vector<uint64_t>& candidates, const PinholeCamera& camera,
                     const ScalePyramid& scales, const PoseOptimiserParams& pose_params,
                     const RelocParams& params);

}  // namespace dqo::tracking
