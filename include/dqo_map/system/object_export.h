#pragma once
// One object out of the map into files, as the extract_object service and dqo_map_offline write
// it: its Gaussians (3DGS PLY with object_id) and its mesh (object_meshes.h), named
// object_<id>_gaussians.ply and object_<id>_mesh.ply, in a sub-folder of the output folder that
// cannot lead out of it (common/output_path.h).

#include <string>

#include "dqo_map/mapping/gaussian_mapper.h"
#include "dqo_map/mesh/support_closure.h"
#include "dqo_map/system/object_meshes.h"

namespace dqo::system {

struct ObjectExport {
  bool success = false;
  std::string message;        // what went wrong, or what was written
  std::string gaussians_path;  // absolute; empty when not written
  std::string mesh_path;
  size_t num_gaussians = 0;
  mesh::SupportClosureInfo closure;
};

// Writes object `id` under `output_root`/`subfolder` (created; "" for the root). Fails, writing
// nothing, for an unknown ID, a sub-folder that leads outside the root, or an object without
// Gaussians; when only the mesh fails (nothing fused), the Gaussians are written and success is
// false with the mesh's error in the message.
ObjectExport export_object(mapping::GaussianMapper& mapper, mapping::ObjectId id,
                           const std::string& output_root, const std::string& subfolder,
                           const ObjectMeshParams& params = ObjectMeshParams());

}  // namespace dqo::system
