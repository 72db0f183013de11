#pragma once
// Closing the side of an object that no camera can see because it rests on something: the bottom of
// a cup on a table, of a book on a shelf. Every view sees the object from the free side of its
// support, so a TSDF of the views leaves the contact face open, and the evaluation protocols
// (METHOD.md §6) measure completion against the whole, closed ground-truth mesh: on `tabletop`
// the open bottoms alone cost 10–30 points of the completion ratio (BENCHMARKS.md).
//
// The support is found in the data, without a gravity direction: a plane fitted (RANSAC) to the
// background's surface points around the object; it supports the object when the object lies on
// one side of it and part of its surface comes within `contact_distance` of it. The footprint is
// the convex hull of those contact points on the plane (a cup's ring becomes its disc, a book's
// contact edges its rectangle, also where a side was never seen). The closure is one more TSDF
// view: a virtual camera under the plane looking at the footprint, whose depth puts a surface on
// the plane there and free space below it; fused with the real views, it gives the object a bottom
// where it meets its support. Plain Eigen (no Open3D): the view goes to fuse_object like the others.

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "dqo_map/geometry/oriented_box.h"
#include "dqo_map/mesh/tsdf_fusion.h"

namespace dqo::mesh {

struct SupportClosureParams {
  bool enabled = true;
  // RANSAC plane fit to the background points: inlier distance, iterations, minimum inliers.
  double plane_inlier = 0.004;  // metres; a table top's Gaussians scatter by ~1 mm
  int iterations = 300;
  int min_inliers = 30;
  // Object surface within this of the plane is in contact with it. The lowest rim of a seen side
  // lies within a voxel or two of the support; 1.5 cm also takes the rim where the surface
  // bends under (a bottle's rounded foot).
  double contact_distance = 0.015;
  int min_contact_points = 20;
  // Object surface more than this on the far side of the plane means the plane does not support
  // the object (it cuts through it): no closure. A plane through the middle of an object leaves
  // a third to a half of it beyond; labels from quadrics (a rim of the support taken for the
  // object) and tracked poses (the rim doubled) put up to ~10 % there on `tabletop`.
  double max_penetration = 0.01;
  double max_penetrating_fraction = 0.15;
  // Share of the footprint's boundary (the hull of the contacts) that must lie within rim_cells
  // cells of a contact: legs touch the floor at a few points of their hull's boundary.
  double min_rim_coverage = 0.5;
  int rim_cells = 3;
  double camera_distance = 1.0;  // metres: the virtual camera's distance under the plane
  uint64_t seed = 1;
};

struct SupportClosureInfo {
  bool closed = false;
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // the plane's, pointing to the object
  double offset = 0.0;                               // plane: normal · x = offset
  int plane_inliers = 0;
  int contact_points = 0;
  int footprint_cells = 0;
  double penetrating_fraction = 0.0;  // of the object's surface beyond max_penetration
  double rim_coverage = 0.0;          // of the footprint's boundary near a contact
  const char* reason = "";  // why not closed
};

// The virtual view that closes the object's contact face, or nullopt (with info->reason) when no
// plane supports the object. `object_views` are the object's own renders (as for fuse_object),
// `background` surface points around the object (e.g. background Gaussians' centres near its
// box), `voxel_size` the TSDF's.
std::optional<FusionView> support_closure_view(const std::vector<FusionView>& object_views,
                                               const std::vector<Eigen::Vector3d>& background,
                                               const OrientedBox& object_box, double voxel_size,
                                               const SupportClosureParams& params,
                                               SupportClosureInfo* info = nullptr);

}  // namespace dqo::mesh
