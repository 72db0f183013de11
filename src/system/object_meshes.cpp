#include "dqo_map/system/object_meshes.h"

#include <utility>
#include <vector>

namespace dqo::system {
namespace {

std::vector<mesh::FusionView> fusion_views(std::vector<mapping::ObjectView> views) {
  std::vector<mesh::FusionView> out;
  out.reserve(views.size());
  for (mapping::ObjectView& v : views) {
    mesh::FusionView f;
    f.camera = v.camera;
    f.T_wc = v.T_wc;
    f.rgb = std::move(v.rgb);
    f.depth = std::move(v.depth);
    out.push_back(std::move(f));
  }
  return out;
}

}  // namespace

std::optional<TriangleMesh> object_mesh(mapping::GaussianMapper& mapper, mapping::ObjectId id,
                                        const mesh::TsdfParams& params, std::string* error) {
  const std::string name = "object " + std::to_string(id);
  const mapping::ObjectRecord* record = mapper.find_object(id);
  if (id == 0 || !record) {
    if (error) *error = name + ": no such object";
    return std::nullopt;
  }
  std::vector<mesh::FusionView> views = fusion_views(mapper.object_views(id));
  if (views.empty()) {
    if (error) *error = name + ": no Gaussians to render in the keyframes that saw it";
    return std::nullopt;
  }
  std::string e;
  auto m = mesh::fuse_object(views, record->box, params, &e);
  if (!m && error) *error = name + ": " + e;
  return m;
}

std::optional<TriangleMesh> background_mesh(mapping::GaussianMapper& mapper, double voxel_size,
                                            const mesh::TsdfParams& params, std::string* error) {
  std::vector<mesh::FusionView> views = fusion_views(mapper.object_views(0));
  if (views.empty()) {
    if (error) *error = "background: no Gaussians to render";
    return std::nullopt;
  }
  std::string e;
  auto m = mesh::fuse_views(views, voxel_size, params, &e);
  if (!m && error) *error = "background: " + e;
  return m;
}

}  // namespace dqo::system
