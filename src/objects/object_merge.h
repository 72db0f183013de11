#pragma once
// Occlusion merge (METHOD.md §2.5): an object first seen only in part (the rest hidden by an
// occluder) and later whole gives two map objects, the piece inside the whole. Two objects of one
// class seen in a keyframe are one when the smaller projected box j lies mostly inside the larger
// one i, t = area(box_i ∩ box_j) / area(box_j) > min_overlap, and in 3D the piece's centre lies
// inside the larger ellipsoid grown by max_distance (d) on every semi-axis.
//
// METHOD.md says "the QD condition holds with d = 0.1" without defining it for two objects of
// different sizes; QD itself (exp(−τ(Δμ + ΔS))) is small exactly for a piece and its whole, so
// it cannot be the test. Containment of the centre is what "pieces of one object" means.
//
// Added to the paper: two objects that one keyframe detected apart (two detections, one to each)
// are never merged (MergeParams::max_seen_apart_iou); without it two chairs side by side, which
// from the side project one inside the other, end as one.
#include <utility>
#include <vector>
#include "dqo_map/objects/object_params.h"
#include "dqo_map/objects/object_types.h"
#include "visibility.h"

namespace dqo::objects {

struct MergePair {
  int from = 0;  // index into `objects`: merged away (the smaller projection)
  int into = 0;  // index into `objects`: kept
};

// objects[v.index] for each visible v. An object takes part in at most one merge per call (the
// next keyframe catches chains). Pairs in the order found, the larger boxes first.
std::vector<MergePair> find_merges(const std::vector<const MapObject*>& objects,
                                   const std::vector<VisibleObject>& visible,
                                   const MergeParams& params);

// True when some keyframe has an observation of each whose boxes overlap less than max_iou (2D
// IoU): that keyframe's detector saw two things, so the two are not pieces of one object.
bool seen_apart(const MapObject& a, const MapObject& b, double max_iou);

// True when p_w lies inside the ellipsoid grown by `margin` metres on each semi-axis.
bool inside_grown_ellipsoid(const DualQuadric& q, const Eigen::Vector3d& p_w, double margin);

// Moves `from`'s observations (one per keyframe: `into`'s wins a tie), class votes and counts into
// `into` and recomputes its class. The quadric of `into` is kept (the refinement over the merged
// observations follows).
void merge_object_into(const MapObject& from, MapObject* into, double rename_margin = 1.0);

// The class vote's mode and its share; for the mapper and the merge. The object keeps its class
// while no other has more than rename_margin times its votes (1: the plain mode). True when the
// class changed.
bool update_class(MapObject* object, double rename_margin = 1.0);

}  // namespace dqo::objects
