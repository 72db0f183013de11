#pragma once
// Object pose refinement by the IoU loss (METHOD.md §3): minimise Σ_views (1 − GIoU(box(C*), box_obs))
// over the centre, the rotation (on SO(3): a Ceres quaternion manifold) and the log semi-axes, with
// C* = P Q* Pᵀ the projected dual conic and box() its closed-form bounding box clipped to the image.
// GIoU rather than IoU so that a view whose projected box misses the detection still pulls the
// ellipsoid towards it (IoU has zero gradient there). Ceres stays inside the .cpp file.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/quadric_init.h"

namespace dqo::objects {

struct RefinementParams {
  int max_iterations = 20;        // Ceres iterations (the released code: 20 Adam steps)
  int min_views = 2;              // objects seen in fewer views are left as they are
  int max_views = 30;             // the most recent views used (bounded cost per object)
  // Edges within this margin of the image border are cut by it and carry no information about the
  // object's extent: both the projected box and the detection are clipped to the image shrunk by
  // the margin, so such edges agree wherever the object really ends beyond them.
  double border_margin_px = 5.0;
  // Semi-axes are kept within [min_semi_axis, max_semi_axis] metres: bounds on the log axes (an
  // initial axis outside them is clamped first).
  double min_semi_axis = 0.005;
  double max_semi_axis = 5.0;
  // Robust loss on each view's residual (detections of an occluded object are too small). The
  // solver minimises Σ huber(r²) with r = 1 − GIoU ∈ [0, 2]; views with r > huber_delta weigh in
  // linearly rather than quadratically.
  double huber_delta = 0.5;
};

// Priors of a levelled map (z up) for an object resting on a horizontal support (not in METHOD.md;
// SurfaceParams says why and holds the weights). Off by default.
struct RefinementPriors {
  bool upright = false;        // the ellipsoid axis nearest the vertical is pulled to the vertical
  double upright_weight = 1.0; // residual: weight × that axis's horizontal part (sin of its tilt)
  bool on_support = false;     // the ellipsoid's lowest point is pulled onto support_z
  double support_z = 0.0;
  double support_weight = 0.5; // residual: weight × (lowest point − support_z) / support_scale
  double support_scale = 0.02;
};

struct RefinementResult {
  bool ok = false;
  std::string error;              // empty when ok
  DualQuadric quadric;            // the refined ellipsoid (the input when not ok)
  double initial_cost = 0.0;      // Σ (1 − GIoU) over the views used, before and after
  double final_cost = 0.0;
  int views_used = 0;             // after skipping unusable views and keeping the max_views newest
  int views_skipped = 0;          // among the newest views considered: bad input, not in front, ...
  int iterations = 0;             // solver iterations (the initial evaluation not counted)
  double time_ms = 0.0;
};

// Views are BoxObservation (P = K [R_cw|t_cw], box, image size), the same type the box-plane
// initialisation takes, oldest first: the max_views usable views nearest the end are used. A view is
// skipped when its P or box is not finite, the box is empty once clipped to the image less the
// border margin, or the initial ellipsoid is not wholly in front of its camera (in_front_of_camera,
// evaluated from P's third row, which is the camera's depth for P = K [R|t] up to a positive scale).
// Fewer than min_views usable views, an invalid initial quadric or a failed solve give ok = false,
// a message in `error` and the input quadric. Never throws.
RefinementResult refine_quadric(const DualQuadric& initial,
                                const std::vector<BoxObservation>& views,
                                const RefinementParams& params = RefinementParams(),
                                const RefinementPriors& priors = RefinementPriors());

// The generalised IoU of two boxes, in [−1, 1] (1 for identical non-empty boxes): IoU − (C − U)/C
// with U the union and C the area of the smallest box enclosing both; empty boxes have area 0.
// 0 when C = 0 (both boxes degenerate and aligned); NaN when a coordinate is not finite.
double generalised_iou(const Box2d& a, const Box2d& b);

// For tests of the solver's derivatives: one view's residual r = 1 − GIoU(box(C*), detection), both
// boxes clipped to the image less border_margin_px, at centre, quaternion q = (w, x, y, z) (normalised
// inside, so any q ≠ 0) and log semi-axes, with its Jacobian from Ceres' automatic differentiation in
// the ambient coordinates (columns: centre 0–2, q 3–6, log axes 7–9). nullopt when the view is
// unusable or the conic has no bounded box there.
struct ViewResidual {
  double value = 0.0;
  Eigen::Matrix<double, 1, 10> jacobian = Eigen::Matrix<double, 1, 10>::Zero();
};
std::optional<ViewResidual> evaluate_view_residual(const BoxObservation& view,
                                                   const Eigen::Vector3d& centre,
                                                   const Eigen::Vector4d& q_wxyz,
                                                   const Eigen::Vector3d& log_axes,
                                                   double border_margin_px);

}  // namespace dqo::objects
