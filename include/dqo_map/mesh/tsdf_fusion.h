#pragma once
// Truncated signed distance fusion of RGB-D views into a triangle mesh (METHOD.md §5).
//
// The caller renders colour and depth of one object's Gaussians (or of the background, or of the
// whole map) from keyframe poses; this module fuses them with Open3D's ScalableTSDFVolume (voxel
// blocks allocated only where depth lands, so a room costs what its surfaces cost) and extracts
// the zero level set by marching cubes, with per-vertex colour. Open3D stays inside the .cpp.

#include <optional>
#include <string>
#include <vector>

#include "dqo_map/common/triangle_mesh.h"
#include "dqo_map/geometry/oriented_box.h"
#include "dqo_map/geometry/pinhole_camera.h"
#include "dqo_map/geometry/se3.h"

namespace dqo::mesh {

// One view: intrinsics, pose, per-pixel colour and depth (camera.width x camera.height pixels).
struct FusionView {
  PinholeCamera camera;
  SE3 T_wc;                  // camera (optical) to world
  std::vector<float> rgb;    // 3 per pixel, row-major, RGB in [0, 1]
  std::vector<float> depth;  // metres (z along the optical axis); 0 or non-finite = no surface
};

struct TsdfParams {
  // fuse_object: voxel = largest full extent of the box / voxels_across, clamped to
  // [min_voxel, max_voxel]. ~100 voxels across resolves a 20 cm mug at 2 mm, the scale of the
  // 1 cm completion threshold of the object tables, without paying for more detail than the
  // rendered depth holds.
  double voxels_across = 100.0;
  // Below 2 mm the rendered depth (a blend of Gaussians) is not that precise, and memory grows as
  // the cube of the resolution; 5 cm still leaves a sofa or a bed with ~50 voxels across.
  double min_voxel = 0.002;  // metres
  double max_voxel = 0.05;   // metres
  // Truncation distance in voxels. Marching cubes needs a few voxels of signed distance on both
  // sides of the surface; 4 covers the depth scatter of a Gaussian render at grazing angles
  // without letting thin parts (a table top seen from both sides) erase each other.
  double truncation_voxels = 4.0;
  // Depth beyond this (metres) is ignored: rooms of the evaluation data sets fit within it, and
  // the far tail of a render is mostly low-opacity haze.
  double depth_max = 8.0;
  // Voxels along the edge of one of the volume's blocks (allocated where depth lands). Open3D
  // integrates block by block, each in its own OpenMP parallel region with one thread per core;
  // on a busy machine every region waits for a descheduled thread (seconds per object on 2 loaded
  // cores). Blocks of 32 make a quarter as many regions as Open3D's default 16, for somewhat more
  // empty space integrated; on an idle machine the two cost about the same.
  int block_voxels = 32;
  // fuse_object only: keep the largest connected piece of the mesh (by surface area), dropping
  // floaters from stray Gaussians. Vertex colours are kept.
  bool largest_component = true;
  // fuse_object only: the mesh is cropped to the object's box grown on every side by
  // crop_margin x (the box's largest full extent), and at least by 2 voxels (marching-cubes
  // vertices of a surface on the box's face lie up to a voxel beyond it). The box of an estimated
  // ellipsoid only approximates the object, hence a margin; a negative value turns cropping off.
  double crop_margin = 0.1;
};

// Fuses the views at a given voxel size (metres) with truncation truncation_voxels x voxel_size:
// for the background or a whole scene. No crop and no component filter (largest_component and
// crop_margin are for objects). nullopt and *error when there are no views, a view's buffers do
// not match its camera's size, a camera or pose is invalid, voxel_size is not positive, or no
// surface was fused ("no surface fused").
std::optional<TriangleMesh> fuse_views(const std::vector<FusionView>& views, double voxel_size,
                                       const TsdfParams& params, std::string* error = nullptr);

// Fuses the views of one object: voxel size from the box (object_voxel_size), the mesh cropped to
// the grown box and, with params.largest_component, reduced to its largest connected component.
// Errors as fuse_views, plus a box that is not finite; a mesh left empty by the crop is "no surface
// fused" too.
std::optional<TriangleMesh> fuse_object(const std::vector<FusionView>& views,
                                        const OrientedBox& object_box, const TsdfParams& params,
                                        std::string* error = nullptr);

// The voxel size fuse_object uses for this box (metres).
double object_voxel_size(const OrientedBox& object_box, const TsdfParams& params);

// The box fuse_object crops to (the object's box grown by the margin described in TsdfParams).
OrientedBox object_crop_box(const OrientedBox& object_box, const TsdfParams& params);

}  // namespace dqo::mesh
