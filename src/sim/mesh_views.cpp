#include "dqo_map/sim/mesh_views.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include "dqo_map/sim/mesh_shape.h"
#include "dqo_map/sim/renderer.h"
#include "dqo_map/sim/scene.h"
#include "dqo_map/sim/trajectory.h"

namespace dqo::sim {

std::vector<MeshView> render_mesh_views(const TriangleMesh& mesh, const MeshViewParams& params, int threads) {
  std::vector<MeshView> views;
  if (mesh.empty() || params.size <= 0) return views;
  Eigen::Vector3d lo = mesh.vertices.front(), hi = lo;
  for (const Eigen::Vector3d& v : mesh.vertices) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const double radius = std::max(0.5 * (hi - lo).norm(), 1e-3);
  const double half_fov = 0.5 * std::clamp(params.fov_deg, 1.0, 170.0) * M_PI / 180.0;
  // The bounding sphere touches the image's edges from this distance.
  const double distance = radius / std::sin(half_fov);
  const double elevation = params.elevation_deg * M_PI / 180.0;

  Scene scene;
  scene.name = "mesh views";
  scene.camera.width = scene.camera.height = params.size;
  scene.camera.fx = scene.camera.fy = 0.5 * params.size / std::tan(half_fov);
  scene.camera.cx = scene.camera.cy = 0.5 * (params.size - 1);
  scene.near = 1e-4;
  scene.background_colour = params.background;
  scene.classes = {{1, "object"}};
  scene.noise.enabled = false;
  SceneObject object;
  object.id = 1;
  object.class_id = 1;
  object.class_name = "object";
  object.shape = std::make_shared<MeshShape>(mesh);
  object.material.colour_a = params.colour;
  scene.objects.push_back(object);
  for (const double azimuth_deg : params.azimuth_deg) {
    const double a = azimuth_deg * M_PI / 180.0;
    const Eigen::Vector3d eye =
        centre + distance * Eigen::Vector3d(std::cos(elevation) * std::cos(a), std::cos(elevation) * std::sin(a),
                                            std::sin(elevation));
    const SE3 T_wc = look_at(eye, centre);
    // Light from over the camera's shoulder and a little from above, so faces turned away read
    // darker than faces towards the viewer: the shape shows in a grey image.
    scene.lighting.ambient = Eigen::Vector3f::Constant(0.35f);
    Light key;
    key.type = Light::Type::kDirectional;
    key.direction = (centre - eye + Eigen::Vector3d(0, 0, -0.5 * distance)).normalized();
    key.intensity = 0.75;
    scene.lighting.lights = {key};
    scene.trajectory = {{0.0, T_wc}};
    const Renderer renderer(scene, threads);
    Frame frame = renderer.render_view(T_wc, 0, 0.0, false);
    MeshView view;
    view.camera = scene.camera;
    view.T_wc = T_wc;
    view.rgb = std::move(frame.rgb);
    for (const uint16_t id : frame.instance.data) view.hit_pixels += id == 1;
    views.push_back(std::move(view));
  }
  return views;
}

}  // namespace dqo::sim
