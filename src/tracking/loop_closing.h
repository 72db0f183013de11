#pragma once
// Loop closing over the tracker's keyframes (ORB-SLAM2's LoopClosing without bag of words: Debian
// packages no vocabulary). Place recognition matches a new keyframe's descriptors against the map
// points of older keyframes it is not covisible with, the best matched are verified by PnP RANSAC
// and a refinement with depth (relocaliser.h); a verified loop is corrected by an SE(3) pose graph
// over every keyframe (pose_graph.h), the map points following their first keyframe and the
// query's matched points fused into the older ones, so that a global bundle adjustment
// (global_ba_problem, solved by solve_local_ba) keeps the loop closed.
//
// Free functions on the map: the tracker calls them on its own thread (tracker_loop.cpp).

#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/tracking/tracker_params.h"
#include "local_ba.h"
#include "map_store.h"
#include "orb_frame.h"

namespace dqo::tracking {

struct LoopDetection {
  bool found = false;
  uint64_t query = kNoId;
  uint64_t match = kNoId;  // the older keyframe
  // The query keyframe's pose as the matched keyframe's map points place it.
  SE3 T_wc_query;
  std::vector<std::pair<int, uint64_t>> matches;  // (query keypoint, map point): the inliers
  int candidates = 0;    // keyframes that qualified (old enough, not covisible)
  int best_matches = 0;  // descriptor matches of the best ranked candidate
};

// The older keyframes the query may close a loop with: at least `min_keyframe_gap` keyframes
// older, sharing no map point with it or with a keyframe it is covisible with. Sorted by ID.
std::vector<uint64_t> loop_candidates(const MapStore& map, uint64_t query, const LoopParams& params);

LoopDetection detect_loop(const MapStore& map, uint64_t query, const PinholeCamera& camera,
                          const ScalePyramid& scales, const PoseOptimiserParams& pose_params,
                          const LoopParams& params);

struct LoopCorrection {
  bool ok = false;
  std::unordered_map<uint64_t, SE3> moved;  // keyframe ID -> corrected T_wc (every free keyframe)
  int fused_points = 0;                     // query points merged into the older ones
  int edges = 0;                            // of the pose graph
  double milliseconds = 0.0;
};

// Corrects the map in place: a pose graph over all keyframes (edges between keyframes sharing at
// least `min_edge_shared` points and between consecutive keyframes, at their current relative
// poses; the loop edge from the detection), `gauge_keyframe` and the matched keyframe held. Map
// points move with their first keyframe; then the matches are fused and covisibility updated.
LoopCorrection correct_loop(MapStore* map, const LoopDetection& loop, uint64_t gauge_keyframe,
                            const ScalePyramid& scales, const LoopParams& params);

// Every keyframe (`gauge_keyframe` held), map point, observation and dense odometry link of the
// map: a global bundle adjustment for solve_local_ba.
LocalBaProblem global_ba_problem(const MapStore& map, uint64_t gauge_keyframe,
                                 const ScalePyramid& scales, const PoseOptimiserParams& pose_params,
                                 uint64_t generation);

}  // namespace dqo::tracking
