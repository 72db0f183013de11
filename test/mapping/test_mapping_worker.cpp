// The mapping stage on its own thread: the same map as the mapper fed directly, inputs from several
// threads, queries during mapping, errors reported, flush at the end, a prompt stop.

#include <gtest/gtest.h>

#include <chrono>
#include <map>
#include <string>
#include <thread>

#include "dqo_map/mapping/mapping_worker.h"
#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"
#include "dqo_map/system/offline_mapping.h"

namespace dqo::mapping {
namespace {

struct Tiny {
  sim::Scene scene;
  DatasetInfo info;
  std::vector<Frame> frames;
};

const Tiny& tiny() {
  static const Tiny t = [] {
    Tiny out;
    std::string error;
    auto s = sim::load_scene(std::string(DQO_SOURCE_DIR) + "/config/scenes/tiny.yaml", {}, &error);
    EXPECT_TRUE(s.has_value()) << error;
    out.scene = s ? *s : sim::Scene();
    out.scene.camera = scale_camera(out.scene.camera, 0.5);
    const sim::Renderer renderer(out.scene, 2);
    out.info = renderer.info();
    for (int i = 0; i < 6; ++i) out.frames.push_back(renderer.render(3 * i, false));
    return out;
  }();
  return t;
}

MappingKeyframe keyframe(KeyframeId id) {
  const Frame& f = tiny().frames[id - 1];
  MappingKeyframe k;
  k.id = id;
  k.stamp = 0.1 * static_cast<double>(id);
  k.camera = tiny().scene.camera;
  k.T_wc = f.T_wc;
  k.rgb = f.rgb;
  k.depth = f.depth;
  return k;
}

KeyframeObjects objects(KeyframeId id) {
  KeyframeObjects o = system::ground_truth_objects(tiny().frames[id - 1], tiny().info).keyframe_objects;
  o.keyframe_id = id;
  return o;
}

GaussianMapperParams params() {
  GaussianMapperParams p;
  p.trainer.iterations = 4;
  p.threads = 1;
  return p;
}

TEST(MappingWorker, SameMapAsTheMapperFedDirectly) {
  GaussianMapper direct(params());
  MappingWorker worker(params());
  const auto records = system::ground_truth_objects(tiny().frames[0], tiny().info).objects;
  direct.set_objects(records);
  worker.set_objects(records);
  for (KeyframeId id = 1; id <= 4; ++id) {
    ASSERT_TRUE(direct.add_keyframe(keyframe(id)));
    ASSERT_TRUE(direct.add_keyframe_objects(objects(id)));
    while (direct.process_next()) {
    }
    worker.add_keyframe(keyframe(id));
    worker.add_keyframe_objects(objects(id));
  }
  worker.wait_until_idle();
  EXPECT_EQ(worker.keyframes_mapped(), 4u);
  EXPECT_TRUE(worker.take_errors().empty());
  EXPECT_EQ(worker.take_reports().size(), 4u);
  EXPECT_TRUE(worker.take_reports().empty()) << "taken once";
  worker.with_mapper([&](GaussianMapper& m) {
    EXPECT_EQ(m.map().positions(), direct.map().positions());
    EXPECT_EQ(m.map().object_ids_per_gaussian(), direct.map().object_ids_per_gaussian());
    return 0;
  });
}

TEST(MappingWorker, InputsFromSeveralThreadsQueriesMeanwhile) {
  MappingWorker worker(params());
  worker.set_objects(system::ground_truth_objects(tiny().frames[0], tiny().info).objects);
  // Keyframes and their objects from two threads, in either order per keyframe; a third thread
  // queries the map while it is being built.
  std::thread keyframes([&] {
    for (KeyframeId id = 1; id <= 6; ++id) worker.add_keyframe(keyframe(id));
  });
  std::thread detections([&] {
    for (KeyframeId id = 6; id >= 1; --id) worker.add_keyframe_objects(objects(id));
  });
  size_t queries = 0;
  std::thread queries_thread([&] {
    for (int i = 0; i < 20; ++i) {
      queries += worker.with_mapper([](GaussianMapper& m) { return m.list_objects().size() + 1; });
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  });
  keyframes.join();
  detections.join();
  queries_thread.join();
  worker.wait_until_idle();
  EXPECT_GE(queries, 20u);
  EXPECT_TRUE(worker.take_errors().empty());
  EXPECT_EQ(worker.keyframes_mapped(), 6u);
  for (const MappingReport& r : worker.take_reports()) EXPECT_TRUE(r.labelled) << r.keyframe_id;
}

TEST(MappingWorker, ErrorsComeBackAndFlushMapsTheWaiting) {
  MappingWorker worker(params());
  MappingKeyframe bad = keyframe(1);
  bad.depth = DepthImage(3, 3, 1, 1.f);
  worker.add_keyframe(bad);
  worker.add_keyframe(keyframe(2));  // its objects never come
  worker.wait_until_idle();
  const auto errors = worker.take_errors();
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("depth image"), std::string::npos) << errors[0];
  EXPECT_EQ(worker.keyframes_mapped(), 0u);
  worker.wait_until_idle(true);
  EXPECT_EQ(worker.keyframes_mapped(), 1u);
  const auto reports = worker.take_reports();
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_FALSE(reports[0].labelled);
}

TEST(MappingWorker, StopsPromptlyWithInputsPending) {
  const auto t0 = std::chrono::steady_clock::now();
  {
    MappingWorker worker(params());
    for (KeyframeId id = 1; id <= 6; ++id) {
      worker.add_keyframe(keyframe(id));
      worker.add_keyframe_objects(objects(id));
    }
  }  // the destructor stops after the step in progress
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_LT(seconds, 5.0);
}

}  // namespace
}  // namespace dqo::mapping
