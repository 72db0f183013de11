#pragma once
// Single-view ellipsoid from a detection box and the depth image, robust to the background that a
// detection box always holds. geometry's initialise_from_depth (the released code's rule: centre
// at the median depth in the box, depth axis from the depth spread) lands on the wall behind thin
// objects (a bottle covers a third of its box) and gives metre-long depth axes; measured on
// tabletop, most first views of the bottle and the laptop failed to associate afterwards.
//
// Here: the front surface is a low quantile of the depth in the central part of the box (an object
// covers its box's centre); the object's samples are those within an object's size behind it; the
// depth semi-axis is their spread, bounded by the lateral semi-axes (objects are about as deep as
// they are wide); the centre lies one depth semi-axis behind the front surface; the lateral
// semi-axes are the box's half width and height at the centre's depth. Rotation: the camera's axes.
#include <vector>
#include "dqo_map/geometry/quadric_init.h"

namespace dqo::objects {

QuadricInitResult initialise_from_depth_robust(const Box2d& box, const PinholeCamera& camera,
                                               const SE3& T_wc, const DepthView& depth,
                                               const DepthInitParams& params);

// Depth evidence of one observation: the single-view depth ellipsoid of its detection (world)
// and the pose of the camera that saw it.
struct DepthEvidence {
  SE3 T_cw;
  const DualQuadric* depth = nullptr;
};

// How far a quadric's centre lies from where the depth images put the object, along each
// observing camera's optical axis, in units of the depth ellipsoid's own half depth along that
// axis (+ 5 cm): median over the evidence of |z_c(q) − z_c(depth)| / (h_depth + 0.05 m). NaN
// without evidence. Box planes alone cannot fix an object's position along the viewing rays when
// the views' directions are few (room, the second table: seven boxes fitted to 11 px by an
// ellipsoid 1.9 m long and 0.45 m too low, whose centre lay 1 m behind the measured surface, 1.9
// of these units); the depth image can.
double depth_disagreement(const DualQuadric& quadric, const std::vector<DepthEvidence>& evidence);

}  // namespace dqo::objects
