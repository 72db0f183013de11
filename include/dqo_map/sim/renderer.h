#pragma once
// Multi-threaded ray caster of a Scene to memory: RGB, depth, instance IDs, per-object visible
// boxes and fractions, simulated detections.
//
// Conventions of the Frame it fills:
// - depth is the z of the hit in the camera's optical frame, in metres (0 = no return);
// - instance holds object IDs, 0 where the pixel sees the background (room, furniture) or nothing;
// - a FrameObject's box spans its visible pixels' centres ± 0.5 px (pixel (u, v) has its centre at
//   integer coordinates, see pinhole_camera.h), clipped to [0, width] x [0, height];
// - visible_fraction = visible pixels / pixels whose ray hits the object at all (through any
//   occluder, background included): 1 for an unoccluded object, also one cut by the image border.
//
// Work is split into 16x16 tiles handed out through an atomic counter; the objects whose projected
// bounds miss a tile are never tested in it. Noise is keyed by pixel, so the images are identical
// for any thread count.

#include <cstdint>

#include "dqo_map/common/dataset.h"
#include "dqo_map/sim/detections.h"
#include "dqo_map/sim/scene.h"

namespace dqo::sim {

class Renderer {
 public:
  // `scene` must outlive the renderer. threads <= 0: std::thread::hardware_concurrency().
  Renderer(const Scene& scene, int threads);

  int num_frames() const { return scene_.num_frames(); }

  // Frame `frame_index` of the scene's trajectory. `noise` false switches every kind of noise off
  // (--no-noise); true applies the scene's noise where its parameters enable it. Detections are
  // always filled: noisy ones with noise, the exact visible boxes without.
  Frame render(int frame_index, bool noise) const;

  // Any camera pose (tests, novel views); frame_index keys the noise.
  Frame render_view(const SE3& T_wc, int frame_index, double timestamp, bool noise) const;

  // Camera, depth scale, classes and ground-truth objects (meshes built on each call).
  DatasetInfo info() const { return dataset_info(scene_); }

  const Scene& scene() const { return scene_; }
  // What the simulated detector knows of the scene (classes, clutter spots, camera).
  const DetectionContext& detection_context() const { return detection_context_; }
  int threads() const { return threads_; }

 private:
  const Scene& scene_;
  int threads_;
  DetectionContext detection_context_;
};

}  // namespace dqo::sim
