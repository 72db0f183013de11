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

// METHOD.md §2.3–2.4.
struct AssociationParams {
  AssociationStrategy strategy = AssociationStrategy::kIouQd;
  double min_iou = 0.5;                // coarse gate: projected conic box vs detection
  QuadricDistanceParams distance;      // fine gate: which similarity and its scale
  double min_similarity = 0.5;         // fine gate: QD (or W2 similarity) at least this
  int max_init_views = 10;             // views used for the fine step's box-plane quadric
  bool require_same_class = false;     // a detector's class confusions should not split objects
};

// METHOD.md §2.5.
struct MergeParams {
  bool enabled = true;
  double min_overlap = 0.85;           // t = overlap(box_i, box_j) / area(box_j)
  double max_distance = 0.1;           // d: the QD condition of the merge (see object_mapper.cpp)
};

// Object lifecycle (DESIGN.md): candidates, confirmation, removal.
struct LifecycleParams {
  int confirm_observations = 3;        // a candidate with this many observations is confirmed
  int candidate_max_missed = 3;        // a candidate missed this often where visible: REMOVED
  int candidate_max_age_keyframes = 30;// a candidate not confirmed within this many keyframes: REMOVED
  int remove_after_missed = 0;         // a confirmed object missed this often in a row: REMOVED
                                       // (0 = never remove confirmed objects)
  int min_box_views = 3;               // box-plane initialisation needs this many views
  bool single_view_fallback = true;    // depth initialisation while fewer views (needs depth)
  InitParams box_init;
  DepthInitParams depth_init;
};

struct ObjectMapperParams {
  DetectionFilterParams filter;
  VisibilityParams visibility;
  AssociationParams association;
  MergeParams merge;
  LifecycleParams lifecycle;
  RefinementParams refinement;
  bool refine = true;                  // IoU refinement of the objects seen in each keyframe
};

}  // namespace dqo::objects
