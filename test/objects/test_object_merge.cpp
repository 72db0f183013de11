// The occlusion merge (METHOD.md §2.5) and what this package adds to it: two objects that one
// keyframe detected apart are never merged, however their projections nest later.
#include <gtest/gtest.h>

#include "../../src/objects/object_merge.h"

namespace dqo::objects {
namespace {

MapObject chair(ObjectId id, const Eigen::Vector3d& centre, const Eigen::Vector3d& axes) {
  MapObject o;
  o.id = id;
  o.state = ObjectState::kConfirmed;
  o.class_id = 10;
  o.quadric = DualQuadric::from_params(centre, Eigen::Matrix3d::Identity(), axes);
  o.has_quadric = true;
  return o;
}

ObjectObservation observation(KeyFrameId kf, const Box2d& box) {
  ObjectObservation o;
  o.keyframe_id = kf;
  o.box = box;
  o.class_id = 10;
  o.score = 0.8f;
  return o;
}

VisibleObject visible(int index, const Box2d& box) {
  VisibleObject v;
  v.index = index;
  v.box = v.unclipped = box;
  v.depth = 2.0;
  return v;
}

// Two chairs seen from the side, one behind the other: the nearer one's (too long) ellipsoid holds
// the farther one's centre and the farther one's box lies inside the nearer one's. The paper's test
// merges them; an earlier keyframe that detected both apart keeps them two.
TEST(ObjectMerge, ObjectsDetectedApartInOneKeyframeStayTwo) {
  MapObject near = chair(1, Eigen::Vector3d(0, 0, 0.5), Eigen::Vector3d(0.3, 0.45, 0.5));
  MapObject far = chair(2, Eigen::Vector3d(0, 0.3, 0.5), Eigen::Vector3d(0.22, 0.21, 0.48));
  const std::vector<const MapObject*> objects{&near, &far};
  const std::vector<VisibleObject> seen{visible(0, Box2d{100, 100, 300, 400}),
                                        visible(1, Box2d{130, 110, 290, 390})};
  MergeParams params;
  ASSERT_GT(params.max_seen_apart_iou, 0.0);  // on by default

  // Never seen in one keyframe: the paper's rule merges the farther into the nearer.
  near.observations = {observation(3, Box2d{100, 100, 300, 400})};
  far.observations = {observation(4, Box2d{130, 110, 290, 390})};
  auto pairs = find_merges(objects, seen, params);
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0].from, 1);
  EXPECT_EQ(pairs[0].into, 0);

  // Keyframe 5 detected both, side by side: boxes of IoU 6000 / 14000 = 0.43.
  near.observations.push_back(observation(5, Box2d{100, 100, 200, 200}));
  far.observations.push_back(observation(5, Box2d{140, 100, 240, 200}));
  EXPECT_TRUE(seen_apart(near, far, params.max_seen_apart_iou));
  EXPECT_TRUE(find_merges(objects, seen, params).empty());

  // Off (the paper's rule alone): merged again.
  MergeParams paper = params;
  paper.max_seen_apart_iou = 0.0;
  EXPECT_EQ(find_merges(objects, seen, paper).size(), 1u);

  // Two detections of one keyframe that overlap more than the threshold (a duplicate the filter let
  // through) are no evidence of two things: IoU 8000 / 12000 = 0.67.
  far.observations.back().box = Box2d{120, 100, 220, 200};
  EXPECT_FALSE(seen_apart(near, far, params.max_seen_apart_iou));
  EXPECT_EQ(find_merges(objects, seen, params).size(), 1u);
}

}  // namespace
}  // namespace dqo::objects
