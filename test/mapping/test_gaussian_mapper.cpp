// The mapping stage (GaussianMapper) on keyframes of the `tiny` scene at half resolution with
// ground-truth poses: pairing of keyframes with their objects in either order and the timeout,
// the bounded queue, object events (no Gaussian lost), pose updates, pixel labels from instance
// images and from quadrics, the Gaussian budget, queries, and snapshot / restore.

#include <gtest/gtest.h>

#ifdef DQO_TEST_CUDA
#include "dqo_map/cuda/device_info.h"
#endif

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <string>

#include "dqo_map/mapping/gaussian_mapper.h"
#include "tiny_keyframes.h"

namespace dqo::mapping {
namespace {

using testing::frame;
using testing::keyframe;
using testing::objects_of;
using testing::truth;

GaussianMapperParams fast_params() {
  GaussianMapperParams p;
  p.trainer.iterations = 4;
  p.threads = 2;
  // The CPU backend (auto would take a GPU where there is one): these tests compare maps value by
  // value, and the CUDA backward's float atomics sum in no fixed order.
  p.backend = Backend::kCpu;
  return p;
}

std::map<uint32_t, size_t> counts(const gs::GaussianMap& map) {
  std::map<uint32_t, size_t> c;
  for (const uint32_t id : map.object_ids_per_gaussian()) ++c[id];
  return c;
}

TEST(GaussianMapper, PairsKeyframesWithTheirObjectsInEitherOrder) {
  GaussianMapper mapper(fast_params());
  mapper.set_objects(truth(0).objects);
  // Keyframe first: it waits for its objects.
  ASSERT_TRUE(mapper.add_keyframe(keyframe(1, 0, 0.0)));
  EXPECT_EQ(mapper.waiting(), 1u);
  EXPECT_FALSE(mapper.process_next().has_value());
  ASSERT_TRUE(mapper.add_keyframe_objects(objects_of(1, 0)));
  EXPECT_EQ(mapper.waiting(), 0u);
  auto r1 = mapper.process_next();
  ASSERT_TRUE(r1.has_value());
  EXPECT_EQ(r1->keyframe_id, 1u);
  EXPECT_TRUE(r1->labelled);
  EXPECT_TRUE(r1->from_instance);
  // Objects first: the keyframe is ready as soon as it comes.
  ASSERT_TRUE(mapper.add_keyframe_objects(objects_of(2, 3)));
  EXPECT_EQ(mapper.ready(), 0u);
  ASSERT_TRUE(mapper.add_keyframe(keyframe(2, 3, 0.1)));
  EXPECT_EQ(mapper.ready(), 1u);
  auto r2 = mapper.process_next();
  ASSERT_TRUE(r2.has_value());
  EXPECT_EQ(r2->keyframe_id, 2u);
  EXPECT_TRUE(r2->labelled);

  // Every object the instance image shows has Gaussians with its ID, and the report's counts are
  // the map's.
  const auto c = counts(mapper.map());
  for (const Detection2d& d : objects_of(1, 0).detections) {
    EXPECT_GT(c.count(d.gt_id) ? c.at(d.gt_id) : 0u, 0u) << "object " << d.gt_id;
  }
  std::map<uint32_t, size_t> reported(r2->gaussians_per_object.begin(), r2->gaussians_per_object.end());
  EXPECT_EQ(reported, c);
  EXPECT_EQ(r2->num_gaussians, mapper.map().size());
  EXPECT_EQ(mapper.keyframes_mapped(), 2u);
}

TEST(GaussianMapper, KeyframeWhoseObjectsNeverComeIsMappedAsBackground) {
  GaussianMapperParams p = fast_params();
  p.objects_timeout = 1.0;
  GaussianMapper mapper(p);
  ASSERT_TRUE(mapper.add_keyframe(keyframe(1, 0, 10.0)));
  ASSERT_TRUE(mapper.add_keyframe(keyframe(2, 1, 10.5)));  // within the timeout: both wait
  EXPECT_EQ(mapper.ready(), 0u);
  ASSERT_TRUE(mapper.add_keyframe(keyframe(3, 2, 11.2)));  // 1.2 s after keyframe 1
  EXPECT_EQ(mapper.ready(), 1u);
  auto r = mapper.process_next();
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->keyframe_id, 1u);
  EXPECT_FALSE(r->labelled);
  EXPECT_GT(mapper.map().size(), 100u);
  EXPECT_EQ(counts(mapper.map()).size(), 1u) << "background only";
  // Its objects arriving late are refused, and say so.
  std::string error;
  EXPECT_FALSE(mapper.add_keyframe_objects(objects_of(1, 0), &error));
  EXPECT_NE(error.find("after the keyframe was mapped"), std::string::npos) << error;
  // The end of the input releases the rest.
  mapper.flush();
  EXPECT_EQ(mapper.ready(), 2u);
  EXPECT_EQ(mapper.waiting(), 0u);
  while (mapper.process_next()) {
  }
  EXPECT_EQ(mapper.keyframes_mapped(), 3u);
}

TEST(GaussianMapper, BoundedQueueDropsTheOldest) {
  GaussianMapperParams p = fast_params();
  p.max_queue = 2;
  GaussianMapper mapper(p);
  for (KeyframeId id = 1; id <= 4; ++id) {
    ASSERT_TRUE(mapper.add_keyframe_objects(objects_of(id, static_cast<int>(id))));
    ASSERT_TRUE(mapper.add_keyframe(keyframe(id, static_cast<int>(id), 0.1 * id)));
  }
  EXPECT_EQ(mapper.dropped(), 2u);
  auto a = mapper.process_next();
  auto b = mapper.process_next();
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->keyframe_id, 3u);
  EXPECT_EQ(b->keyframe_id, 4u);
  EXPECT_EQ(b->dropped_total, 2u);
  EXPECT_FALSE(mapper.process_next().has_value());
}

TEST(GaussianMapper, BadInputIsRefusedAndChangesNothing) {
  GaussianMapper mapper(fast_params());
  std::string error;
  MappingKeyframe k = keyframe(1, 0, 0.0);
  k.depth = DepthImage(10, 10, 1, 1.f);
  EXPECT_FALSE(mapper.add_keyframe(k, &error));
  EXPECT_NE(error.find("depth image"), std::string::npos) << error;
  k = keyframe(1, 0, 0.0);
  k.rgb = ImageRgb8();
  EXPECT_FALSE(mapper.add_keyframe(k, &error));
  EXPECT_NE(error.find("colour image"), std::string::npos) << error;
  k = keyframe(1, 0, 0.0);
  k.camera.fx = 0.0;
  EXPECT_FALSE(mapper.add_keyframe(k, &error));
  k = keyframe(1, 0, std::nan(""));
  EXPECT_FALSE(mapper.add_keyframe(k, &error));
  EXPECT_NE(error.find("not finite"), std::string::npos) << error;
  k = keyframe(1, 0, 0.0);
  k.T_wc = SE3(Eigen::Quaterniond::Identity(), Eigen::Vector3d(NAN, 0, 0));
  EXPECT_FALSE(mapper.add_keyframe(k, &error));
  EXPECT_EQ(mapper.waiting(), 0u);
  ASSERT_TRUE(mapper.add_keyframe(keyframe(1, 0, 0.0), &error)) << error;
  EXPECT_FALSE(mapper.add_keyframe(keyframe(1, 1, 0.1), &error));
  EXPECT_NE(error.find("repeated"), std::string::npos) << error;
  KeyframeObjects o = objects_of(1, 0);
  o.object_ids.push_back(99);
  EXPECT_FALSE(mapper.add_keyframe_objects(o, &error));
  EXPECT_NE(error.find("object IDs"), std::string::npos) << error;
  o = objects_of(1, 0);
  o.instance = InstanceImage(3, 3, 1, 0);
  EXPECT_FALSE(mapper.add_keyframe_objects(o, &error));
  EXPECT_NE(error.find("instance image"), std::string::npos) << error;
  o = objects_of(1, 0);
  o.object_ids[0] = kMaxObjectId + 1;
  EXPECT_FALSE(mapper.add_keyframe_objects(o, &error));
  EXPECT_NE(error.find("beyond"), std::string::npos) << error;
  EXPECT_EQ(mapper.apply_event({MappingEvent::Type::kMerged, kMaxObjectId + 7, 1}), 0u);
  EXPECT_EQ(mapper.waiting(), 1u);  // still waiting for valid objects
  EXPECT_TRUE(mapper.add_keyframe_objects(objects_of(1, 0), &error)) << error;
  // backend cuda: a GPU mapper where the CUDA ring is built and a GPU is usable, else refused.
  auto make_cuda = [] {
    GaussianMapperParams p = fast_params();
    p.backend = Backend::kCuda;
    GaussianMapper m(p);
  };
#ifdef DQO_TEST_CUDA
  if (cuda::gpu_available()) {
    EXPECT_NO_THROW(make_cuda());
  } else {
    EXPECT_THROW(make_cuda(), std::invalid_argument);
  }
#else
  EXPECT_THROW(make_cuda(), std::invalid_argument);
#endif
}

TEST(GaussianMapper, MergedAndRemovedObjectsKeepEveryGaussian) {
  GaussianMapper mapper(fast_params());
  mapper.set_objects(truth(0).objects);
  ASSERT_TRUE(mapper.add_keyframe_objects(objects_of(1, 0)));
  ASSERT_TRUE(mapper.add_keyframe(keyframe(1, 0, 0.0)));
  ASSERT_TRUE(mapper.process_next());
  const auto before = counts(mapper.map());
  const size_t total = mapper.map().size();
  std::vector<uint32_t> ids;
  for (const auto& [id, n] : before) {
    if (id != 0) ids.push_back(id);
  }
  ASSERT_GE(ids.size(), 3u);
  const uint32_t a = ids[0], b = ids[1], c = ids[2];

  MappingEvent merge{MappingEvent::Type::kMerged, b, a};
  EXPECT_EQ(mapper.apply_event(merge), before.at(b));
  auto after = counts(mapper.map());
  EXPECT_EQ(after[a], before.at(a) + before.at(b));
  EXPECT_EQ(after.count(b), 0u);
  EXPECT_EQ(mapper.map().size(), total);
  EXPECT_EQ(mapper.find_object(b), nullptr);

  MappingEvent remove{MappingEvent::Type::kRemoved, c, 0};
  EXPECT_EQ(mapper.apply_event(remove), before.at(c));
  after = counts(mapper.map());
  EXPECT_EQ(after[0], before.at(0) + before.at(c));
  EXPECT_EQ(after.count(c), 0u);
  EXPECT_EQ(mapper.map().size(), total);

  // A later keyframe whose objects still name b (sent before the merge reached the object stage's
  // subscribers) labels its pixels a: no Gaussian of b comes back.
  ASSERT_TRUE(mapper.add_keyframe_objects(objects_of(2, 1)));
  ASSERT_TRUE(mapper.add_keyframe(keyframe(2, 1, 0.1)));
  auto r = mapper.process_next();
  ASSERT_TRUE(r.has_value());
  after = counts(mapper.map());
  EXPECT_EQ(after.count(b), 0u);
  EXPECT_EQ(after.count(c), 0u);
  EXPECT_GT(after[a], 0u);
}

TEST(GaussianMapper, PoseUpdatesMoveStoredAndWaitingKeyframes) {
  GaussianMapper mapper(fast_params());
  mapper.set_objects(truth(0).objects);
  ASSERT_TRUE(mapper.add_keyframe_objects(objects_of(1, 0)));
  ASSERT_TRUE(mapper.add_keyframe(keyframe(1, 0, 0.0)));
  ASSERT_TRUE(mapper.process_next());
  ASSERT_TRUE(mapper.add_keyframe(keyframe(2, 1, 0.1)));  // waits for its objects
  const SE3 shift(Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitZ())),
                  Eigen::Vector3d(0.03, -0.02, 0.01));
  const SE3 moved1 = shift * frame(0).T_wc, moved2 = shift * frame(1).T_wc;
  EXPECT_EQ(mapper.set_keyframe_poses({{1, moved1}, {2, moved2}, {77, moved2}}), 2);
  ASSERT_EQ(mapper.keyframe_poses().size(), 1u);
  EXPECT_LT((mapper.keyframe_poses()[0].T_wc.translation() - moved1.translation()).norm(), 1e-12);
  ASSERT_TRUE(mapper.add_keyframe_objects(objects_of(2, 1)));
  ASSERT_TRUE(mapper.process_next());
  ASSERT_EQ(mapper.keyframe_poses().size(), 2u);
  EXPECT_LT((mapper.keyframe_poses()[1].T_wc.translation() - moved2.translation()).norm(), 1e-12);
  // The views that meshes are fused from use the corrected poses.
  const uint32_t object = mapper.list_objects().front().object.id;
  for (const ObjectView& v : mapper.object_views(object)) {
    const SE3& expected = v.keyframe_id == 1 ? moved1 : moved2;
    EXPECT_LT((v.T_wc.translation() - expected.translation()).norm(), 1e-12);
  }
}

TEST(GaussianMapper, QuadricLabelsWithoutAnInstanceImage) {
  GaussianMapper mapper(fast_params());
  mapper.set_objects(truth(0).objects);
  KeyframeObjects o = objects_of(1, 0);
  o.instance = InstanceImage();
  ASSERT_TRUE(mapper.add_keyframe_objects(o));
  ASSERT_TRUE(mapper.add_keyframe(keyframe(1, 0, 0.0)));
  auto r = mapper.process_next();
  ASSERT_TRUE(r.has_value());
  EXPECT_TRUE(r->labelled);
  EXPECT_FALSE(r->from_instance);
  // Each object's Gaussians lie inside its ground-truth box, enlarged by the label rule's scale
  // (ellipsoid_scale 1.2 of the inscribed ellipsoid) and a little for the Gaussians' spread.
  const auto& map = mapper.map();
  size_t labelled = 0, inside = 0;
  for (size_t i = 0; i < map.size(); ++i) {
    const uint32_t id = map.object_ids_per_gaussian()[i];
    if (id == 0) continue;
    const ObjectRecord* rec = mapper.find_object(id);
    ASSERT_NE(rec, nullptr);
    const Eigen::Vector3d p(map.positions()[3 * i], map.positions()[3 * i + 1], map.positions()[3 * i + 2]);
    const Eigen::Vector3d local = rec->box.rotation.transpose() * (p - rec->box.centre);
    ++labelled;
    inside += (local.array().abs() <= 1.3 * rec->box.half_extents.array() + 0.01).all() ? 1 : 0;
  }
  EXPECT_GT(labelled, 20u);
  EXPECT_GE(inside, labelled * 98 / 100);
}

TEST(GaussianMapper, BudgetHolds) {
  GaussianMapperParams p = fast_params();
  p.max_gaussians = 1500;
  GaussianMapper mapper(p);
  size_t pruned = 0;
  for (KeyframeId id = 1; id <= 4; ++id) {
    const int f = static_cast<int>(id) * 4;
    ASSERT_TRUE(mapper.add_keyframe_objects(objects_of(id, f)));
    ASSERT_TRUE(mapper.add_keyframe(keyframe(id, f, 0.1 * id)));
    auto r = mapper.process_next();
    ASSERT_TRUE(r.has_value());
    EXPECT_LE(r->num_gaussians, 1500u);
    pruned += r->trainer.pruned_budget;
  }
  EXPECT_GT(pruned, 0u);
  EXPECT_EQ(mapper.map().size(), 1500u);
}

TEST(GaussianMapper, ObjectViewsShowTheObjectAlone) {
  GaussianMapper mapper(fast_params());
  mapper.set_objects(truth(0).objects);
  for (KeyframeId id = 1; id <= 2; ++id) {
    ASSERT_TRUE(mapper.add_keyframe_objects(objects_of(id, static_cast<int>(id) * 5)));
    ASSERT_TRUE(mapper.add_keyframe(keyframe(id, static_cast<int>(id) * 5, 0.1 * id)));
    ASSERT_TRUE(mapper.process_next());
  }
  const auto summaries = mapper.list_objects();
  ASSERT_FALSE(summaries.empty());
  for (const ObjectSummary& s : summaries) {
    EXPECT_TRUE(s.known);
    EXPECT_EQ(s.num_gaussians, mapper.object_gaussians(s.object.id).size());
    const auto views = mapper.object_views(s.object.id);
    ASSERT_FALSE(views.empty()) << s.object.id;
    // Every surface pixel back-projects into the object's box (grown for the Gaussians' extent).
    size_t surface = 0, inside = 0;
    for (const ObjectView& v : views) {
      for (int y = 0; y < v.camera.height; ++y) {
        for (int x = 0; x < v.camera.width; ++x) {
          const float d = v.depth[static_cast<size_t>(y) * v.camera.width + x];
          if (d <= 0.f) continue;
          const Eigen::Vector3d p = v.T_wc * v.camera.back_project(x, y, d);
          const Eigen::Vector3d local =
              s.object.box.rotation.transpose() * (p - s.object.box.centre);
          ++surface;
          inside += (local.array().abs() <= s.object.box.half_extents.array() + 0.03).all();
        }
      }
    }
    EXPECT_GT(surface, 0u);
    EXPECT_GE(inside, surface * 95 / 100) << "object " << s.object.id;
  }
}

TEST(GaussianMapper, SnapshotRestoresTheMap) {
  GaussianMapper mapper(fast_params());
  mapper.set_objects(truth(0).objects);
  ASSERT_TRUE(mapper.add_keyframe_objects(objects_of(1, 0)));
  ASSERT_TRUE(mapper.add_keyframe(keyframe(1, 0, 0.0)));
  ASSERT_TRUE(mapper.process_next());
  const MapFileContents saved = mapper.snapshot(42);
  EXPECT_EQ(saved.next_object_id, 42u);
  EXPECT_EQ(saved.params_hash, mapper.params_hash());

  GaussianMapper same(fast_params());
  std::string warning;
  same.restore(saved, &warning);
  EXPECT_TRUE(warning.empty()) << warning;
  EXPECT_EQ(same.map().positions(), mapper.map().positions());
  EXPECT_EQ(same.map().object_ids_per_gaussian(), mapper.map().object_ids_per_gaussian());
  EXPECT_EQ(same.keyframes_mapped(), 1u);
  EXPECT_EQ(same.list_objects().size(), mapper.list_objects().size());
  // A restored keyframe ID counts as seen; mapping goes on from the restored map.
  EXPECT_FALSE(same.add_keyframe(keyframe(1, 0, 0.0)));
  ASSERT_TRUE(same.add_keyframe_objects(objects_of(2, 1)));
  ASSERT_TRUE(same.add_keyframe(keyframe(2, 1, 0.1)));
  ASSERT_TRUE(same.process_next());

  // The thread count shapes nothing (the same map on any): no warning for it.
  GaussianMapperParams more_threads = fast_params();
  more_threads.threads += 3;
  EXPECT_EQ(GaussianMapper(more_threads).params_hash(), mapper.params_hash());

  GaussianMapperParams other = fast_params();
  other.trainer.iterations = 5;
  GaussianMapper different(other);
  EXPECT_NE(different.params_hash(), mapper.params_hash());
  different.restore(saved, &warning);
  EXPECT_NE(warning.find("other mapping parameters"), std::string::npos);
  EXPECT_EQ(different.map().size(), mapper.map().size());
}

}  // namespace
}  // namespace dqo::mapping
