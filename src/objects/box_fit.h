#pragma once
// The object's oriented box from its detections: centre, rotation and half extents such that the
// image bounding box of the box's eight projected corners matches each detection (generalised IoU,
// like the quadric refinement, Ceres with a quaternion manifold and log half extents).
//
// Why, beside the ellipsoid: the refinement fits the ellipsoid's conic box to the detections, and a
// detection is the box of the object's silhouette. For a box-like object the silhouette's extent
// adds up its half extents linearly (Σ|h_i u_i|) while an ellipsoid's adds them in quadrature
// (sqrt(Σ a_i² u_i²)), so the fitted ellipsoid must be larger than the object in oblique views:
// measured on tabletop without any noise, the ellipsoid's box (half extents = semi-axes, METHOD.md
// §6) reaches a mean 3D IoU of only 0.50 against the ground-truth boxes (a flat book 0.23). The
// ellipsoid stays what association and the Gaussians use; the box is what the object list reports.
#include <vector>
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/oriented_box.h"
#include "dqo_map/geometry/quadric_init.h"
#include "dqo_map/objects/object_params.h"

namespace dqo::objects {

// A rotation's columns read as an upright frame: `up` the column nearest the vertical, `hx` the
// more horizontal of the other two (its heading is the yaw), `hy` the last.
struct UprightAxes {
  int up = 2, hx = 0, hy = 1;
  double yaw = 0.0;
};
UprightAxes upright_axes(const Eigen::Matrix3d& R);

// The box turned upright about its axis nearest the vertical: the same extents, that yaw.
OrientedBox upright_box(const OrientedBox& box);

struct BoxFitResult {
  bool ok = false;
  OrientedBox box;
  double initial_cost = 0.0;
  double final_cost = 0.0;      // Σ (1 − GIoU) of the box's corner boxes over the views used
  double ellipsoid_cost = 0.0;  // the same for the ellipsoid's conic boxes
  // The box explains the detections better than the ellipsoid (a box-like object): the object list
  // should report the box. For round objects (cups, bottles) the ellipsoid fits better, and its
  // box is the better estimate of the object's extent.
  bool better_than_ellipsoid = false;
  double time_ms = 0.0;
};

// Starts from the ellipsoid's centre and rotation. Views as for refine_quadric (oldest first).
BoxFitResult fit_box(const DualQuadric& ellipsoid, const std::vector<BoxObservation>& views,
                     const BoxFitParams& params);

}  // namespace dqo::objects
