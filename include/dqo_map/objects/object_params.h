#pragma once
// Parameters of the object stage, one struct per step (METHOD.md §2–3), gathered in
// ObjectMapperParams. Defaults follow METHOD.md; departures are commented with the reason.
// config/objects.yaml lists every field (params_yaml.h loads it strictly).
#include <map>
#include <string>
#include "dqo_map/geometry/quadric_distance.h"
#include "dqo_map/geometry/quadric_init.h"
#include "dqo_map/objects/object_refinement.h"

namespace dqo::objects {

// METHOD.md §2.1 (VOOM's filter).
struct DetectionFilterParams {
  double min_score = 0.2;
  double min_area_px = 300.0;
  double max_area_fraction = 0.5;      // of the image area
  double border_margin_px = 5.0;       // boxes within this of the image border are dropped
  // METHOD.md (VOOM's filter): 0.3. Two chairs side by side, one partly behind the other, overlap
  // 0.41-0.43 from the room's dining-table views: at 0.3 one of them was dropped in every such view
  // and the two became one object (room 20/21 -> 21/21, mean 3D IoU 0.534 -> 0.588; BENCHMARKS.md).
  // A detector's own NMS (0.45-0.65) already removes its duplicates.
  double duplicate_iou_same_class = 0.5;
  double duplicate_iou_other_class = 0.6;
  int max_detections = 200;            // per keyframe; the rest (lowest scores) are dropped
};

// METHOD.md §2.2.
struct VisibilityParams {
  double min_fraction_in_image = 0.3;  // of the projected box
  double occlusion_iou = 0.8;          // two projections overlapping more: keep the nearer
  double near = 0.05;                  // metres; the ellipsoid must lie wholly beyond this depth
};

enum class AssociationStrategy { kIou, kQd, kIouQd };
const char* to_string(AssociationStrategy strategy);
// "iou", "qd", "iou+qd"; false for anything else.
bool parse_association_strategy(const std::string& text, AssociationStrategy* strategy);

// Which quadric the fine step compares with the object's (METHOD.md §2.4).
enum class FineQuadric {
  kBoxes,  // box planes of the object's recent observations plus the detection (the paper); the
           // detection's depth ellipsoid where that fit fails or there are too few views
  kDepth,  // the detection's single-view depth ellipsoid; box planes where there is no depth
};
const char* to_string(FineQuadric source);
// "boxes", "depth"; false for anything else.
bool parse_fine_quadric(const std::string& text, FineQuadric* source);

// METHOD.md §2.3–2.4.
struct AssociationParams {
  AssociationStrategy strategy = AssociationStrategy::kIouQd;
  double min_iou = 0.5;                // coarse gate: projected conic box vs detection
  QuadricDistanceParams distance;      // fine gate: which similarity and its scale
  // Fine gate: QD (or W2 similarity) at least this. METHOD.md gives no value; 0.5 (tau = 1) rejected
  // right matches whose box-plane quadric from a few noisy views was poor (room: 8 spurious
  // duplicates, 20/21 found); 0.2 still rejects objects metres apart (bench_objects, BENCHMARKS.md).
  double min_similarity = 0.2;
  // ... except where the coarse IoU is at least this (strategy iou+qd): the fine step's quadric of a
  // candidate from few views is what fails then. Room with the real-detector profile: the TV's
  // detections at IoU 0.78-0.79 failed QD at 0.18-0.19 and split it into two candidates, neither
  // confirmed (19/21 -> 20/21; BENCHMARKS.md). > 1: off (the paper).
  double accept_iou = 0.75;
  int max_init_views = 10;             // views used for the fine step's box-plane quadric
  FineQuadric fine_quadric = FineQuadric::kBoxes;
  bool require_same_class = false;     // a detector's class confusions should not split objects
};

// METHOD.md §2.5.
struct MergeParams {
  bool enabled = true;
  // t = overlap(box_i, box_j) / area(box_j). METHOD.md: 0.85 and d = 0.1; 0.7 and 0.25 m merge
  // more of the duplicates that noisy boxes leave on room (spurious 5 -> 4, measured together with
  // min_similarity 0.2; BENCHMARKS.md).
  double min_overlap = 0.7;
  double max_distance = 0.25;          // d: the piece's centre within the whole grown by d (object_merge.h)
  // Ellipsoids whose boxes overlap at least this 3D IoU merge whatever their classes: twins a
  // detector's confusions started (a cup seen as bottle). A cup on a book does not come near. >1: off.
  double min_iou_3d_any_class = 0.3;
  // Two objects that one keyframe saw as two detections (one associated with each) whose boxes
  // overlap less than this 2D IoU are two things and never merge (object_merge.h seen_apart). The
  // detection filter's duplicate IoU keeps one of boxes that overlap more. 0: off (the paper).
  double max_seen_apart_iou = 0.5;
};

// The object's own surface from depth (src/objects/object_surface.h): its box from its points and
// the detections, and the support it stands on. Needs a levelled map (box_fit.upright: z up).
struct SurfaceParams {
  bool enabled = true;
  int samples_per_box = 400;          // depth samples kept per detection (a grid over the box)
  double min_depth = 0.1;             // m; samples outside are ignored
  double max_depth = 8.0;
  int max_views = 30;                 // the newest observations' points are used
  int max_points = 3000;              // at most this many of them (evenly strided): bounded cost
  double ellipsoid_margin = 1.25;     // points inside the ellipsoid scaled by this are the object's
  int min_points = 60;                // fewer: no surface box (the detections' box stays)
  // Each extent of the surface box (smallest to smallest, ...) at least this share of the
  // detections' box's: a thinner one comes from an ellipsoid that cut the points to a sliver.
  double min_extent_ratio = 0.3;
  double trim_quantile = 0.02;        // each side's extent from this quantile of the points
  double round_footprint = 0.93;      // smallest / largest footprint over yaw above this: round, yaw 0
  double support_reach = 0.1;         // m beyond the ellipsoid's footprint where the support is sought
  double support_band = 0.015;        // m; points this close above the support are the support
  double support_max_gap = 0.08;      // m; the object's lowest points within this of it: it rests on it
  // A candidate is confirmed only where its detections' content stands out of the surface around
  // them (object_surface.h stand_out_share; median over its observations that can tell): at least
  // min_stand_out of the box's depth samples farther than stand_out_distance from the ring's plane.
  // m, plus 0.005 z² for the depth noise at the sample's depth z. 0.02 (session 13) left a 3 cm
  // book on a table 1.5 m away standing out of nothing (0.02 + 0.011 > 0.03): room's second book
  // was never confirmed with the real-detector profile (BENCHMARKS.md, session 14).
  double stand_out_distance = 0.012;
  double plane_tolerance = 0.015;     // m (+ 0.005 z²): a ring sample this near a plane lies on it
  double ring_explained = 0.85;       // share of the ring its (up to two) planes must hold to judge
  // A laptop on a desk seen from above: 0.05-0.06 of its box stands out (the screen); a patch of
  // a wall or a table: none beyond the noise.
  double min_stand_out = 0.03;
  int min_support_points = 20;        // around the object (outside its ellipsoid grown by half), in a 2 cm band
  // An unseen horizontal face of the surface box stops at a vertical plane seen behind the object
  // around its boxes (object_surface.h find_back_plane: a wall, a sofa's back) whose normal lies
  // within this angle of the face's axis. 0: off (the face from the detections' box).
  double back_plane_max_angle_deg = 30.0;
  // Refinement's priors where the object rests on a support in a levelled map: one ellipsoid axis
  // vertical (residual: that axis's horizontal part) and the ellipsoid's bottom on the support
  // (residual in units of support_scale). Weighed against each view's 1 − GIoU: the views can
  // overcome them (a tilted lid keeps its box upright; the shape is free).
  double upright_weight = 1.0;
  double support_weight = 0.5;
  double support_scale = 0.02;        // m
};

// The object's class from its vote (object_types.h: labels as a histogram).
struct LabelParams {
  // The class changes only when another class has more than this times the current one's votes
  // (then a kRenamed event): look-alike classes with about equal votes do not flip the name.
  double rename_margin = 1.25;
  int top_classes = 3;                 // classes (and shares) reported per object
};

// Whether an object exists, as a belief updated by evidence (DESIGN.md association_node): log-odds
// l = log(p / (1 − p)), per keyframe where the object should be visible (in view, unoccluded,
// wholly inside the image):
//   detected        l += log(recall / false_alarm_rate)
//   missed          l += w · log((1 − recall) / (1 − false_alarm_rate)), with w = supported_miss_weight
//                   where the keyframe's depth shows a surface inside the projected ellipsoid where
//                   the object should be (a detector's miss of something that is there), 1 otherwise
//   depth sees through the ellipsoid (free space where the object is claimed): also + free_space
//   occluded (depth nearer than the object's front) or cut by the border: no change
//   once per candidate, when it is judged for confirmation: where more than half of its detections
//   stand clearly out of their surroundings (a stand-out share, object_surface.h, ≥ clear_stand_out)
//                   l += log(clear_stand_out_if_object / clear_stand_out_if_clutter)
// A real detector misses objects most of the time (recall 30–70 % on small, occluded or sideways
// objects and on classes outside its vocabulary), so a miss of an object it rarely sees costs
// little, a detection much: an object seen in 17 of 58 views is confirmed and stays, a box seen
// once is not. The miss counters this replaces removed such objects (0 objects on real data).
struct ExistenceParams {
  double prior = 0.1;               // P(exists) of a new candidate before its first detection
  double recall = 0.5;              // P(detected | exists, should be seen): the detector's recall
  // Per class name, overriding `recall`: "refrigerator: 0.3, tv: 0.6" (the object's current class).
  std::map<std::string, double> recall_by_class;
  double false_alarm_rate = 0.05;   // P(a detection associates here | no object here)
  double supported_miss_weight = 0.25;
  double free_space = -1.0;         // log-odds per keyframe whose depth sees through the ellipsoid
  double min_surface_fraction = 0.2;  // of the valid depth samples, to count as a surface there
  // The depth's shape as a second sensor beside the detector: P(more than half of an object's
  // detections stand clearly out of the surface around them | an object there) and (| false alarms).
  // Recurring clutter boxes (a mark on a wall, a patch of the table) do not; counting more of them
  // cannot tell them from an object, this can. Measured on room with the real-detector profile
  // (BENCHMARKS.md, session 15): a share ≥ 0.3 in 62 % of the objects' detections that can tell,
  // 7.5 % of the false alarms' (8 of 106). Taken as 0.6 and 0.15 (log-odds +1.39, about half of
  // one detection's): a real detector's false alarms fall on real things more often than the
  // simulated ones, and the sample is small. 1 turns it off.
  double clear_stand_out = 0.3;
  double clear_stand_out_if_object = 0.6;
  double clear_stand_out_if_clutter = 0.15;
  double confirm_probability = 0.95;  // a candidate reaching this is confirmed
  double remove_probability = 0.1;   // an object (candidate or confirmed) falling to this is removed
  double max_log_odds = 8.0;        // belief saturates here: an object that left can still go
  // A candidate not confirmed within this many keyframes (where it took no detection) is removed:
  // clutter on a real surface costs little per miss and would otherwise stay a candidate forever.
  int candidate_max_age_keyframes = 30;

  double recall_of(const std::string& class_name) const;
  double log_odds_detected(const std::string& class_name) const;
  double log_odds_missed(const std::string& class_name) const;
  double log_odds_depth_shape(bool stands_out) const;
};

// "a: 0.3, b: 0.6" <-> map; false (and *error) for a malformed list or a value outside (0, 1).
bool parse_recall_by_class(const std::string& text, std::map<std::string, double>* out,
                           std::string* error = nullptr);
std::string recall_by_class_to_string(const std::map<std::string, double>& recall);

// Object lifecycle (DESIGN.md): candidates, confirmation and removal by ExistenceParams.
struct LifecycleParams {
  ExistenceParams existence;
  int min_box_views = 3;               // box-plane initialisation needs this many views
  // Depth check of box-plane quadrics (not in METHOD.md; src/objects/depth_init.h): where the
  // observations have depth, a box-plane quadric whose centre lies further than this from where the
  // depth puts the object (depth_disagreement: median over the views, in units of the depth
  // ellipsoid's half depth + 5 cm) does not replace an ellipsoid that agrees better with the depth,
  // and the fine step compares the detection's depth ellipsoid instead. Box planes from a few
  // directions leave the position along the rays free (room: the second table's ellipsoid from
  // seven boxes lay 1 m behind the measured surface and 0.45 m too low; it replaced a right one and
  // then rejected the right detections: 20/21, 1 spurious). 0 = off.
  double max_depth_disagreement = 1.0;
  bool single_view_fallback = true;    // depth initialisation while fewer views (needs depth)
  InitParams box_init;
  DepthInitParams depth_init;
};

// The object's oriented box, fitted to the detections as a box (src/objects/box_fit.h says why):
// what the object list reports. The ellipsoid is not changed by it.
struct BoxFitParams {
  bool enabled = true;
  int max_iterations = 30;
  int min_views = 3;
  int max_views = 30;          // the newest views
  double initial_scale = 0.8;  // start from the ellipsoid's semi-axes times this
  double huber_delta = 0.5;    // robust loss on 1 − GIoU per view
  // Boxes stand upright: the rotation is a yaw about the world's z axis. Needs a map frame with z
  // up (the synthetic scenes, trajectories anchored to their ground truth); false for maps that
  // are not gravity-aligned (a tracker that starts at the first camera's frame).
  bool upright = true;
};

struct ObjectMapperParams {
  DetectionFilterParams filter;
  VisibilityParams visibility;
  AssociationParams association;
  MergeParams merge;
  LifecycleParams lifecycle;
  RefinementParams refinement;
  BoxFitParams box_fit;
  SurfaceParams surface;
  LabelParams labels;
  bool refine = true;                  // IoU refinement of the objects seen in each keyframe
};

}  // namespace dqo::objects
