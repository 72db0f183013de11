#pragma once
// Stage: an object's own surface from depth (not in METHOD.md; issue 24): points sampled inside its
// detection boxes, the horizontal support it stands on in a levelled (z-up) map, and the box that
// agrees with both the points and the detections.
//
// Why: the ellipsoid and the box fitted to detection boxes overestimate where views are few (a
// silhouette box holds the object and whatever the views cannot separate from it), while an
// object's depth points underestimate its unseen back. The surface box takes each face from the
// points where some keyframe looked at that face, from the detections' box where none did, and the
// bottom from the support the object rests on.
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/oriented_box.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/quadric_init.h"
#include "dqo_map/objects/object_params.h"

namespace dqo::objects {

// Valid depth samples on a grid over `box` (about params.samples_per_box), in the camera frame.
std::vector<Eigen::Vector3f> sample_box_points(const Box2d& box, const PinholeCamera& camera,
                                               const DepthView& depth, const SurfaceParams& params);

// About 300 depth samples of the ring around `box` (the box grown by a quarter of its size on
// each side, the box itself left out), camera frame: the surface the detection sits in. Empty
// without depth or for an invalid box. fit_ring_surface reads it.
std::vector<Eigen::Vector3d> ring_points(const Box2d& box, const PinholeCamera& camera, const DepthView& depth,
                                         const SurfaceParams& params);

// A plane among a ring's samples: n·p = d, n pointing away from the camera (camera frame), with
// the number of ring samples within the plane tolerance.
struct RingPlane {
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  double d = 0.0;
  size_t inliers = 0;
};

// The surface a detection sits in, as up to two planes of its ring (ring_points): the largest (a
// seeded RANSAC over triples, refined by least squares over its inliers: the same depth gives the
// same planes), then the largest among the samples it leaves (a wall and the floor below it, a
// table and the wall behind it). A plane holds at least 30 samples and a tenth of the ring.
struct RingSurface {
  std::vector<RingPlane> planes;  // largest first
  size_t samples = 0;             // ring samples
};
RingSurface fit_ring_surface(const std::vector<Eigen::Vector3d>& ring_c, const SurfaceParams& params);

// How much a detection's content stands out of the surface around it: the share of `box_points_c`
// (the box's samples, camera frame) farther than stand_out_distance from every plane of `ring`.
// A detector's clutter on a wall, on a table or where they meet is a patch of that surface (share
// near 0); an object stands out of it. NaN where the planes leave more than 1 − ring_explained of
// the ring (other objects around it: nothing to say) or the ring holds too few samples.
double stand_out_share(const std::vector<Eigen::Vector3f>& box_points_c, const RingSurface& ring,
                       const SurfaceParams& params);

// A plane behind an object that it cannot pass: the wall a TV hangs on, the sofa's back behind a
// cushion. n·p = d with n pointing away from the camera; frame as the caller's points.
struct BackPlane {
  Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  double d = 0.0;
};

// The ring's largest plane (fit_ring_surface), if it holds at least a third of the ring (and 30
// samples) and the box's content stands in front of it (the median of `box_points_c` more than
// stand_out_distance on the camera's side). Camera frame. Unlike stand_out_share, a part of the
// ring suffices: the wall above a sofa, with the floor below it.
std::optional<BackPlane> find_back_plane(const std::vector<Eigen::Vector3f>& box_points_c, const RingSurface& ring,
                                         const SurfaceParams& params);

struct SupportEstimate {
  bool found = false;
  double z = 0.0;       // height of the support's top (map frame, z up)
  int points = 0;       // points in its height band
};

// The support under `q` among `points_w` (the boxes' points: the object and what surrounds it):
// the lowest 2 cm height band, from support_max_gap below the object's lowest points up to them,
// holding at least min_support_points of the points around the object (within its footprint
// grown by support_reach, below its centre, outside its ellipsoid grown by half: a plane that
// extends beyond the object, not its own near-horizontal parts).
SupportEstimate find_support(const std::vector<Eigen::Vector3d>& points_w, const DualQuadric& q,
                             const SurfaceParams& params);

// The points of the object itself: inside its ellipsoid grown by ellipsoid_margin and, where a
// support was found, above the support's band.
std::vector<Eigen::Vector3d> object_points(const std::vector<Eigen::Vector3d>& points_w, const DualQuadric& q,
                                           const SupportEstimate& support, const SurfaceParams& params);

// The extent of the points along `direction` between the trim and 1 − trim quantiles (0 for none).
double trimmed_spread(const std::vector<Eigen::Vector3d>& points_w, const Eigen::Vector3d& direction, double trim);

// At least min_points points, all but the trimmed quantiles within 2 × support_band in height: a
// patch of a horizontal surface, not an object standing on one.
bool flat_patch(const std::vector<Eigen::Vector3d>& points_w, const SurfaceParams& params);

struct SurfaceBoxResult {
  bool ok = false;
  OrientedBox box;
  int points = 0;
  int faces_from_points = 0;  // of the six faces, those a keyframe looked at
  int faces_from_back_planes = 0;  // unseen faces held in front of a plane behind the object
  // The smallest ratio, over the axes no back plane shortened, of the box's extent to the
  // detections' box's along the same axis (callers refuse slivers by it).
  double min_extent_ratio = 0.0;
};

// An upright box (yaw about z): the yaw of the smallest footprint of the points' trimmed extent
// (the detections' box yaw where the points are too few or no yaw is clearly better); each side
// from the points' trimmed extent where a camera looked at that face, else the farther of the
// points' and the detections' box; the bottom on the support where the object rests on it.
// back_planes_w: planes behind the object (find_back_plane's, in the map frame) from its views; an
// unseen horizontal face whose axis is within back_plane_max_angle of a vertical plane's normal
// (median over those planes) stops at that plane, not at the detections' box beyond it.
SurfaceBoxResult fit_surface_box(const std::vector<Eigen::Vector3d>& points_w, const OrientedBox& detections_box,
                                 const std::vector<Eigen::Vector3d>& camera_centres_w,
                                 const SupportEstimate& support, const SurfaceParams& params,
                                 const std::vector<BackPlane>& back_planes_w = {});

}  // namespace dqo::objects
