// The fine gate's exception (AssociationParams::accept_iou): a detection that the object's
// projection covers nearly exactly is that object even where the fine step's quadric (from one
// view's depth here) disagrees with the object's, as for a TV whose few views put it on the wall.
#include <gtest/gtest.h>

#include "../../src/objects/association.h"
#include "dqo_map/geometry/conic.h"
#include "dqo_map/geometry/quadric_distance.h"
#include "object_test_util.h"

namespace dqo::objects {
namespace {

TEST(Association, ANearlyExactProjectionOvercomesAFailedFineGate) {
  const PinholeCamera camera = test::test_camera();
  const SE3 T_wc = SE3::identity();
  // The object as its few views made it: 1.2 m deep along the line of sight, centred 3 m away.
  MapObject object;
  object.id = 7;
  object.state = ObjectState::kCandidate;
  object.has_quadric = true;
  object.quadric = DualQuadric::from_params(Eigen::Vector3d(0.0, 0.0, 3.0), Eigen::Matrix3d::Identity(),
                                            Eigen::Vector3d(0.5, 0.35, 1.2));
  const std::optional<Box2d> projected = test::exact_box(object.quadric, camera, T_wc);
  ASSERT_TRUE(projected);
  // The depth shows a flat panel 1.8 m away filling the view (a TV on its wall, seen head-on).
  const DepthImage depth = test::render_depth({}, camera, T_wc, 1.8f);
  AssociationFrame frame;
  frame.camera = &camera;
  frame.T_wc = T_wc;
  frame.P = camera.projection_matrix(T_wc.inverse());
  frame.depth = test::view_of(depth);
  const ViewLookup no_views = [](const ObjectObservation&) { return std::nullopt; };
  LifecycleParams lifecycle;
  AssociationParams params;
  ASSERT_EQ(params.strategy, AssociationStrategy::kIouQd);
  const std::vector<AssociationTrack> tracks{{&object, *projected}};

  // The fine step's quadric (the detection's depth ellipsoid: no stored views) fails the QD gate.
  const std::optional<DualQuadric> observed =
      observation_quadric(object, *projected, frame, no_views, params.max_init_views, lifecycle);
  ASSERT_TRUE(observed);
  ASSERT_LT(quadric_similarity(*observed, object.quadric, params.distance), params.min_similarity);

  Detection2d exact;
  exact.box = *projected;
  exact.class_id = 1;
  exact.score = 0.9f;
  // The paper's gates alone: no match.
  AssociationParams paper = params;
  paper.accept_iou = 1.01;
  EXPECT_EQ(associate(tracks, {exact}, frame, no_views, paper, lifecycle).track_to_detection[0], -1);
  // With the exception: matched.
  EXPECT_EQ(associate(tracks, {exact}, frame, no_views, params, lifecycle).track_to_detection[0], 0);
  // A box the projection covers at IoU 0.6 (past the coarse gate, short of accept_iou): no match.
  Detection2d shifted = exact;
  const double w = projected->width();
  shifted.box.x_min += 0.25 * w;
  shifted.box.x_max += 0.25 * w;
  const double overlap = iou(shifted.box, *projected);
  ASSERT_GT(overlap, params.min_iou);
  ASSERT_LT(overlap, params.accept_iou);
  EXPECT_EQ(associate(tracks, {shifted}, frame, no_views, params, lifecycle).track_to_detection[0], -1);
}

}  // namespace
}  // namespace dqo::objects
