#pragma once
// Coarse-to-fine association of a keyframe's filtered detections with the map objects it should
// see (METHOD.md §2.3–2.4), one-to-one:
//   coarse  IoU between the object's projected box and the detection > min_iou (not for `qd`);
//   fine    a quadric built from the object's recent observation boxes plus the detection
//           (box planes, initialise_from_boxes) — or, with too few views or a failed fit, the
//           detection's single-view depth ellipsoid (fine_quadric = depth: that one first; also
//           when the depth contradicts the box-plane quadric, LifecycleParams::max_depth_disagreement,
//           a departure from METHOD.md) —
//           compared with the object's quadric by quadric_similarity >= min_similarity (not for
//           `iou`);
//   assign  the admissible pairs go to solve_assignment with score IoU (iou), similarity (qd) or
//           their sum (iou+qd): no detection feeds two objects, no object takes two detections.
#include <functional>
#include <optional>
#include <vector>
#include "dqo_map/common/dataset.h"
#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/quadric_init.h"
#include "dqo_map/objects/object_params.h"
#include "dqo_map/objects/object_types.h"
#include "depth_init.h"

namespace dqo::objects {

// One object that may take a detection of this keyframe.
struct AssociationTrack {
  const MapObject* object = nullptr;
  // The projected box, or for a candidate without an ellipsoid the box of its last observation.
  Box2d box;
};

// The camera of a stored keyframe for one observation (nullopt when the keyframe is unknown).
using ViewLookup = std::function<std::optional<BoxObservation>(const ObjectObservation&)>;
// The depth evidence of one stored observation (no depth or unknown keyframe: depth == nullptr).
using DepthLookup = std::function<DepthEvidence(const ObjectObservation&)>;

// The keyframe as association needs it.
struct AssociationFrame {
  const PinholeCamera* camera = nullptr;
  SE3 T_wc;
  Eigen::Matrix<double, 3, 4> P = Eigen::Matrix<double, 3, 4>::Zero();
  DepthView depth;
  // Optional: the depth ellipsoids of the detections passed to associate (same order; built here
  // when absent) and of the objects' stored observations, for the depth check of the fine step's
  // box-plane quadric (LifecycleParams::max_depth_disagreement).
  const std::vector<std::optional<DualQuadric>>* detection_depth = nullptr;
  DepthLookup depth_lookup;
};

struct AssociationResult {
  std::vector<int> track_to_detection;  // [track] -> index into `detections`, -1 when none
  int coarse_pairs = 0;                 // pairs that passed the coarse gate (all pairs for qd)
  int fine_inits = 0;                   // quadrics built for the fine gate
};

// detections: the filtered detections of the keyframe.
AssociationResult associate(const std::vector<AssociationTrack>& tracks,
                            const std::vector<Detection2d>& detections,
                            const AssociationFrame& frame, const ViewLookup& lookup,
                            const AssociationParams& params, const LifecycleParams& lifecycle);

// The quadric that the fine step compares: box planes of the object's newest observations (at
// most max_views − 1 of them) plus `box` seen from `frame`, when that makes at least min_box_views
// views, the fit succeeds and the depth does not contradict it (max_depth_disagreement, against
// the depth evidence of those observations and `box_depth`, the detection's depth ellipsoid, when
// given); otherwise the single-view depth ellipsoid of `box` (when allowed and
// depth is present); otherwise nullopt. `depth_cache` (optional) memoises the depth ellipsoid.
std::optional<DualQuadric> observation_quadric(const MapObject& object, const Box2d& box,
                                               const AssociationFrame& frame,
                                               const ViewLookup& lookup, int max_views,
                                               const LifecycleParams& lifecycle,
                                               const DualQuadric* box_depth = nullptr);

}  // namespace dqo::objects
