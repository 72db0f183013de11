#pragma once
// Per-object meshes from the Gaussian map (METHOD.md §5): each object's own Gaussians rendered
// alone (colour and surface depth) from the keyframes that saw it (GaussianMapper::object_views),
// fused into a TSDF sized to the object and meshed (mesh/tsdf_fusion.h). What extract_object and
// dqo_map_offline write.

#include <optional>
#include <string>

#include "dqo_map/common/triangle_mesh.h"
#include "dqo_map/mapping/gaussian_mapper.h"
#include "dqo_map/mesh/tsdf_fusion.h"

namespace dqo::system {

// The mesh of object `id` (its record's box sizes the volume). nullopt and *error when the object
// is unknown, has no Gaussians, or nothing could be fused.
std::optional<TriangleMesh> object_mesh(mapping::GaussianMapper& mapper, mapping::ObjectId id,
                                        const mesh::TsdfParams& params,
                                        std::string* error = nullptr);

// The background's mesh (object 0) at a fixed voxel size, from up to mesh_views keyframes.
std::optional<TriangleMesh> background_mesh(mapping::GaussianMapper& mapper, double voxel_size,
                                            const mesh::TsdfParams& params,
                                            std::string* error = nullptr);

}  // namespace dqo::system
