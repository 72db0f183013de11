#include "dqo_map/sim/scene_frame_source.h"

#include <string>
#include <utility>

namespace dqo::sim {

SceneFrameSource::SceneFrameSource(Scene scene, double scale, bool noise, int threads)
    : scene_(std::move(scene)), noise_(noise) {
  if (scale != 1.0) scene_.camera = scale_camera(scene_.camera, scale);
  renderer_ = std::make_unique<Renderer>(scene_, threads);
  info_ = renderer_->info();
}

std::optional<Frame> SceneFrameSource::read_frame(int i, std::string* error) const {
  if (i < 0 || i >= num_frames()) {
    if (error) *error = "frame " + std::to_string(i) + " is outside the scene's " +
                        std::to_string(num_frames()) + " frames";
    return std::nullopt;
  }
  return renderer_->render(i, noise_);
}

}  // namespace dqo::sim
