#pragma once
// Object pose refinement by the IoU loss (METHOD.md §3): minimise Σ_views (1 − GIoU(box(C*), box_obs))
// over the centre, the rotation (on SO(3): a Ceres quaternion manifold) and the log semi-axes, with
// C* = P Q* Pᵀ the projected dual conic and box() its closed-form bounding box clipped to the image.
// GIoU rather than IoU so that a view whose projected box misses the detection still pulls the
// ellipsoid towards it (IoU has zero gradient there). Ceres stays inside the .cpp file.
#include <string>
#include <vector>
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/quadric_init.h"

namespace dqo::objects {

struct RefinementParams {
  int max_iterations = 20;        // Ceres iterations (the released code: 20 Adam steps)
  int min_views = 2;              // objects seen in fewer views are left as they are
  int max_views = 30;             // the most recent views used (bounded cost per object)
  // Views whose projected box (or detection) touches the image border compare clipped boxes;
  // edges within this margin of the border carry no information about the object's extent.
  double border_margin_px = 5.0;
  // Semi-axes are kept within [min_semi_axis, max_semi_axis] metres (soft, by the log-axis bounds).
  double min_semi_axis = 0.005;
  double max_semi_axis = 5.0;
  // Robust loss on each view's residual (detections of an occluded object are too small).
  double huber_delta = 0.5;
};

struct RefinementResult {
  bool ok = false;
  std::string error;              // empty when ok
  DualQuadric quadric;            // the refined ellipsoid (the input when not ok)
  double initial_cost = 0.0;      // Σ (1 − GIoU) over the views used, before and after
  double final_cost = 0.0;
  int views_used = 0;
  int iterations = 0;
  double time_ms = 0.0;
};

// Views are BoxObservation (P = K [R_cw|t_cw], box, image size), the same type the box-plane
// initialisation takes. Never throws; a view where the ellipsoid is not in front of the camera is
// skipped.
RefinementResult refine_quadric(const DualQuadric& initial,
                                const std::vector<BoxObservation>& views,
                                const RefinementParams& params = RefinementParams());

// The generalised IoU of two boxes, in [−1, 1] (1 for identical boxes); for the loss and its tests.
double generalised_iou(const Box2d& a, const Box2d& b);

}  // namespace dqo::objects
