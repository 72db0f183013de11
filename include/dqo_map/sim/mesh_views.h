#pragma once
// A mesh seen from a few sides, for people: the object meshes a run extracted, rendered by the
// simulator's ray caster (grey, lit from the camera's side and from above) from cameras placed
// around the mesh's bounds at one elevation, so that a contact sheet shows whether a mesh looks
// like its object without a 3D viewer (dqo_render_meshes, scripts/real_data).
#include <vector>

#include "dqo_map/common/image.h"
#include "dqo_map/common/triangle_mesh.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::sim {

struct MeshViewParams {
  int size = 320;                                    // square images, pixels
  double fov_deg = 40.0;                             // the camera's field of view
  double elevation_deg = 30.0;                       // above the horizontal (world z up)
  // Camera directions about z from the mesh: (cos a, sin a) in the map's x-y plane.
  std::vector<double> azimuth_deg = {-120.0, -30.0, 60.0};
  Eigen::Vector3f colour = Eigen::Vector3f(0.78f, 0.76f, 0.72f);
  Eigen::Vector3f background = Eigen::Vector3f(1.0f, 1.0f, 1.0f);
};

struct MeshView {
  ImageRgb8 rgb;
  PinholeCamera camera;
  SE3 T_wc;
  int hit_pixels = 0;  // pixels that see the mesh
};

// One view per azimuth, the whole mesh in frame (the camera at the distance where the sphere
// around its bounds fills the field of view). Empty for an empty mesh.
std::vector<MeshView> render_mesh_views(const TriangleMesh& mesh, const MeshViewParams& params = MeshViewParams(),
                                        int threads = 1);

}  // namespace dqo::sim
