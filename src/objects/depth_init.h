#pragma once
// The objects' use of the single-view depth ellipsoids (geometry's initialise_from_depth, robust to
// the background in a detection box): the depth check of box-plane quadrics.
#include <vector>
#include "dqo_map/geometry/quadric_init.h"

namespace dqo::objects {

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
