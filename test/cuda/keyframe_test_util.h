#pragma once
// Keyframes for the GPU mapping tests: a map rendered by the CPU reference as a camera would see
// it (8-bit colour, depth where the render is opaque, the dominant object IDs as labels).

#include <algorithm>
#include <cmath>

#include "dqo_map/gaussians/trainer.h"

namespace dqo::cuda::testing {

inline gs::TrainingKeyframe rendered_keyframe(const gs::GaussianMap& truth, const PinholeCamera& camera, const SE3& T_wc,
                                              uint32_t id) {
  gs::TrainingKeyframe kf;
  kf.id = id;
  kf.camera = camera;
  kf.T_wc = T_wc;
  gs::RenderSettings s;
  s.normalise_depth = true;
  gs::RenderOutput out;
  gs::make_cpu_rasteriser(0)->forward(truth, camera, T_wc.inverse(), s, &out, nullptr);
  const int w = camera.width, h = camera.height;
  const size_t pixels = static_cast<size_t>(w) * h;
  kf.rgb = ImageRgb8(w, h, 3, 0);
  kf.depth = DepthImage(w, h, 1, 0.f);
  kf.labels = LabelImage(w, h, 1, 0u);
  for (size_t p = 0; p < pixels; ++p) {
    for (int c = 0; c < 3; ++c)
      kf.rgb.data[3 * p + c] = static_cast<uint8_t>(std::lround(255.f * std::clamp(out.rgb[3 * p + c], 0.f, 1.f)));
    kf.depth.data[p] = out.alpha[p] > 0.5f ? out.depth[p] : 0.f;
    kf.labels.data[p] = out.dominant_id[p];
  }
  return kf;
}

}  // namespace dqo::cuda::testing
