#pragma once
// Parameters of the object stage, one struct per step (METHOD.md §2–3), gathered in
// ObjectMapperParams. Defaults follow METHOD.md; departures are commented with the reason.
// config/objects.yaml lists every field (params_yaml.h loads it strictly).
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
  double duplicate_iou_same_class = 0.3;
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
};

// Object lifecycle (DESIGN.md): candidates, confirmation, removal.
struct LifecycleParams {
  int confirm_observations = 3;        // a candidate with this many observations is confirmed
  int candidate_max_missed = 3;        // a candidate missed this often where visible: REMOVED
  int candidate_max_age_keyframes = 30;// a candidate not confirmed within this many keyframes: REMOVED
  // A confirmed object missed this often in a row where it should be seen: REMOVED (0 = never).
  // 8: early objects placed wrongly (a box-plane fit from a short baseline, a depth ellipsoid on
  // an occluder) otherwise stay as spurious objects next to the right one (room: 4 -> 1 spurious;
  // with a detector's 10 % misses, 8 misses in a row of a right object is rare).
  int remove_after_missed = 8;
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
  bool refine = true;                  // IoU refinement of the objects seen in each keyframe
};

}  // namespace dqo::objects
