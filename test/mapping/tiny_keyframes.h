#pragma once
// Keyframes of the `tiny` scene at half resolution (80x60: fast, still five objects in view),
// rendered once and cached, with the ground-truth object stage's answer for them: the inputs of the
// mapping-stage tests.

#include <map>
#include <mutex>
#include <string>

#include <gtest/gtest.h>

#include "dqo_map/mapping/mapping_types.h"
#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene_loader.h"
#include "dqo_map/system/offline_mapping.h"

namespace dqo::mapping::testing {

inline const sim::Scene& tiny() {
  static const sim::Scene scene = [] {
    std::string error;
    auto s = sim::load_scene(std::string(DQO_SOURCE_DIR) + "/config/scenes/tiny.yaml", {}, &error);
    EXPECT_TRUE(s.has_value()) << error;
    sim::Scene out = s ? *s : sim::Scene();
    out.camera = scale_camera(out.camera, 0.5);
    return out;
  }();
  return scene;
}

// Frame `index` of the trajectory, noise-free. Safe from several threads (the worker tests).
inline const Frame& frame(int index) {
  static const sim::Renderer renderer(tiny(), 2);
  static std::map<int, Frame> frames;  // node-based: references stay valid as it grows
  static std::mutex mutex;
  std::lock_guard<std::mutex> lock(mutex);
  auto it = frames.find(index);
  if (it == frames.end()) it = frames.emplace(index, renderer.render(index, false)).first;
  return it->second;
}

inline const DatasetInfo& info() {
  static const DatasetInfo i = sim::Renderer(tiny(), 1).info();
  return i;
}

inline MappingKeyframe keyframe(KeyframeId id, int index, double stamp) {
  const Frame& f = frame(index);
  MappingKeyframe k;
  k.id = id;
  k.stamp = stamp;
  k.camera = tiny().camera;
  k.T_wc = f.T_wc;
  k.rgb = f.rgb;
  k.depth = f.depth;
  return k;
}

// The ground-truth object stage's answer for a frame (one detection per instance).
inline system::ObjectStageOutput truth(int index) {
  return system::ground_truth_objects(frame(index), info());
}

inline KeyframeObjects objects_of(KeyframeId id, int index) {
  KeyframeObjects o = truth(index).keyframe_objects;
  o.keyframe_id = id;
  return o;
}

}  // namespace dqo::mapping::testing
