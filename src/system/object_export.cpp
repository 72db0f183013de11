#include "dqo_map/system/object_export.h"

#include <filesystem>
#include <system_error>
#include <vector>

#include "dqo_map/common/output_path.h"
#include "dqo_map/gaussians/gaussian_ply.h"
#include "dqo_map/io/mesh_io.h"

namespace dqo::system {

ObjectExport export_object(mapping::GaussianMapper& mapper, mapping::ObjectId id,
                           const std::string& output_root, const std::string& subfolder,
                           const ObjectMeshParams& params) {
  namespace fs = std::filesystem;
  ObjectExport out;
  const std::string name = "object " + std::to_string(id);
  if (id == 0 || id > mapping::kMaxObjectId || !mapper.find_object(id)) {
    std::string known;
    for (const mapping::ObjectSummary& s : mapper.list_objects()) {
      if (s.known) known += (known.empty() ? "" : ", ") + std::to_string(s.object.id);
    }
    out.message = name + ": no such object (known: " + (known.empty() ? "none" : known) + ")";
    return out;
  }
  std::string error;
  const auto folder = resolve_output_path(output_root, subfolder, &error, true);
  if (!folder) {
    out.message = error;
    return out;
  }
  const std::vector<uint32_t> indices = mapper.map().indices_of(static_cast<uint32_t>(id));
  out.num_gaussians = indices.size();
  if (indices.empty()) {
    out.message = name + ": it has no Gaussians yet";
    return out;
  }
  std::error_code ec;
  fs::create_directories(*folder, ec);
  if (ec) {
    out.message = *folder + ": " + ec.message();
    return out;
  }
  const fs::path base = fs::path(*folder) / ("object_" + std::to_string(id));
  const std::string gaussians = base.string() + "_gaussians.ply";
  if (!gs::save_gaussians_ply(gaussians, mapper.map(), &indices, &error)) {
    out.message = error;
    return out;
  }
  out.gaussians_path = gaussians;
  const auto m = object_mesh(mapper, id, params, &error, &out.closure);
  if (!m) {
    out.message = name + ": Gaussians written, no mesh: " + error;
    return out;
  }
  const std::string mesh = base.string() + "_mesh.ply";
  if (!save_mesh_ply(mesh, *m, &error)) {
    out.message = error;
    return out;
  }
  out.mesh_path = mesh;
  out.success = true;
  out.message = name + ": " + std::to_string(indices.size()) + " Gaussians, mesh of " +
                std::to_string(m->triangles.size()) + " triangles";
  return out;
}

}  // namespace dqo::system
