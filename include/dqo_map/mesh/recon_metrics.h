#pragma once
// Reconstruction metrics of a mesh against a ground-truth mesh (METHOD.md §6, vMAP's protocol):
// points sampled uniformly by area on both surfaces, the reconstruction's optionally restricted to
// the ground-truth object's box enlarged by 1/0.9; then
//   Accuracy   = mean distance from reconstructed points to their nearest ground-truth point (cm)
//   Completion = mean distance from ground-truth points to their nearest reconstructed point (cm)
//   completion ratio = % of ground-truth points within 1 cm (objects) / 5 cm (scenes)
// Distances are point to sampled point, as in vMAP, so even a perfect reconstruction scores a
// little above 0 (about half the sample spacing).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "dqo_map/common/triangle_mesh.h"
#include "dqo_map/geometry/oriented_box.h"

namespace dqo::mesh {

struct ReconParams {
  int samples = 10000;  // points per surface (vMAP samples 10k)
  // When set, only the reconstruction's surface inside this box, scaled by crop_scale about its
  // centre, is sampled (the ground-truth object's box: what lies outside belongs to something
  // else). The ground truth is never cropped.
  std::optional<OrientedBox> crop_box;
  double crop_scale = 1.0 / 0.9;  // vMAP enlarges the box by 1/0.9
  // Both samplers derive their streams from it (different ones for the two meshes, so that a mesh
  // against itself is compared through independent samples, as in the reference code).
  uint64_t seed = 1;
};

struct ReconMetrics {
  double accuracy_cm = 0.0;
  double completion_cm = 0.0;
  double comp_ratio_1cm = 0.0;  // percent of ground-truth points within 1 cm of the reconstruction
  double comp_ratio_5cm = 0.0;  // percent within 5 cm
  int rec_points = 0;           // reconstructed points used (after the crop)
  int gt_points = 0;
};

// nullopt and *error when a mesh is empty or has no area, has an index outside its vertices or a
// vertex that is not finite, samples < 1, or the crop leaves no reconstructed surface.
std::optional<ReconMetrics> evaluate_reconstruction(const TriangleMesh& rec,
                                                    const TriangleMesh& gt,
                                                    const ReconParams& params,
                                                    std::string* error = nullptr);

// `count` points uniformly distributed by area on the mesh, deterministic for a seed (its own
// generator: Open3D 0.16's sampler cannot be seeded). With `crop`, uniform on the part of the
// surface inside the box: sampled by rejection from the triangles that may reach into it, until
// `count` points are inside or 50 x count draws were spent (fewer points then; none when the
// surface misses the box). Empty, with *error, for an invalid mesh or count < 1.
std::vector<Eigen::Vector3d> sample_surface(const TriangleMesh& mesh, int count, uint64_t seed,
                                            const OrientedBox* crop = nullptr,
                                            std::string* error = nullptr);

}  // namespace dqo::mesh
