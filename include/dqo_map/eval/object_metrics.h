#pragma once
// Object pose metrics (METHOD.md §6): estimated objects matched one-to-one to ground truth, then
// 3D IoU of oriented boxes, 2D IoU of projected boxes and centre distance error (CDE).
//
// Matching. A pair (estimate, ground truth) is admissible when the classes agree and the centres
// lie within half the ground-truth box's largest full extent, i.e. within its largest half extent.
// Among admissible pairs the matching takes as many pairs as possible and, among those, the least
// total centre distance (an exact assignment, per class). Estimates left over are spurious, ground
// truth left over is unmatched.
//
// Objects are boxes: for an estimated ellipsoid the box has the same centre and rotation and half
// extents = semi-axes (box_from_quadric); a ground-truth box is itself.
//
// Means. mean_iou_3d is over ground-truth objects (sum over matches / num_gt), so an unmatched
// object counts as 0: the benchmark target "mean 3D IoU >= 0.6" is over the scene's objects, and a
// mean over matches alone would reward dropping hard objects. mean_iou_3d_matched is the mean over
// matches. mean_iou_2d likewise counts every ground-truth object seen in at least one view (0 when
// unmatched); mean_cde is over matches (CDE has no value without a match).

#include <cstdint>
#include <optional>
#include <vector>

#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/oriented_box.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::eval {

struct ObjectEstimate {
  uint64_t id = 0;
  int class_id = 0;
  OrientedBox box;  // world frame; for an ellipsoid half_extents = semi-axes
};

// A camera view for the 2D IoU: intrinsics and the camera-to-world pose.
struct EvalView {
  PinholeCamera camera;
  SE3 T_wc;
};

// What is projected for the 2D IoU.
enum class Projection2d {
  // Both objects as their boxes: the image bounding box of the 8 projected corners. The 2D
  // counterpart of the 3D IoU (which also compares boxes); an estimate equal to the ground truth
  // scores 1.
  kBoxes,
  // Both objects as the ellipsoids inscribed in their boxes: the bounding box of the projected
  // conic, which is what the mapper fits to detections.
  kEllipsoids,
};

struct ObjectEvalParams {
  Projection2d projection = Projection2d::kBoxes;
  // A view counts for a ground-truth object when the whole object lies deeper than this (metres)
  // and its projected box overlaps the image.
  double near = 0.01;
};

struct ObjectMatch {
  uint64_t est_id = 0;
  uint64_t gt_id = 0;
  int class_id = 0;
  double iou_3d = 0.0;           // exact, oriented boxes
  double iou_2d = 0.0;           // mean over views_2d views; NaN when views_2d == 0
  double centre_distance = 0.0;  // metres
  // Views where the ground truth is wholly in front of the camera and its box overlaps the image.
  // The estimate's box is clipped to the image; where the estimate cannot be projected (it
  // reaches behind the camera) the view scores 0.
  int views_2d = 0;
};

struct ObjectMetrics {
  std::vector<ObjectMatch> matches;    // in ground-truth order
  std::vector<uint64_t> unmatched_gt;  // ground-truth IDs without a match, in input order
  std::vector<uint64_t> spurious;      // estimate IDs without a match, in input order
  int num_gt = 0;
  int num_matched = 0;
  int num_spurious = 0;
  double mean_iou_3d = 0.0;          // sum of match IoUs / num_gt (0 when num_gt == 0)
  double mean_iou_3d_matched = 0.0;  // over matches; NaN without matches
  // Sum of match 2D IoUs / ground-truth objects seen in at least one view; NaN when none is.
  double mean_iou_2d = 0.0;
  int num_gt_in_views = 0;  // that denominator
  double mean_cde = 0.0;    // metres, over matches; NaN without matches
};

// Pure function of its inputs; IDs are carried through, not interpreted (duplicates are allowed
// here, the file readers reject them).
ObjectMetrics evaluate_objects(const std::vector<ObjectEstimate>& estimated,
                               const std::vector<ObjectEstimate>& ground_truth,
                               const std::vector<EvalView>& views = {},
                               const ObjectEvalParams& params = {});

// The admissible radius of a ground-truth box: half its largest full extent.
double match_radius(const OrientedBox& gt_box);

// The image bounding box of a projected object, clipped to the image: nullopt when the object is
// not wholly deeper than `near` or (ellipsoids) its conic has no bounded box; empty (area 0) when
// it projects outside the image. Exposed for tests and tools that draw the boxes.
std::optional<Box2d> projected_image_box(const OrientedBox& box, const PinholeCamera& camera,
                                         const SE3& T_cw, Projection2d projection, double near);

}  // namespace dqo::eval
