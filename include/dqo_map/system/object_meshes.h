#pragma once
// Per-object meshes from the Gaussian map (METHOD.md §5): each object's own Gaussians rendered
// alone (colour and surface depth) from the keyframes that saw it (GaussianMapper::object_views),
// fused into a TSDF sized to the object and meshed (mesh/tsdf_fusion.h). What extract_object and
// dqo_map_offline write. The face an object rests on, which no view sees, is closed on its support
// (mesh/support_closure.h), found in the surface around the object's silhouette in its views.

#include <optional>
#include <string>

#include "dqo_map/common/triangle_mesh.h"
#include "dqo_map/mapping/gaussian_mapper.h"
#include "dqo_map/mesh/support_closure.h"
#include "dqo_map/mesh/tsdf_fusion.h"

namespace dqo::system {

struct ObjectMeshParams {
  mesh::TsdfParams tsdf;
  mesh::SupportClosureParams closure;
  double support_search = 0.05;  // metres around the object's box searched for its support
  int support_ring_px = 4;       // pixels around the object's silhouette that show the support
};

// The mesh of object `id` (its record's box sizes the volume). nullopt and *error when the object
// is unknown, has no Gaussians, or nothing could be fused. `closure` (optional) says whether and
// where the contact face was closed.
std::optional<TriangleMesh> object_mesh(mapping::GaussianMapper& mapper, mapping::ObjectId id,
                                        const ObjectMeshParams& params,
                                        std::string* error = nullptr,
                                        mesh::SupportClosureInfo* closure = nullptr);

// The background's mesh (object 0) at a fixed voxel size, from up to mesh_views keyframes.
std::optional<TriangleMesh> background_mesh(mapping::GaussianMapper& mapper, double voxel_size,
                                            const mesh::TsdfParams& params,
                                            std::string* error = nullptr);

}  // namespace dqo::system
