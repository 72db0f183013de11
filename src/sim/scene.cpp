#include "dqo_map/sim/scene.h"

#include <set>

#include "dqo_map/sim/procedural_mesh.h"

namespace dqo::sim {

std::vector<GtObject> ground_truth_objects(const Scene& scene) {
  std::vector<GtObject> out;
  out.reserve(scene.objects.size());
  for (const SceneObject& obj : scene.objects) {
    GtObject gt;
    gt.id = obj.id;
    gt.class_id = obj.class_id;
    gt.class_name = obj.class_name;
    const TriangleMesh local = obj.shape->surface_mesh();
    // The tight box of the surface in the object's own frame: exact for boxes, meshes and parts
    // made of them, and within the tessellation of curved primitives (whose extreme points are
    // mesh vertices) otherwise.
    Aabb box;
    for (const auto& v : local.vertices) box.extend(v);
    if (box.empty()) box = obj.shape->bounds();
    gt.box.centre = obj.T_wo * (obj.scale * box.centre());
    gt.box.rotation = obj.T_wo.rotation();
    gt.box.half_extents = 0.5 * obj.scale * box.extent();
    append_mesh(local, obj.T_wo, obj.scale, &gt.mesh);
    out.push_back(std::move(gt));
  }
  return out;
}

DatasetInfo dataset_info(const Scene& scene) {
  DatasetInfo info;
  info.camera = scene.camera;
  info.depth_scale = scene.depth_scale;
  info.class_names = scene.classes;
  info.objects = ground_truth_objects(scene);
  return info;
}

std::string validate_scene(const Scene& scene) {
  const PinholeCamera& c = scene.camera;
  if (c.width <= 0 || c.height <= 0 || !(c.fx > 0.0) || !(c.fy > 0.0)) {
    return "the camera needs a positive image size and focal lengths";
  }
  if (!(scene.depth_scale > 0.0)) return "depth_scale must be positive";
  if (scene.trajectory.empty()) return "the trajectory has no frames";
  std::set<uint32_t> ids;
  for (const SceneObject& obj : scene.objects) {
    const std::string what = "object " + std::to_string(obj.id);
    if (obj.id == 0 || obj.id > 65535) return what + ": IDs run from 1 to 65535 (uint16 images)";
    if (!ids.insert(obj.id).second) return what + ": ID used twice";
    if (!obj.shape) return what + ": no shape";
    if (!(obj.scale > 0.0)) return what + ": scale must be positive";
    const auto it = scene.classes.find(obj.class_id);
    if (it == scene.classes.end())
      return what + ": class " + std::to_string(obj.class_id) + " not in the class table";
    if (it->second != obj.class_name) return what + ": class name does not match the class table";
  }
  for (const SceneObject& obj : scene.background) {
    if (obj.id != 0) return "background surfaces have ID 0";
    if (!obj.shape) return "a background surface has no shape";
    if (!(obj.scale > 0.0)) return "a background surface has a non-positive scale";
  }
  return "";
}

}  // namespace dqo::sim
