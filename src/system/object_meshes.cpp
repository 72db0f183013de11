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

// The surface around the object's silhouette in its views: pixels within `ring` pixels of the
// object that show something else (the whole map's render), back-projected, kept within `margin`
// of the box. Rendered depth rather than Gaussian centres: the meshes are fused from rendered
// depth, and the centres of a flat surface's Gaussians sit a few millimetres behind it.
std::vector<Eigen::Vector3d> surroundings(const std::vector<mapping::ObjectView>& views,
                                          const OrientedBox& box, double margin, int ring) {
  std::vector<Eigen::Vector3d> out;
  const Eigen::Matrix3d R_bw = box.rotation.transpose();
  const Eigen::Array3d limit = box.half_extents.array() + margin;
  for (const mapping::ObjectView& v : views) {
    if (v.scene_depth.empty()) continue;
    const int w = v.camera.width, h = v.camera.height;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const size_t i = static_cast<size_t>(y) * w + x;
        if (v.depth[i] > 0.f || !(v.scene_depth[i] > 0.f)) continue;
        bool near_object = false;
        for (int dy = -ring; dy <= ring && !near_object; ++dy) {
          for (int dx = -ring; dx <= ring && !near_object; ++dx) {
            const int xx = x + dx, yy = y + dy;
            near_object = xx >= 0 && yy >= 0 && xx < w && yy < h &&
                          v.depth[static_cast<size_t>(yy) * w + xx] > 0.f;
          }
        }
        if (!near_object) continue;
        const Eigen::Vector3d p = v.T_wc * v.camera.back_project(x, y, v.scene_depth[i]);
        if (((R_bw * (p - box.centre)).array().abs() <= limit).all()) out.push_back(p);
      }
    }
  }
  return out;
}

}  // namespace

std::optional<TriangleMesh> object_mesh(mapping::GaussianMapper& mapper, mapping::ObjectId id,
                                        const ObjectMeshParams& params, std::string* error,
                                        mesh::SupportClosureInfo* closure) {
  const std::string name = "object " + std::to_string(id);
  const mapping::ObjectRecord* record = mapper.find_object(id);
  if (id == 0 || !record) {
    if (error) *error = name + ": no such object";
    return std::nullopt;
  }
  std::vector<mapping::ObjectView> rendered = mapper.object_views(id, params.closure.enabled);
  const std::vector<Eigen::Vector3d> around =
      surroundings(rendered, record->box, params.support_search, params.support_ring_px);
  std::vector<mesh::FusionView> views = fusion_views(std::move(rendered));
  if (views.empty()) {
    if (error) *error = name + ": no Gaussians to render in the keyframes that saw it";
    return std::nullopt;
  }
  const double voxel = mesh::object_voxel_size(record->box, params.tsdf);
  auto support = mesh::support_closure_view(views, around, record->box, voxel, params.closure,
                                            closure);
  if (support) views.push_back(std::move(*support));
  std::string e;
  auto m = mesh::fuse_object(views, record->box, params.tsdf, &e);
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
