// The object mapper end to end on synthetic views of ellipsoids: exact multi-view initialisation,
// the occlusion merge, the lifecycle (IDs, events, state file) and bad input.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <gtest/gtest.h>
#include "dqo_map/geometry/oriented_box.h"
#include "dqo_map/objects/object_mapper.h"
#include "object_test_util.h"

namespace dqo::objects {
namespace {

using test::detection;
using test::exact_box;
using test::look_at;
using test::render_depth;
using test::test_camera;

DualQuadric gt_ellipsoid() {
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
      Eigen::AngleAxisd(0.2, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  return DualQuadric::from_params(Eigen::Vector3d(0.3, -0.2, 0.8), R, Eigen::Vector3d(0.25, 0.15, 0.1));
}

// Keyframe k of an orbit around `target`: radius 1.4 m, `step` radians apart, height varying.
SE3 orbit_pose(int k, const Eigen::Vector3d& target, double step = 0.21) {
  const double a = step * k;
  const Eigen::Vector3d eye = target + Eigen::Vector3d(1.4 * std::cos(a), 1.4 * std::sin(a),
                                                       0.5 + 0.1 * std::sin(1.7 * k));
  return look_at(eye, target);
}

ObjectKeyFrame keyframe(KeyFrameId id, const SE3& T_wc, const PinholeCamera& camera) {
  ObjectKeyFrame kf;
  kf.id = id;
  kf.stamp = 0.1 * static_cast<double>(id);
  kf.camera = camera;
  kf.T_wc = T_wc;
  return kf;
}

int count_events(const std::vector<ObjectEvent>& events, ObjectEvent::Type type) {
  return static_cast<int>(std::count_if(events.begin(), events.end(),
                                        [&](const ObjectEvent& e) { return e.type == type; }));
}

// Noise-free boxes from several views: the box-plane initialisation inside the mapper recovers
// the ellipsoid exactly (to the precision of the SVD), with and without refinement.
TEST(ObjectMapper, NoiseFreeMultiViewInitialisationIsExact) {
  const DualQuadric gt = gt_ellipsoid();
  const PinholeCamera camera = test_camera();
  for (const bool refine : {false, true}) {
    for (const bool with_depth : {false, true}) {
      ObjectMapperParams params;
      params.refine = refine;
      ObjectMapper mapper(params);
      for (int k = 0; k < 6; ++k) {
        ObjectKeyFrame kf = keyframe(static_cast<KeyFrameId>(k + 1), orbit_pose(k, gt.centre()), camera);
        DepthImage depth;
        if (with_depth) {
          depth = render_depth({gt}, camera, kf.T_wc);
          kf.depth = test::view_of(depth);
        }
        const auto box = exact_box(gt, camera, kf.T_wc);
        ASSERT_TRUE(box);
        kf.detections.push_back(detection(*box));
        std::string error;
        const KeyFrameAssociation r = mapper.process_keyframe(kf, &error);
        ASSERT_TRUE(error.empty()) << error;
        ASSERT_EQ(r.object_ids.size(), 1u);
        EXPECT_EQ(r.object_ids[0], 1u) << "keyframe " << k << " refine " << refine << " depth " << with_depth;
      }
      const std::vector<MapObject> objects = mapper.objects();
      ASSERT_EQ(objects.size(), 1u);
      const MapObject& o = objects[0];
      EXPECT_EQ(o.state, ObjectState::kConfirmed);
      EXPECT_TRUE(o.from_boxes);
      EXPECT_EQ(o.observations.size(), 6u);
      // Compare the matrices (the decomposition of a near-spheroid is not unique).
      const double tol = refine ? 2e-3 : 1e-6;
      EXPECT_LT((o.quadric.centre() - gt.centre()).norm(), tol);
      EXPECT_LT((o.quadric.shape_matrix() - gt.shape_matrix()).norm(), tol * 0.1);
      EXPECT_GT(iou_3d(box_from_quadric(o.quadric), box_from_quadric(gt)), refine ? 0.98 : 0.9999);
    }
  }
}

// Boxes that box planes explain by an ellipsoid far behind where the depth images put the object
// (views from a narrow range of directions leave the position along the rays to the boxes' small
// differences): with the depth check (LifecycleParams::max_depth_disagreement) the mapper keeps
// the depth-consistent ellipsoid near the ground truth; without it the box-plane ellipsoid
// replaces it (the check is what makes the difference).
TEST(ObjectMapper, DepthContradictedBoxPlaneQuadricDoesNotReplaceTheDepthEllipsoid) {
  const DualQuadric gt = gt_ellipsoid();
  const PinholeCamera camera = test_camera();
  // Cameras on an arc of ±0.08 rad, 1.4 m from the object (baseline ratio 0.15); the boxes are
  // those of the ground truth scaled by 1.6 about the middle camera (the same silhouette there,
  // 0.84 m deeper).
  std::vector<SE3> poses;
  for (int k = 0; k < 5; ++k) {
    const double a = -0.08 + 0.04 * k;
    poses.push_back(look_at(gt.centre() + Eigen::Vector3d(1.4 * std::cos(a), 1.4 * std::sin(a), 0.5), gt.centre()));
  }
  const Eigen::Vector3d eye = poses[2].translation();
  const DualQuadric wrong = DualQuadric::from_params(eye + 1.6 * (gt.centre() - eye), gt.rotation(),
                                                     1.6 * gt.semi_axes());
  auto run = [&](double max_depth_disagreement) {
    ObjectMapperParams params;
    params.refine = false;  // the initialisation alone
    params.box_fit.enabled = false;
    params.lifecycle.max_depth_disagreement = max_depth_disagreement;
    ObjectMapper mapper(params);
    for (size_t k = 0; k < poses.size(); ++k) {
      ObjectKeyFrame kf = keyframe(static_cast<KeyFrameId>(k + 1), poses[k], camera);
      const DepthImage depth = render_depth({gt}, camera, kf.T_wc);
      kf.depth = test::view_of(depth);
      const auto box = exact_box(wrong, camera, kf.T_wc);
      EXPECT_TRUE(box);
      if (!box) continue;
      kf.detections.push_back(detection(*box));
      std::string error;
      mapper.process_keyframe(kf, &error);
      EXPECT_TRUE(error.empty()) << error;
    }
    return mapper.objects();
  };
  const std::vector<MapObject> checked = run(1.0);
  ASSERT_EQ(checked.size(), 1u);
  EXPECT_FALSE(checked[0].from_boxes);
  EXPECT_LT((checked[0].quadric.centre() - gt.centre()).norm(), 0.15);
  const std::vector<MapObject> unchecked = run(0.0);
  ASSERT_EQ(unchecked.size(), 1u);
  EXPECT_TRUE(unchecked[0].from_boxes);
  EXPECT_GT((unchecked[0].quadric.centre() - gt.centre()).norm(), 0.5);
}

// A sofa-like object first seen only in part (the rest hidden), later whole: two objects, then
// one, with a MERGED event of the piece into the whole.
TEST(ObjectMapper, MergeJoinsThePiecesOfAnOccludedObject) {
  const DualQuadric whole = DualQuadric::from_params(Eigen::Vector3d(0, 0, 0.4), Eigen::Matrix3d::Identity(),
                                                     Eigen::Vector3d(0.8, 0.3, 0.3));
  const DualQuadric piece = DualQuadric::from_params(Eigen::Vector3d(-0.45, 0, 0.4),
                                                     Eigen::Matrix3d::Identity(),
                                                     Eigen::Vector3d(0.3, 0.25, 0.25));
  const PinholeCamera camera = test_camera();
  ObjectMapperParams params;
  params.refine = false;  // the merge alone, not the refinement over the merged boxes
  ObjectMapper mapper(params);
  std::vector<ObjectEvent> events;
  KeyFrameId id = 1;
  auto view = [&](double x, const DualQuadric& seen) {
    ObjectKeyFrame kf = keyframe(id++, look_at(Eigen::Vector3d(x, -2.5, 1.0), Eigen::Vector3d(0, 0, 0.4)), camera);
    const auto box = exact_box(seen, camera, kf.T_wc);
    ASSERT_TRUE(box);
    kf.detections.push_back(detection(*box, 3));
    std::string error;
    const KeyFrameAssociation r = mapper.process_keyframe(kf, &error);
    ASSERT_TRUE(error.empty()) << error;
    events.insert(events.end(), r.events.begin(), r.events.end());
  };
  for (const double x : {-0.6, -0.3, 0.0, 0.3}) view(x, piece);
  ASSERT_EQ(mapper.objects().size(), 1u);
  const ObjectId piece_id = mapper.objects()[0].id;
  for (const double x : {-0.45, -0.15, 0.15, 0.45, 0.6}) view(x, whole);

  ASSERT_EQ(count_events(events, ObjectEvent::Type::kCreated), 2);
  ASSERT_EQ(count_events(events, ObjectEvent::Type::kMerged), 1);
  const auto merged = std::find_if(events.begin(), events.end(),
                                   [](const ObjectEvent& e) { return e.type == ObjectEvent::Type::kMerged; });
  EXPECT_EQ(merged->id, piece_id);
  EXPECT_NE(merged->into_id, piece_id);
  const std::vector<MapObject> objects = mapper.objects(true);
  ASSERT_EQ(objects.size(), 1u);
  EXPECT_EQ(objects[0].id, merged->into_id);
  EXPECT_EQ(mapper.find(piece_id), nullptr);
  EXPECT_EQ(objects[0].observations.size(), 9u);  // 4 of the piece + 5 of the whole
  EXPECT_EQ(objects[0].class_id, 3);
  // The whole object's ellipsoid (matrices: a spheroid's box depends on the arbitrary rotation
  // about its symmetry axis).
  EXPECT_LT((objects[0].quadric.centre() - whole.centre()).norm(), 1e-6);
  EXPECT_LT((objects[0].quadric.shape_matrix() - whole.shape_matrix()).norm(), 1e-6);
}

// A false positive seen once becomes a candidate with its own ID (CREATED) and is REMOVED when
// it keeps not being detected where it should be seen; IDs are never reused, also across a
// save/load of the state.
TEST(ObjectMapper, LifecycleEventsAndIdsAcrossRestarts) {
  const DualQuadric gt = gt_ellipsoid();
  const PinholeCamera camera = test_camera(320, 240);
  ObjectMapperParams params;
  // The false positive lies on the wall (the depth shows a surface there), so its misses cost little:
  // it goes by the candidates' age limit.
  params.lifecycle.existence.candidate_max_age_keyframes = 5;
  ObjectMapper mapper(params);
  std::vector<ObjectEvent> events;
  std::vector<ObjectId> confirmed;
  ObjectId false_positive = 0;
  for (int k = 0; k < 8; ++k) {
    ObjectKeyFrame kf = keyframe(static_cast<KeyFrameId>(10 + k), orbit_pose(k, gt.centre(), 0.05), camera);
    const DepthImage depth = render_depth({gt}, camera, kf.T_wc, 2.5f);  // a wall behind
    kf.depth = test::view_of(depth);
    const auto box = exact_box(gt, camera, kf.T_wc);
    ASSERT_TRUE(box);
    kf.detections.push_back(detection(*box, 1));
    if (k == 1) kf.detections.push_back(detection(Box2d{20, 20, 70, 60}, 2, 0.5f));
    std::string error;
    const KeyFrameAssociation r = mapper.process_keyframe(kf, &error);
    ASSERT_TRUE(error.empty()) << error;
    if (k == 1) {
      ASSERT_EQ(r.verdicts[1], DetectionVerdict::kNewObject);
      false_positive = r.object_ids[1];
    }
    events.insert(events.end(), r.events.begin(), r.events.end());
    // Confirmed once, in the keyframe after which objects() first lists it.
    const bool listed = !mapper.objects().empty();
    const bool listed_before = !confirmed.empty();
    confirmed.insert(confirmed.end(), r.confirmed.begin(), r.confirmed.end());
    EXPECT_EQ(r.confirmed.size(), listed && !listed_before ? 1u : 0u) << "keyframe " << k;
  }
  ASSERT_NE(false_positive, 0u);
  EXPECT_EQ(count_events(events, ObjectEvent::Type::kCreated), 2);
  EXPECT_EQ(count_events(events, ObjectEvent::Type::kRemoved), 1);
  const auto removed = std::find_if(events.begin(), events.end(),
                                    [](const ObjectEvent& e) { return e.type == ObjectEvent::Type::kRemoved; });
  EXPECT_EQ(removed->id, false_positive);
  ASSERT_EQ(mapper.objects(true).size(), 1u);
  const MapObject kept = mapper.objects()[0];
  EXPECT_EQ(kept.state, ObjectState::kConfirmed);
  EXPECT_EQ(confirmed, std::vector<ObjectId>{kept.id}) << "the false positive is never confirmed";

  const std::string path = (std::filesystem::temp_directory_path() /
                            ("dqo_object_state_" + std::to_string(::getpid()) + ".txt")).string();
  std::string error;
  mapper.set_map_id("tracker:map:run 1");
  ASSERT_TRUE(mapper.save_state(path, &error)) << error;
  EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
  ObjectMapper restarted(params);
  ASSERT_TRUE(restarted.load_state(path, &error)) << error;
  EXPECT_EQ(restarted.map_id(), "tracker:map:run 1");
  EXPECT_EQ(restarted.next_id(), mapper.next_id());
  ASSERT_EQ(restarted.objects().size(), 1u);
  const MapObject loaded = restarted.objects()[0];
  EXPECT_EQ(loaded.id, kept.id);
  EXPECT_EQ(loaded.class_id, kept.class_id);
  EXPECT_EQ(loaded.class_name, kept.class_name);
  EXPECT_EQ(loaded.observation_count, kept.observation_count);
  EXPECT_LT((loaded.quadric.matrix() - kept.quadric.matrix()).norm(), 1e-12);
  EXPECT_EQ(loaded.has_box, kept.has_box);
  if (kept.has_box) {
    EXPECT_EQ(loaded.box.centre, kept.box.centre);
    EXPECT_EQ(loaded.box.half_extents, kept.box.half_extents);
  }

  // A new object after the restart takes an ID above every ID given before (the removed one too).
  ObjectKeyFrame kf = keyframe(100, look_at(Eigen::Vector3d(0, -5, 1), Eigen::Vector3d(0, -8, 1)), camera);
  kf.detections.push_back(detection(Box2d{100, 80, 160, 140}, 4));
  const DepthImage depth(camera.width, camera.height, 1, 2.0f);
  kf.depth = test::view_of(depth);
  const KeyFrameAssociation r = restarted.process_keyframe(kf, &error);
  ASSERT_EQ(r.verdicts[0], DetectionVerdict::kNewObject);
  EXPECT_GT(r.object_ids[0], std::max(false_positive, kept.id));
  EXPECT_EQ(r.object_ids[0], mapper.next_id());

  // A corrupt state file is refused and the loaded map stays.
  { std::ofstream(path) << "dqo_object_state 1\nnext_id 5\nobject 9 confirmed 1\n"; }
  EXPECT_FALSE(restarted.load_state(path, &error));
  EXPECT_NE(error.find(path + ":3:"), std::string::npos) << error;
  EXPECT_EQ(restarted.objects(true).size(), 2u);

  // Another map: every object dropped with a REMOVED event, the ID counter kept.
  const ObjectId next_before = restarted.next_id();
  const std::vector<ObjectEvent> dropped = restarted.drop_objects();
  EXPECT_EQ(dropped.size(), 2u);
  for (const ObjectEvent& e : dropped) EXPECT_EQ(e.type, ObjectEvent::Type::kRemoved);
  EXPECT_TRUE(restarted.objects(true).empty());
  EXPECT_EQ(restarted.next_id(), next_before);
  // Keyframe IDs of a new tracker run start over: accepted after the drop.
  const KeyFrameAssociation again = restarted.process_keyframe(kf, &error);
  EXPECT_TRUE(error.empty()) << error;
  ASSERT_EQ(again.object_ids.size(), 1u);
  EXPECT_EQ(again.object_ids[0], next_before);
  std::filesystem::remove(path);
}

TEST(ObjectMapper, BadInputGivesVerdictsAndErrors) {
  const DualQuadric gt = gt_ellipsoid();
  const PinholeCamera camera = test_camera(320, 240);
  ObjectMapper mapper;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  ObjectKeyFrame kf = keyframe(1, orbit_pose(0, gt.centre()), camera);
  const DepthImage depth = render_depth({gt}, camera, kf.T_wc, 2.5f);
  kf.depth = test::view_of(depth);
  kf.detections.push_back(detection(Box2d{nan, 10, 50, 50}));
  kf.detections.push_back(detection(Box2d{80, 80, 40, 120}));      // negative width
  kf.detections.push_back(detection(Box2d{400, 10, 450, 60}));     // outside the image
  kf.detections.push_back(detection(*exact_box(gt, camera, kf.T_wc)));
  for (int k = 0; k < 1000; ++k) {  // a thousand more, all over the image
    const double x = 6 + (k % 40) * 7.0, y = 6 + (k / 40) * 8.0;
    kf.detections.push_back(detection(Box2d{x, y, x + 20, y + 20}, k % 3, 0.3f));
  }
  std::string error;
  const KeyFrameAssociation r = mapper.process_keyframe(kf, &error);
  EXPECT_TRUE(error.empty()) << error;
  ASSERT_EQ(r.verdicts.size(), kf.detections.size());
  EXPECT_EQ(r.verdicts[0], DetectionVerdict::kInvalid);
  EXPECT_EQ(r.verdicts[1], DetectionVerdict::kInvalid);
  EXPECT_EQ(r.verdicts[2], DetectionVerdict::kInvalid);
  EXPECT_EQ(r.verdicts[3], DetectionVerdict::kNewObject);
  EXPECT_LE(static_cast<int>(r.filtered.size()), mapper.params().filter.max_detections);
  EXPECT_EQ(r.filtered.size(), r.filtered_object_ids.size());
  for (size_t k = 0; k < r.filtered.size(); ++k) {
    EXPECT_EQ(r.object_ids[static_cast<size_t>(r.filtered_source[k])], r.filtered_object_ids[k]);
  }
  std::set<ObjectId> ids;
  for (size_t k = 0; k < r.verdicts.size(); ++k) {
    const bool made = r.verdicts[k] == DetectionVerdict::kNewObject;
    EXPECT_EQ(made, r.object_ids[k] != 0);
    if (made) {
      EXPECT_TRUE(ids.insert(r.object_ids[k]).second) << "one ID for two detections";
    }
  }
  const size_t objects_before = mapper.objects(true).size();
  const ObjectId next_before = mapper.next_id();

  // The same keyframe ID again: an error, nothing changes.
  const KeyFrameAssociation again = mapper.process_keyframe(kf, &error);
  EXPECT_NE(error.find("repeated keyframe"), std::string::npos) << error;
  EXPECT_TRUE(again.verdicts.empty());
  EXPECT_EQ(mapper.objects(true).size(), objects_before);
  EXPECT_EQ(mapper.next_id(), next_before);

  // A broken camera, a non-finite pose, a depth image of the wrong size.
  ObjectKeyFrame broken = keyframe(2, kf.T_wc, camera);
  broken.camera.fx = 0.0;
  mapper.process_keyframe(broken, &error);
  EXPECT_NE(error.find("camera"), std::string::npos) << error;
  broken = keyframe(3, SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(nan, 0, 0)), camera);
  mapper.process_keyframe(broken, &error);
  EXPECT_NE(error.find("pose"), std::string::npos) << error;
  broken = keyframe(4, kf.T_wc, camera);
  const DepthImage small(10, 10, 1, 1.0f);
  broken.depth = test::view_of(small);
  mapper.process_keyframe(broken, &error);
  EXPECT_NE(error.find("depth"), std::string::npos) << error;
  EXPECT_EQ(mapper.next_id(), next_before);

  // Updates for unknown keyframes are ignored.
  EXPECT_EQ(mapper.update_keyframe_poses({{1, kf.T_wc}, {77, kf.T_wc}}), 1);
}

}  // namespace
}  // namespace dqo::objects
