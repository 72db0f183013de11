#pragma once
// Which map objects a keyframe should see (METHOD.md §2.2): ellipsoid wholly in front of the
// camera, at least a fraction of its projected box inside the image; of two projections that
// overlap more than occlusion_iou, only the nearer counts (the farther one is hidden behind it).
#include <vector>
#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"
#include "dqo_map/objects/object_params.h"

namespace dqo::objects {

struct VisibleObject {
  int index = 0;         // into the input list
  Box2d box;             // projected box clipped to the image
  Box2d unclipped;
  double depth = 0.0;    // camera depth of the centre, for the occlusion rule
};

// quadrics: the objects to test (those without an ellipsoid are not passed in). Returns the
// visible, unoccluded ones in input order; `hidden` (optional) receives the indices of objects
// that project into the image but lie behind a nearer one.
std::vector<VisibleObject> visible_objects(const std::vector<const DualQuadric*>& quadrics,
                                           const PinholeCamera& camera, const SE3& T_cw,
                                           const VisibilityParams& params,
                                           std::vector<int>* hidden = nullptr);

}  // namespace dqo::objects
