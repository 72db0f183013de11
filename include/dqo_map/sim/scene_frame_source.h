#pragma once
// A synthetic scene as a FrameSource: frames rendered in memory on demand (no dataset folder), at
// the scene's resolution or scaled, with or without the scene's noise. What the offline runner reads
// when its input is a scene YAML, and all it has on the GPU machine.

#include <memory>

#include "dqo_map/common/frame_source.h"
#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene.h"

namespace dqo::sim {

class SceneFrameSource : public FrameSource {
 public:
  // scale: image size relative to the scene's camera (intrinsics follow, scale_camera);
  // threads <= 0: all cores.
  SceneFrameSource(Scene scene, double scale, bool noise, int threads);
  // The renderer refers to the scene held here: neither copied nor moved.
  SceneFrameSource(const SceneFrameSource&) = delete;
  SceneFrameSource& operator=(const SceneFrameSource&) = delete;

  const DatasetInfo& info() const override { return info_; }
  int num_frames() const override { return renderer_->num_frames(); }
  std::optional<Frame> read_frame(int i, std::string* error = nullptr) const override;
  const Scene& scene() const { return scene_; }

 private:
  Scene scene_;
  bool noise_;
  std::unique_ptr<Renderer> renderer_;  // refers to scene_
  DatasetInfo info_;                    // built once: the meshes are not cheap
};

}  // namespace dqo::sim
