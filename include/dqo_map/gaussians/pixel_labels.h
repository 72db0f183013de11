#pragma once
// Pixel labels for the mapper: the map object ID of every pixel of a keyframe (0 = background),
// from which new Gaussians take their object and against which L_ins is computed (METHOD.md §4,
// DESIGN.md mapping nodelet).
//   - From an instance image where the input has one: its values mapped to object IDs by a table
//     (a DetectionArray's image holds detection index + 1; a dataset's holds object IDs).
//   - Otherwise from the objects: a pixel whose back-projected depth point lies inside the
//     object's ellipsoid, scaled by `ellipsoid_scale`, and whose centre lies inside the object's
//     detection box takes the object's ID; where several claim a pixel, the higher-scoring
//     detection wins.

#include <cstdint>
#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/geometry/box2d.h"
#include "dqo_map/geometry/dual_quadric.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::gs {

using LabelImage = Image<uint32_t>;  // one channel, map object ID per pixel, 0 = background

// table[v] is the object ID of instance value v; values outside the table, and 0, become 0.
LabelImage labels_from_instance(const InstanceImage& instance, const std::vector<uint32_t>& table);

// Instance values are object IDs already (ground truth, the dataset's instance/ images).
LabelImage labels_from_instance(const InstanceImage& instance);

// One object as seen in the keyframe: its map ID, its quadric (world frame), the detection that
// matched it and that detection's score.
struct LabelledObject {
  uint32_t object_id = 0;
  DualQuadric quadric;
  Box2d box;
  float score = 1.f;
};

struct ObjectLabelParams {
  double ellipsoid_scale = 1.2;  // semi-axes multiplied by this for the inside test
  double min_depth = 0.0;        // metres; depth outside [min, max] labels nothing
  double max_depth = 1e9;
};

// `depth` in metres (0 / NaN = no measurement: never labelled), T_wc the keyframe's pose.
LabelImage labels_from_objects(const DepthImage& depth, const PinholeCamera& camera,
                               const SE3& T_wc, const std::vector<LabelledObject>& objects,
                               const ObjectLabelParams& params = ObjectLabelParams());

}  // namespace dqo::gs
